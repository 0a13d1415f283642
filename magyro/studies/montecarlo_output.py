"""What a Monte Carlo study hands back: the result, its JSON (schema magyro.montecarlo/1), CSV and text."""
from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field

import numpy as np

from magyro import __version__
from magyro.studies.montecarlo_table import (
    ACC_GROUPS,
    PAPER_TABLE1_MEAN,
    PAPER_TABLE1_STD,
    Row,
    err_over_std_bound,
    format_rows,
    paper_summary,
    std_ratio_interval,
    target_checks,
    targets_text,
)
from magyro.studies.montecarlo_values import Outcome, is_missing, json_dict, json_number

SCHEMA = "magyro.montecarlo/1"
CSV_COLUMNS = ("method", "parameter", "group", "unit", "truth", "n", "mean", "std", "crlb", "std_over_crlb",
               "mean_error_over_std", "reported_over_actual", "paper_std", "paper_mean", "vs_paper")


@dataclass
class MethodResult:
    """One method's table, runs and failures."""

    method: str
    rows: list[Row]
    outcomes: list[Outcome]

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if not o.ok]

    @property
    def succeeded(self) -> int:
        return sum(o.ok for o in self.outcomes)

    def row(self, name: str) -> Row:
        return next(r for r in self.rows if r.name == name)

    def targets(self) -> dict:
        return target_checks(self.rows)

    @property
    def has_accelerometer(self) -> bool:
        return any(r.group in ACC_GROUPS for r in self.rows)

    def accelerometer_targets(self) -> dict:
        """The same targets on the accelerometer's 12 (issue 26), when they are in the table."""
        return target_checks(self.rows, ACC_GROUPS)

    def to_dict(self) -> dict:
        solve_s = [o.seconds for o in self.outcomes if o.ok]
        cpu_s = [o.cpu_seconds for o in self.outcomes if o.ok]
        return {
            "method": self.method,
            "succeeded": self.succeeded,
            "failed": len(self.failed),
            "failures": [o.to_dict() for o in self.failed],
            "solve_seconds_mean": json_number(float(np.mean(solve_s)) if solve_s else None),
            "solve_cpu_seconds_mean": json_number(float(np.mean(cpu_s)) if cpu_s else None),
            "parameters": [r.to_dict() for r in self.rows],
            "targets": self.targets(),
            **({"accelerometer_targets": self.accelerometer_targets()} if self.has_accelerometer else {}),
            "runs": [o.to_dict() for o in self.outcomes],
        }


@dataclass
class MonteCarloResult:
    """Every method's table over the same seeds, with the truth and the CRLB they are judged against."""

    problem: str
    problem_source: str
    runs: int
    seed0: int
    jobs: int
    methods: dict[str, MethodResult]
    truth: dict
    crlb: dict
    crlb_error: str | None
    paper_applies: bool
    wall_s: float
    start_method: str | None
    created: str
    mag_unit: str
    crlb_white: dict = field(default_factory=dict)   # with an accelerometer: the bound with the hand still

    @property
    def seeds(self) -> list[int]:
        return list(range(self.seed0, self.seed0 + self.runs))

    @property
    def failed_count(self) -> int:
        return sum(len(m.failed) for m in self.methods.values())

    @property
    def all_succeeded(self) -> bool:
        return self.failed_count == 0

    def __getitem__(self, method: str) -> MethodResult:
        return self.methods[method]

    # -- JSON
    def to_dict(self) -> dict:
        lo, hi = std_ratio_interval(min((m.succeeded for m in self.methods.values()), default=0))
        return {
            "schema": SCHEMA,
            "magyro_version": __version__,
            "created": self.created,
            "problem": {"name": self.problem, "source": self.problem_source, "mag_unit": self.mag_unit},
            "runs": self.runs,
            "seeds": self.seeds,
            "jobs": self.jobs,
            "start_method": self.start_method,
            "wall_seconds": self.wall_s,
            "all_succeeded": self.all_succeeded,
            "failed": self.failed_count,
            "truth": self.truth,
            "crlb": {"seed": self.seed0, "error": self.crlb_error, "std": json_dict(self.crlb),
                     "note": "Fisher information of the joint least squares at the true parameters and attitude "
                             "(crlb.cramer_rao_std), at the session of the first seed; the noise realisation enters "
                             "only through the gyro samples in the Jacobian. Euler-angle rows: J cov(d) J^T.",
                     **({"white_std": json_dict(self.crlb_white),
                         "accelerometer_note": "with an accelerometer (crlb_accelerometer.accelerometer_cramer_rao): "
                                               "the hand's acceleration counted as noise of its known ensemble, "
                                               "dense over the interval means; white_std: the hand still"}
                        if self.crlb_white else {})},
            "misalignment_definition": "misalignment_deg = d = Log(C_b_m_est^T C_b_m_true) in deg "
                                       "(C_true = C_est Exp(d), result.misalignment_vector(C_est, C_true)); truth 0",
            "paper_table1": {"applies": self.paper_applies, "std": PAPER_TABLE1_STD if self.paper_applies else None,
                             "mean": PAPER_TABLE1_MEAN if self.paper_applies else None},
            "std_over_crlb_95pct_interval_if_efficient": [json_number(lo), json_number(hi)],
            "methods": {name: m.to_dict() for name, m in self.methods.items()},
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)

    # -- CSV (the table, one row per method and parameter)
    def to_csv(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(CSV_COLUMNS)
        for name, m in self.methods.items():
            for r in m.rows:
                d = r.__dict__
                w.writerow([name, r.name] + ["" if is_missing(d[k]) else _csv_value(d[k]) for k in CSV_COLUMNS[2:]])
        return buf.getvalue()

    # -- text
    def table(self) -> str:
        out = []
        seeds = f"seeds {self.seed0}..{self.seed0 + self.runs - 1}" if self.runs > 1 else f"seed {self.seed0}"
        for name, m in self.methods.items():
            out.append(f"{self.problem}: {self.runs} runs ({seeds}), method {name}: "
                       f"{m.succeeded} succeeded, {len(m.failed)} failed")
            out.append(format_rows(m.rows, self.paper_applies))
            lo, hi = std_ratio_interval(m.succeeded)
            if np.isfinite(lo):
                out.append(f"with {m.succeeded} runs an efficient unbiased estimator's std/CRLB lies in [{lo:.2f}, {hi:.2f}] "
                           f"and its |err/std| below {err_over_std_bound(m.succeeded):.2f} (each 95 %)")
            out.extend(targets_text(m.targets()))
            if m.has_accelerometer:
                out.extend(targets_text(m.accelerometer_targets(), "accelerometer"))
            if self.paper_applies:
                out.append(paper_summary(m.rows))
            for o in m.failed:
                out.append(f"FAILED seed {o.seed}: {o.error_type} (exit {o.exit_code}): {o.error}")
            out.append("")
        out.append("misalignment_deg = d, C_b_m(true) = C_b_m(est) Exp(d); euler_deg = dcm2eul(C_b_m(est)) "
                   "[roll, pitch, yaw], the paper's column.")
        if self.crlb_error:
            out.append(f"no CRLB: {self.crlb_error}")
        else:
            out.append(f"CRLB at truth, computed once at seed {self.seed0}'s session"
                       + (", the hand's acceleration counted as noise of its known ensemble (with the hand still it "
                          "would be " + ", ".join(f"{k} {v:.3g}" for k, v in self.crlb_white.items()
                                                  if k.startswith(("K_a", "bias_m_s2", "acc_"))) + ")."
                          if self.crlb_white else "."))
        out.append(f"{self.wall_s:.1f} s wall, {self.jobs} job(s)")
        return "\n".join(out)


def _csv_value(v):
    return repr(float(v)) if isinstance(v, (float, np.floating)) else v


def write_outputs(result: MonteCarloResult, json_path=None, csv_path=None) -> None:
    """The JSON (schema magyro.montecarlo/1) and the CSV table, each written whole or not at all."""
    from magyro.io.atomic import write_text_atomically

    if json_path is not None:
        write_text_atomically(json_path, result.to_json() + "\n")
    if csv_path is not None:
        write_text_atomically(csv_path, result.to_csv())
