"""Where many independent solves run: this process, a local process pool, or a Dask cluster.

One layer for `magyro batch` and `magyro montecarlo`. `executor_for(jobs, scheduler)`
chooses:

- `InProcess`: jobs == 1 and no scheduler; tasks run here, one after another.
- `LocalPool`: a process pool of `jobs` spawned workers, each with one BLAS/OpenMP
  thread (a solve is single-threaded at heart; two threads per worker only fight).
- `DaskCluster`: a `dask.distributed` scheduler at ADDRESS (`--scheduler`, or the
  environment variable MAGYRO_SCHEDULER), with `pip install 'magyro[dask]'`. Each worker
  runs one task at a time. Its nanny starts it with one BLAS/OpenMP thread (dask's
  default `distributed.nanny.pre-spawn-environ`), as the pool does, so the same task
  gives bit-for-bit the same numbers on either executor.

Compiled kernels: a worker loads the solver's kernels from the kernel cache
(`magyro.nls.kernels.cache_dir()`), once per process, and compiles a missing one once
per machine (the cache is written atomically, so workers never see half a library).
`check()` refuses, before any work, an executor that cannot run (no dask.distributed, nothing
listening at the scheduler's address). Dask workers on other machines get the client's cached kernels once, when they join
(`magyro.dask_worker.MagyroWorker`, a worker plugin, which also undoes the nanny's malloc
setting that made solves 1.7x slower), not with every task.

`run_unordered(executor, fn, items, done)` keeps at most a few tasks per worker in
flight, so the client's memory does not grow with the number of items, and calls
`done(item, result, error)` as each finishes: a task that raised, or whose worker
died, comes back as its error, and the others go on.
"""
from __future__ import annotations

import concurrent.futures as cf
from concurrent.futures.process import BrokenProcessPool
import contextlib
import multiprocessing
import os
from typing import Any, Callable, Iterable

from magyro.errors import InputError

WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                           "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
DEFAULT_START_METHOD = "spawn"
SCHEDULER_VARIABLE = "MAGYRO_SCHEDULER"
CONNECT_TIMEOUT = "10s"
TASKS_IN_FLIGHT_PER_WORKER = 2
FRUITLESS_RESTARTS = 3
_NOTHING = object()


# --------------------------------------------------------------------------- choosing


def executor_for(jobs: int = 1, scheduler: str | None = None, start_method: str | None = None):
    """The executor for `--jobs` and `--scheduler` (None: the MAGYRO_SCHEDULER environment variable, if set)."""
    if not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1:
        raise InputError(f"--jobs must be a positive integer, got {jobs!r}")
    scheduler = scheduler or os.environ.get(SCHEDULER_VARIABLE) or None
    if scheduler:
        return DaskCluster(scheduler)
    if jobs == 1:
        return InProcess()
    return LocalPool(jobs, start_method or DEFAULT_START_METHOD)


# --------------------------------------------------------------------------- executors


class InProcess:
    """Tasks run in this process, in order: no start-up cost, nothing to pickle."""

    name = "in-process"
    workers = 1

    def check(self) -> None:
        return None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    def submit(self, fn: Callable, *args) -> cf.Future:
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:
            future.set_exception(exc)
        return future

    def wait_any(self, futures: set) -> set:
        return {f for f in futures if f.done()}

    def restart(self) -> None:
        return None

    def describe(self) -> str:
        return "this process"


class LocalPool:
    """A pool of `workers` spawned processes, each with one BLAS/OpenMP thread."""

    name = "local pool"

    def check(self) -> None:
        return None

    def __init__(self, workers: int, start_method: str = DEFAULT_START_METHOD):
        self.workers = workers
        self.start_method = start_method
        self._pool: cf.ProcessPoolExecutor | None = None
        self._finished = 0            # tasks that came back from a worker (a result or the task's own error)
        self._finished_at_restart = 0
        self._fruitless_restarts = 0  # restarts in a row with no task back in between

    def __enter__(self):
        context = multiprocessing.get_context(self.start_method)
        with single_threaded_children():
            self._pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=context,
                                                initializer=single_threaded_worker)
        return self

    def restart(self) -> None:
        """A new pool after a worker died (a broken pool takes no more tasks). SolverError at the third break in
        a row with no task back in between: one task that kills its worker breaks the pool twice (its run and
        its run alone), so a third means the workers cannot run anything, and restarting is futile."""
        self._pool.shutdown(wait=False, cancel_futures=True)
        fruitless = self._finished == self._finished_at_restart
        self._fruitless_restarts = self._fruitless_restarts + 1 if fruitless else 1
        self._finished_at_restart = self._finished
        if self._fruitless_restarts >= FRUITLESS_RESTARTS:
            from magyro.errors import SolverError

            raise SolverError(
                "the worker processes die before finishing any task: a script that runs a batch or a study "
                "with --jobs > 1 must start its work under `if __name__ == \"__main__\":` (the workers import it); "
                "otherwise run it with jobs=1 to see the error")
        self.__enter__()

    def __exit__(self, exc_type, *exc) -> None:
        if self._pool is not None:
            failed = exc_type is not None
            self._pool.shutdown(wait=not failed, cancel_futures=failed)
            self._pool = None

    def submit(self, fn: Callable, *args) -> cf.Future:
        with single_threaded_children():   # a worker the pool starts now reads them at import
            future = self._pool.submit(fn, *args)
        future.add_done_callback(self._count)
        return future

    def _count(self, future: cf.Future) -> None:
        if not future.cancelled() and not isinstance(future.exception(), BrokenProcessPool):
            self._finished += 1

    def wait_any(self, futures: set) -> set:
        return cf.wait(futures, return_when=cf.FIRST_COMPLETED).done

    def describe(self) -> str:
        return f"a local pool of {self.workers} processes ({self.start_method})"


class DaskCluster:
    """A dask.distributed cluster at `address` (tcp://host:port); each worker runs one task at a time."""

    name = "dask"

    def __init__(self, address: str):
        self.address = address
        self.client = None
        self.workers = 0

    def check(self) -> None:
        """InputError, before any work, when dask.distributed is missing or nothing listens at the address."""
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise InputError("--scheduler needs dask.distributed: pip install 'magyro[dask]'") from None
        try:
            refuse_unreachable(self.address)   # at once, rather than after the Dask client's whole timeout
        except OSError as exc:
            raise self.unreachable(exc) from None

    def unreachable(self, exc: BaseException) -> InputError:
        return InputError(f"no Dask scheduler answers at {self.address} ({type(exc).__name__}: {exc}); start one "
                          "with `dask scheduler` and workers with `dask worker ADDRESS --nthreads 1`, or leave "
                          f"--scheduler and {SCHEDULER_VARIABLE} unset for the local pool")

    def __enter__(self):
        self.check()
        from distributed import Client

        try:
            self.client = Client(self.address, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as exc:
            raise self.unreachable(exc) from None
        from magyro.dask_worker import MagyroWorker

        self.client.register_plugin(MagyroWorker.from_local_cache(), name=MagyroWorker.name)
        self.workers = max(1, sum(w.get("nthreads", 1) for w in self.client.scheduler_info()["workers"].values()))
        return self

    def __exit__(self, *exc) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None

    def submit(self, fn: Callable, *args):
        return self.client.submit(fn, *args, pure=False)

    def restart(self) -> None:
        return None

    def wait_any(self, futures: set) -> set:
        from distributed import wait

        return set(wait(list(futures), return_when="FIRST_COMPLETED").done)

    def describe(self) -> str:
        return f"the Dask cluster at {self.address} ({self.workers} worker threads)"


def refuse_unreachable(address: str) -> None:
    """OSError at once when nothing listens at a tcp://HOST:PORT address (a refused connection); other
    addresses (tls://, a name Dask resolves itself) are left to the Dask client."""
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme != "tcp" or parts.hostname is None or parts.port is None:
        return
    socket.create_connection((parts.hostname, parts.port), timeout=5).close()


# --------------------------------------------------------------------------- running many tasks


def run_unordered(executor, fn: Callable, items: Iterable, done: Callable[[Any, Any, BaseException | None], None],
                  arguments: Callable[[Any], tuple] = lambda item: (item,), warm_first: bool = False) -> None:
    """fn(*arguments(item)) for every item on `executor`, at most TASKS_IN_FLIGHT_PER_WORKER per worker at once;
    `done(item, result, None)` or `done(item, None, error)` as each finishes, in the order they finish.

    `warm_first`: the first item runs alone, the rest after it, so what it compiles into the kernel cache
    (a cold machine's solver kernels) is compiled once rather than by every worker at the same time.

    A worker that dies breaks a local pool and every task in flight with it: the pool is started again, the
    others go on, and the items that were in flight are run again one at a time, so only the one that kills
    its worker again fails (with the pool's error). A Dask cluster retries a dead worker's task itself."""
    iterator = iter(items)
    if warm_first and executor.workers > 1:
        first = next(iterator, _NOTHING)
        if first is _NOTHING:
            return
        suspects = _run_window(executor, fn, iter([first]), done, arguments, 1)
        _run_alone(executor, fn, suspects, done, arguments)
    suspects = _run_window(executor, fn, iterator, done, arguments, TASKS_IN_FLIGHT_PER_WORKER * executor.workers)
    _run_alone(executor, fn, suspects, done, arguments)


def _run_window(executor, fn, iterator, done, arguments, limit: int) -> list:
    """Run the items with at most `limit` in flight; the items in flight when a local pool broke."""
    pending: dict = {}
    suspects: list = []
    exhausted = False
    while pending or not exhausted:
        while not exhausted and len(pending) < max(1, limit):
            item = next(iterator, _NOTHING)
            if item is _NOTHING:
                exhausted = True
                break
            pending[executor.submit(fn, *arguments(item))] = item
        if not pending:
            break
        for future in executor.wait_any(set(pending)):
            item = pending.pop(future)
            try:
                result = future.result()
            except BrokenProcessPool:   # some worker died: every task in flight is lost, not only its own
                suspects.append(item)
                suspects.extend(pending.values())
                pending.clear()
                executor.restart()
                break
            except Exception as exc:   # the task raised, or its Dask worker died (KilledWorker)
                done(item, None, exc)
            else:
                done(item, result, None)
    return suspects


def _run_alone(executor, fn, items: list, done, arguments) -> None:
    """Each item alone (a broken pool's suspects): one that breaks the pool again is the one that kills it."""
    for item in items:
        future = executor.submit(fn, *arguments(item))
        try:
            result = future.result()
        except BrokenProcessPool as exc:
            executor.restart()
            done(item, None, exc)
        except Exception as exc:
            done(item, None, exc)
        else:
            done(item, result, None)


# --------------------------------------------------------------------------- worker set-up


def single_threaded_worker() -> None:
    """Pool initializer: one BLAS/OpenMP thread per worker (the environment is also set before spawning)."""
    for name in WORKER_THREAD_VARIABLES:
        os.environ[name] = "1"


@contextlib.contextmanager
def single_threaded_children():
    """Set the thread-count variables while workers start (spawned children read them at import)."""
    saved = {name: os.environ.get(name) for name in WORKER_THREAD_VARIABLES}
    try:
        for name in WORKER_THREAD_VARIABLES:
            os.environ[name] = "1"
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
