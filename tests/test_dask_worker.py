"""The Dask worker plugin pins BLAS to one thread (issue 22 item 7): a worker started with `dask worker
--no-nanny` runs numpy's OpenBLAS with one thread per core, and `magyro batch` results then differed from the
local pool's (one BLAS thread per worker) by up to 1.2e-9; after the plugin, every worker has one thread."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from magyro.executor import WORKER_THREAD_VARIABLES as THREAD_VARIABLES


def test_the_worker_sets_the_pools_thread_variables():
    pytest.importorskip("distributed", reason="the plugin needs dask.distributed (magyro[dask])")
    from magyro.dask_worker import THREAD_VARIABLES as worker_variables

    assert worker_variables == THREAD_VARIABLES


def env_without_thread_limits() -> dict:
    return {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}


def test_the_plugin_pins_blas_in_a_process_started_without_limits():
    """A process like a --no-nanny worker (numpy imported, no thread variables): one thread after setup()."""
    pytest.importorskip("threadpoolctl", reason="magyro[dask] installs threadpoolctl")
    pytest.importorskip("distributed", reason="the plugin needs dask.distributed (magyro[dask])")
    code = ("import numpy, json, os\n"
            "from threadpoolctl import threadpool_info\n"
            "before = {i['internal_api']: i['num_threads'] for i in threadpool_info()}\n"
            "from magyro.dask_worker import MagyroWorker\n"
            "MagyroWorker({}).setup()\n"
            "after = {i['internal_api']: i['num_threads'] for i in threadpool_info()}\n"
            "print(json.dumps([before, after, os.environ.get('OMP_NUM_THREADS')]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env_without_thread_limits(),
                         timeout=120)
    assert out.returncode == 0, out.stderr
    import json

    before, after, omp = json.loads(out.stdout)
    assert after and set(after.values()) == {1} and omp == "1", (before, after)
    assert set(before) == set(after)
    if (os.cpu_count() or 1) > 1:  # the test can fail: without the plugin there is more than one thread
        assert max(before.values()) > 1, before


def test_a_no_nanny_worker_has_one_blas_thread_after_joining(tmp_path):
    """`dask worker ADDRESS --no-nanny`, the way that gave other numbers, joined through DaskCluster: 1 thread."""
    pytest.importorskip("threadpoolctl", reason="magyro[dask] installs threadpoolctl")
    distributed = pytest.importorskip("distributed", reason="needs dask.distributed (magyro[dask])")
    from magyro.dask_worker import blas_threads
    from magyro.executor import DaskCluster

    with distributed.LocalCluster(n_workers=0, dashboard_address=":0", silence_logs=40) as cluster:
        worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
                                   "--no-nanny", "--nthreads", "1", "--no-dashboard"],
                                  env=env_without_thread_limits(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            with distributed.Client(cluster.scheduler_address, timeout="20s") as client:
                client.wait_for_workers(1, timeout=60)
                unpinned = client.run(blas_threads)
            with DaskCluster(cluster.scheduler_address) as executor:
                pinned = executor.client.run(blas_threads)
        finally:
            worker.terminate()
            worker.wait(timeout=30)
    (threads,) = pinned.values()
    assert threads and set(threads.values()) == {1}, pinned
    if (os.cpu_count() or 1) > 1:
        (before,) = unpinned.values()
        assert max(before.values()) > 1, unpinned
