"""`magyro batch`: many devices' sessions calibrated, judged against limits, summarised as a fleet.

    from magyro.batch import run_batch, load_limits
    result = run_batch(["sessions/"], "out/", limits=load_limits("limits.toml"), jobs=2)
    print(result.table())

Modules: `inputs` (files, folders, globs, manifests as devices), `task` (one device as a worker
solves it), `row` (a device's summary row), `limits` (acceptance limits and verdicts), `summary`
(summary.parquet/.csv/.html), `run` (the batch: executor, resume, outputs). The executors are
`magyro.executor`'s, shared with `magyro montecarlo`.
"""
from __future__ import annotations

from magyro.lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {"run_batch": "run", "BatchResult": "run", "load_limits": "limits",
                                               "Limits": "limits", "devices_from_inputs": "inputs"})
__all__ = ["run_batch", "BatchResult", "load_limits", "Limits", "devices_from_inputs"]
