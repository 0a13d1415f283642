"""The slow part of the watch: `magyro observe`'s prediction of every gyro parameter's one-sigma on the data so
far, run by a `Predictor` in a background process (or thread, or inline for tests), and whether it meets the
targets (`meets`). `magyro.live.monitor` asks for one whenever the rank is 12 and the last one is in.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from magyro.errors import MagyroError
from magyro.session import Session

REFRESH_S = 2.0             # default: a new prediction at most every this many seconds of data ...
COST_FACTOR = 2.0           # ... and at most every this many times the last prediction's cost
                            # (benchmarks/bench_watch.py, 2-core machine under load: 0.2-0.5 s on 60-120 s
                            # at 100 Hz, 0.26-1.3 s at 200 Hz; the worker is busy at most half the time)
GROUPS = ("scale_ppm", "nonorth_deg", "bias_deg_s", "misalignment_deg")
GROUP_LABELS = {"scale_ppm": ("scale factor", "ppm"), "nonorth_deg": ("non-orthogonality", "deg"),
                "bias_deg_s": ("bias", "deg/s"), "misalignment_deg": ("misalignment", "deg")}


def targets_dict(targets) -> dict:
    """`Targets` as {group: target} in the groups' units."""
    return {"scale_ppm": targets.scale_factor_ppm, "nonorth_deg": targets.non_orthogonality_deg,
            "bias_deg_s": targets.bias_deg_s, "misalignment_deg": targets.misalignment_deg}


@dataclass
class Prediction:
    """One `magyro observe` prediction on the data up to `t_s` (session time: the samples' own t)."""

    t_s: float
    std: dict | None               # {group: [3 values]} in the groups' units, None when observe gives none
    verdict: str
    reason: str
    rank: int
    seconds: float                 # how long observe took
    error: str | None = None


def meets(p: Prediction, targets) -> bool:
    """Every predicted one-sigma within its target (the test of `magyro observe`'s "sufficient" verdict)."""
    if p.std is None:
        return False
    t = targets_dict(targets)
    return all(np.all(np.isfinite(p.std[g])) and float(np.max(p.std[g])) <= t[g] for g in GROUPS)


# --------------------------------------------------------------------------- the prediction


def predict_session(session: Session, t_s: float, options=None, targets=None) -> Prediction:
    """`magyro observe`'s prediction on `session` (what `magyro observe` of the saved session computes)."""
    import os

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from magyro.api import observe
    from magyro.observability.report import accuracy_rows

    start = time.perf_counter()
    try:
        report = observe(session, options, targets)
    except MagyroError as exc:
        return Prediction(t_s, None, "insufficient", str(exc), 0, time.perf_counter() - start, error=str(exc))
    std = None
    if report.predicted_std is not None:
        rows = accuracy_rows(report.predicted_std, report.targets)
        std = {g: [float(v) for v in np.asarray(values, dtype=float)] for g, (_, values, _, _) in zip(GROUPS, rows)}
    return Prediction(t_s, std, report.verdict, report.reason, int(report.rank), time.perf_counter() - start)


def _worker_ignores_sigint() -> None:
    """Ctrl-C on a terminal reaches the whole process group: the watch stops and saves, its worker just ends."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _warm() -> None:
    import os

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    import magyro.api  # noqa: F401
    import magyro.observability.excitation  # noqa: F401


class Predictor:
    """Runs `predict_session` on the data so far: `mode` "process" (a worker process, the default of
    `magyro watch`: the display never waits for it), "thread", or "inline" (at once, in `update()`:
    deterministic, for tests). A new prediction starts only when the last one is in, and at most every
    `refresh_s` seconds of data."""

    def __init__(self, mode: str = "process", refresh_s: float = REFRESH_S, options=None, targets=None):
        if mode not in ("process", "thread", "inline"):
            raise ValueError(f"unknown predictor mode {mode!r}")
        self.mode = mode
        self.refresh_s = refresh_s
        self.options = options
        self.targets = targets
        self._future = None
        self._ready: Prediction | None = None
        self._last_submit_t: float | None = None
        self._executor = None
        self.history: list[Prediction] = []

    @property
    def busy(self) -> bool:
        return self._future is not None and not self._future.done()

    def due(self, t_s: float) -> bool:
        """Idle, and `refresh_s` seconds of data since the last start, and at least twice the last one's cost
        (so a long recording, whose prediction grows with it, keeps the worker busy at most half the time)."""
        if self.busy:
            return False
        if self._last_submit_t is None:
            return True
        last_cost = self.history[-1].seconds if self.history else 0.0
        return t_s - self._last_submit_t >= max(self.refresh_s, COST_FACTOR * last_cost)

    def submit(self, session: Session, t_s: float) -> None:
        self._last_submit_t = t_s
        if self.mode == "inline":
            self._ready = predict_session(session, t_s, self.options, self.targets)
            self.history.append(self._ready)
            return
        if self._executor is None:
            self._executor = self._start()
        self._future = self._executor.submit(predict_session, session, t_s, self.options, self.targets)

    def _start(self):
        import concurrent.futures as cf

        if self.mode == "thread":
            return cf.ThreadPoolExecutor(max_workers=1, thread_name_prefix="magyro-predict")
        import multiprocessing

        return cf.ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                      initializer=_worker_ignores_sigint)

    def warm_up(self) -> None:
        """Start the worker now and have it import what a prediction needs (a spawned process takes a second or
        two), so that the first prediction is not late by that much."""
        if self.mode == "inline" or self._executor is not None:
            return
        self._executor = self._start()
        self._executor.submit(_warm)

    def poll(self) -> Prediction | None:
        """The prediction finished since the last poll, or None."""
        if self._ready is not None:
            out, self._ready = self._ready, None
            return out
        if self._future is not None and self._future.done():
            future, self._future = self._future, None
            try:
                out = future.result()
            except Exception as exc:  # noqa: BLE001 - a broken worker must not stop the recording
                out = Prediction(self._last_submit_t or 0.0, None, "unknown", "", 0, 0.0,
                                 error=f"{type(exc).__name__}: {exc}")
            self.history.append(out)
            return out
        return None

    def close(self) -> None:
        """Stop without waiting: a prediction still running is abandoned (its worker process ended)."""
        ex, self._executor = self._executor, None
        if ex is None:
            return
        processes = list(getattr(ex, "_processes", {}).values()) if self.mode == "process" else []
        ex.shutdown(wait=False, cancel_futures=True)
        for p in processes:   # the worker process this predictor started
            if p.is_alive():
                p.terminate()
