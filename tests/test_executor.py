"""The executor layer (issue 15): a dead worker fails only its own task on the local pool, and a real Dask
cluster on localhost (a scheduler and two worker processes) gives `magyro batch` and `magyro montecarlo` the
same numbers, bit for bit, as `--jobs 2`, with a broken session isolated there too."""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from magyro.executor import DaskCluster, InProcess, LocalPool, executor_for, run_unordered

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_batch import calibration_numbers, fleet  # noqa: E402,F401  (fleet: the fixture)


def square_or_die(k: int) -> int:
    """A task whose worker dies on k == 3 or 0 (as a segfault in a native library would kill it)."""
    if k in (0, 3):
        os._exit(7)
    return k * k


@pytest.mark.parametrize("warm_first", [False, True], ids=["window", "first-alone"])
def test_a_worker_that_dies_fails_only_its_own_task(warm_first):
    """Even the first task, run alone to warm the kernels, may kill its worker without stopping the rest."""
    results, errors = {}, {}

    def done(k, result, error):
        (errors if error is not None else results)[k] = error or result

    with LocalPool(2) as executor:
        run_unordered(executor, square_or_die, range(8), done, warm_first=warm_first)
    assert results == {k: k * k for k in range(8) if k not in (0, 3)}
    assert sorted(errors) == [0, 3] and all("BrokenProcessPool" in type(e).__name__ for e in errors.values())


def test_executor_choice():
    assert isinstance(executor_for(1), InProcess)
    assert isinstance(executor_for(2), LocalPool)
    assert isinstance(executor_for(2, "tcp://127.0.0.1:1"), DaskCluster)


# --------------------------------------------------------------------------- a real Dask cluster on localhost


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed", reason="the Dask tests need magyro[dask] (dask.distributed)")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as c:
        yield c.scheduler_address


def test_no_scheduler_is_one_clear_message(tmp_path):
    pytest.importorskip("distributed", reason="needs dask.distributed")
    import subprocess

    r = subprocess.run([sys.executable, "-m", "magyro", "montecarlo", "paper-table1", "-n", "1", "--scheduler",
                        "tcp://127.0.0.1:9"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no Dask scheduler answers at tcp://127.0.0.1:9" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    (sessions / "a.parquet").write_bytes(b"never read")
    r = subprocess.run([sys.executable, "-m", "magyro", "batch", str(sessions), "-o", str(tmp_path / "out"),
                        "--scheduler", "127.0.0.1:9"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no Dask scheduler answers at 127.0.0.1:9" in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()   # refused before any output was made


def test_batch_on_dask_equals_the_local_pool_bit_for_bit(cluster, fleet, tmp_path):
    from magyro.batch.run import run_batch

    extra = tmp_path / "extra"          # the fleet and a broken file (the executors' equality needs no real trial:
    extra.mkdir()                       # test_batch runs one degraded real trial through the pool)
    (extra / "broken.parquet").write_bytes(b"not a session")
    inputs = [fleet / "manifest.csv", extra]
    pool = run_batch(inputs, tmp_path / "pool", jobs=2)
    dask = run_batch(inputs, tmp_path / "dask", scheduler=cluster)
    assert "Dask cluster" in dask.executor and "local pool" in pool.executor
    assert [r["device_id"] for r in dask.rows] == [r["device_id"] for r in pool.rows]
    for a, b in zip(pool.rows, dask.rows):
        assert (a["exit_code"], a["message"], a["verdict"]) == (b["exit_code"], b["message"], b["verdict"])
        if a["calibration"]:
            A = calibration_numbers(tmp_path / "pool" / a["calibration"])
            B = calibration_numbers(tmp_path / "dask" / b["calibration"])
            assert set(A) >= {"gyro", "std"} and A == B, a["device_id"]
    broken = next(r for r in dask.rows if r["device_id"] == "broken")
    assert broken["exit_code"] == 2 and "parquet" in broken["message"].lower()
    assert sum(r["exit_code"] == 0 for r in dask.rows) == 3


def test_montecarlo_on_dask_equals_the_local_pool_bit_for_bit(cluster):
    from magyro.studies.montecarlo import run_montecarlo
    from magyro.studies.scenario import load_problem

    problem = load_problem("short-30s")
    pool = run_montecarlo(problem, 4, jobs=2)
    dask = run_montecarlo(problem, 4, scheduler=cluster)
    for a, b in zip(pool.methods["nls"].outcomes, dask.methods["nls"].outcomes):
        assert a.ok and b.ok and (a.seed, a.estimate, a.reported_std) == (b.seed, b.estimate, b.reported_std)
    assert pool.crlb == dask.crlb and pool.crlb


def test_dask_workers_get_the_clients_kernels_once_when_they_join(tmp_path, monkeypatch):
    """A worker with its own (empty) kernel cache, as on another machine, holds the client's compiled kernels
    after joining, before any task; and its malloc is set back to an ordinary process's."""
    distributed = pytest.importorskip("distributed", reason="needs dask.distributed")
    client_cache, worker_cache = tmp_path / "client", tmp_path / "worker"
    client_cache.mkdir()
    (client_cache / "kernel_abc.so").write_bytes(b"\x7fELF compiled kernel")
    monkeypatch.setenv("MAGYRO_CACHE_DIR", str(client_cache))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40, env={"MAGYRO_CACHE_DIR": str(worker_cache)}) as c:
        with DaskCluster(c.scheduler_address) as executor:
            assert (worker_cache / "kernel_abc.so").read_bytes() == b"\x7fELF compiled kernel"
            from magyro.dask_worker import ordinary_malloc
            assert executor.submit(ordinary_malloc).result() is True


def test_workers_that_cannot_start_are_one_clear_error_not_a_crashed_fleet(fleet, tmp_path):
    """A script that runs a batch with jobs=2 without `if __name__ == "__main__":` kills every worker it starts
    (each re-runs the script); the batch stops with the cause instead of restarting the pool forever."""
    import subprocess

    script = tmp_path / "no_main_guard.py"
    script.write_text("from magyro.batch import run_batch\n"
                      f"run_batch([{str(fleet / 'manifest.csv')!r}], {str(tmp_path / 'out')!r}, jobs=2)\n")
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0
    # the last line of the script's error, before what multiprocessing's resource tracker may print at exit about
    # the killed workers' semaphores (seen under load)
    lines = [line for line in r.stderr.splitlines() if "resource_tracker" not in line and not line.startswith("  ")]
    assert 'must start its work under `if __name__ == "__main__":`' in lines[-1], r.stderr
    rows = [json.loads(p.read_text())["row"] for p in (tmp_path / "out" / "rows").glob("*.json")]
    assert len(rows) <= 2 and all(r["exit_class"] == "crashed" for r in rows)   # tried again by a rerun
