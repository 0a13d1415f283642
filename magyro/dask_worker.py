"""A Dask worker made ready for magyro's solves: a worker plugin (imported only with `--scheduler`).

Registered by `magyro.executor.DaskCluster` when it connects; every worker that joins, once:

- writes the client's cached kernel libraries into its own kernel cache (a library already
  there is left alone), so a worker on another machine compiles nothing the client already has;
- gives glibc's malloc back the thresholds of an ordinary process. Dask's nanny starts workers
  with MALLOC_TRIM_THRESHOLD_=65536, which also fixes the mmap threshold at 128 KiB, so every
  array of a solve is mapped and unmapped anew: measured on the 2-core machine, a 100 s
  production-line solve took 1.15 s in such a worker against 0.68 s in a plain process, and
  0.75 s after `mallopt` (M_MMAP_THRESHOLD 32 MiB, M_TRIM_THRESHOLD 64 MiB). Numbers are unchanged;
- pins BLAS/OpenMP to one thread, as the local pool's workers have (`one_blas_thread`). A nanny sets
  the thread variables before the worker starts; a worker started with `dask worker --no-nanny`
  has numpy's OpenBLAS running one thread per core, and its sums come out in another order: batch
  results then differed from the local pool's by up to 1.2e-9. threadpoolctl sets the thread
  count of the libraries already loaded; the variables cover those loaded later.
"""
from __future__ import annotations

import os
from pathlib import Path

from distributed.diagnostics.plugin import WorkerPlugin

KERNEL_SHIPPING_LIMIT_BYTES = 64 * 2**20   # the client's cache beyond this is not shipped (workers compile)


class MagyroWorker(WorkerPlugin):
    """The worker plugin: the client's compiled kernels, written into the worker's cache, and malloc's thresholds."""

    name = "magyro-worker"

    def __init__(self, libraries: dict[str, bytes]):
        self.libraries = libraries

    @classmethod
    def from_local_cache(cls) -> "MagyroWorker":
        from magyro.nls.kernels import cache_dir

        libraries, total = {}, 0
        for lib in sorted(Path(cache_dir()).glob("*.so"), key=lambda p: -p.stat().st_mtime):
            size = lib.stat().st_size
            if total + size > KERNEL_SHIPPING_LIMIT_BYTES:
                break
            libraries[lib.name] = lib.read_bytes()
            total += size
        return cls(libraries)

    def setup(self, worker=None) -> None:
        one_blas_thread()
        ordinary_malloc()
        self.write_kernels()

    def write_kernels(self) -> None:
        from magyro.nls.kernels import cache_dir

        folder = Path(cache_dir())
        folder.mkdir(parents=True, exist_ok=True)
        for name, data in self.libraries.items():
            target = folder / name
            if target.exists():
                continue
            tmp = folder / f".{name}.{os.getpid()}.tmp"
            tmp.write_bytes(data)
            os.replace(tmp, target)

    def teardown(self, worker=None) -> None:
        return None


# magyro.executor.WORKER_THREAD_VARIABLES (not imported: the executor imports this module)
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                    "NUMEXPR_NUM_THREADS")


def one_blas_thread() -> dict[str, int]:
    """One BLAS/OpenMP thread in this process, whatever started it: {library: threads} after the change."""
    from threadpoolctl import threadpool_limits

    os.environ.update({name: "1" for name in THREAD_VARIABLES})  # for libraries loaded from now on
    import numpy  # noqa: F401  (its BLAS loaded, so that its pool is the one limited)

    threadpool_limits(limits=1)  # called, not entered: the limit stays for the worker's life
    return blas_threads()


def blas_threads() -> dict[str, int]:
    """{threading library (openblas, openmp, mkl, ...): its thread count} in this process."""
    from threadpoolctl import threadpool_info

    return {info["internal_api"]: info["num_threads"] for info in threadpool_info()}


M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3      # glibc's mallopt parameters
MMAP_THRESHOLD_BYTES, TRIM_THRESHOLD_BYTES = 32 * 2**20, 64 * 2**20


def ordinary_malloc() -> bool:
    """Set glibc's mmap and trim thresholds to what its dynamic policy reaches in a plain process; False where
    there is no glibc (nothing to undo there)."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
                    and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
    except (OSError, AttributeError):
        return False
