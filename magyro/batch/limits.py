"""Acceptance limits of a production line, and each device's verdict against them.

`load_limits(path)` reads a TOML file with a ``[limits]`` table and/or a ``[targets]`` table (an example
with every key explained: docs/limits-example.toml). The ``[targets]`` table is the accuracy targets every
command shares (magyro.targets; ``magyro observe/watch/report --targets`` read the same file): in a batch
they are the std limits (`STD_OF_TARGET`), so observe, report and batch judge a one-sigma against one set
of numbers. `with_targets(limits, targets)` adds them from ``magyro batch --targets``; `verdict(row, limits)` judges one row of the fleet
summary (`magyro.batch.row`) and `with_verdicts(rows, limits)` adds the columns ``verdict``
("accepted" | "rejected" | "failed") and ``verdict_reason`` to copies of the rows. The limits
only read the rows, so changing them never re-solves a session.

A limit left out (None) is no limit. A quantity that a limit needs but the row does not
hold (NaN) rejects the device: an acceptance never passes what it did not measure. The
``max_abs_acc_*`` and ``target_acc_*`` limits bound the accelerometer's parameters (``magyro batch --accelerometer``);
a device whose calibration has no accelerometer is rejected by them, with one reason.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path

from magyro.batch.row import AXES, EULER, PAIRS, accelerometer_columns, number_of, text_of
from magyro.errors import InputError
from magyro.io.toml_file import read_toml
from magyro.front.findings import KINDS
from magyro.targets import deprecated, renamed_keys


# the recording check's finding kinds and the calibration's other warning kinds (magyro.batch.row.warning_kind);
# "any" in reject_warnings rejects every warning
FINDING_KINDS = KINDS
WARNING_KINDS = FINDING_KINDS + ("split_check", "forced", "rests", "other")
ANY = "any"
SPLIT_HINT = "run the batch with --split-check"
ACC_HINT = "no accelerometer in the calibration: run the batch with --accelerometer on sessions with ax ay az"


@dataclass(frozen=True)
class Limits:
    """Acceptance limits; None = no limit. Absolute limits bound |value| of each axis, std limits each one-sigma."""

    max_abs_scale_ppm: float | None = None         # |K_g[i,i] - 1|, ppm
    max_abs_nonorth_deg: float | None = None       # |K_g above the diagonal| as angles, deg
    max_abs_bias_deg_s: float | None = None        # |eps_b|, deg/s
    max_abs_misalignment_deg: float | None = None  # |each Euler angle of C_b_m|, deg
    target_scale_ppm: float | None = None
    target_nonorth_deg: float | None = None
    target_bias_deg_s: float | None = None
    target_misalignment_deg: float | None = None
    # the accelerometer's (needs `magyro batch --accelerometer`; a device without it is rejected by these)
    max_abs_acc_scale_ppm: float | None = None         # |K_a[i,i] - 1|, ppm
    max_abs_acc_nonorth_deg: float | None = None       # |K_a above the diagonal| as angles, deg
    max_abs_acc_bias_m_s2: float | None = None         # |eps_a|, m/s^2
    max_abs_acc_misalignment_deg: float | None = None  # |each Euler angle of C_b_a|, deg
    target_acc_scale_ppm: float | None = None
    target_acc_nonorth_deg: float | None = None
    target_acc_bias_m_s2: float | None = None
    target_acc_misalignment_deg: float | None = None
    max_split_rms_z: float | None = None           # the split-half check's RMS z (needs --split-check)
    reject_warnings: tuple[str, ...] = ()          # warning kinds (row's warning_kinds) that reject; "any": all
    reject_findings: tuple[str, ...] = ()          # recording-check kinds (row's findings), repaired or not

    def is_empty(self) -> bool:
        return all(getattr(self, f.name) in (None, ()) for f in fields(self))

    def __getattr__(self, name: str):   # only for names that are no field: the old max_std_* ones
        if name in OLD_KEYS:
            deprecated(f"Limits.{name} is deprecated: it is Limits.{OLD_KEYS[name]} ({_WHY})")
            return getattr(self, OLD_KEYS[name])
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")


# limit -> (the row's columns it bounds, unit, absolute value?)
CHECKS = {
    "max_abs_scale_ppm": ([f"scale_ppm_{a}" for a in AXES], "ppm", True),
    "max_abs_nonorth_deg": ([f"nonorth_deg_{p}" for *_, p in PAIRS], "deg", True),
    "max_abs_bias_deg_s": ([f"bias_deg_s_{a}" for a in AXES], "deg/s", True),
    "max_abs_misalignment_deg": ([f"misalignment_deg_{e}" for e in EULER], "deg", True),
    "target_scale_ppm": ([f"std_scale_ppm_{a}" for a in AXES], "ppm", False),
    "target_nonorth_deg": ([f"std_nonorth_deg_{p}" for *_, p in PAIRS], "deg", False),
    "target_bias_deg_s": ([f"std_bias_deg_s_{a}" for a in AXES], "deg/s", False),
    "target_misalignment_deg": ([f"std_misalignment_deg_{a}" for a in AXES], "deg", False),
    "max_abs_acc_scale_ppm": ([f"acc_scale_ppm_{a}" for a in AXES], "ppm", True),
    "max_abs_acc_nonorth_deg": ([f"acc_nonorth_deg_{p}" for *_, p in PAIRS], "deg", True),
    "max_abs_acc_bias_m_s2": ([f"acc_bias_m_s2_{a}" for a in AXES], "m/s^2", True),
    "max_abs_acc_misalignment_deg": ([f"acc_misalignment_deg_{e}" for e in EULER], "deg", True),
    "target_acc_scale_ppm": ([f"std_acc_scale_ppm_{a}" for a in AXES], "ppm", False),
    "target_acc_nonorth_deg": ([f"std_acc_nonorth_deg_{p}" for *_, p in PAIRS], "deg", False),
    "target_acc_bias_m_s2": ([f"std_acc_bias_m_s2_{a}" for a in AXES], "m/s^2", False),
    "target_acc_misalignment_deg": ([f"std_acc_misalignment_deg_{a}" for a in AXES], "deg", False),
    "max_split_rms_z": (["split_rms_z"], "", False),
}
ACCELEROMETER_KEYS = tuple(k for k in CHECKS if "_acc_" in k)
NUMBER_KEYS = tuple(CHECKS)
# the accuracy targets (magyro.targets.Targets field) that set each std limit: a [targets] table's keys are
# these same names (magyro.targets.FILE_KEYS), as are the --target-* options
STD_OF_TARGET = {"scale_factor_ppm": "target_scale_ppm", "non_orthogonality_deg": "target_nonorth_deg",
                 "bias_deg_s": "target_bias_deg_s", "misalignment_deg": "target_misalignment_deg"}
LIST_KEYS = ("reject_warnings", "reject_findings")
KEYS = NUMBER_KEYS + LIST_KEYS
_WHY = ("an acceptance target is target_*, as in [targets] and --target-*; max_std_* names only the solve's refusal "
        "bound, --max-std-*")
# before one vocabulary, the std limits were max_std_* here, the name of the solve's refusal bound
# (--max-std-*): still read as their target_* name, with a deprecation message
OLD_KEYS = {key.replace("target_", "max_std_", 1): key for key in NUMBER_KEYS if key.startswith("target_")}


def _old_names_too(init):
    """Limits(max_std_scale_ppm=...) of Python code written before: read as target_scale_ppm, with a message
    (over the new name's value, which dataclasses.replace passes along)."""
    def __init__(self, *args, **kwargs):
        for old in [k for k in kwargs if k in OLD_KEYS]:
            deprecated(f"Limits(): {old} is deprecated, read as {OLD_KEYS[old]} ({_WHY}); rename it")
            kwargs[OLD_KEYS[old]] = kwargs.pop(old)
        init(self, *args, **kwargs)

    __init__.__doc__ = init.__doc__
    return __init__


Limits.__init__ = _old_names_too(Limits.__init__)


# --------------------------------------------------------------------------- reading


def load_limits(path) -> Limits:
    """Read and check a limits TOML (one ``[limits]`` table); InputError with one plain message if unusable."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"limits file {path} not found (no such file)")
    if path.is_dir():
        raise InputError(f"limits file {path} is a folder; give the path of a TOML file")
    raw = read_toml(path, f"limits file {path}")
    return parse_limits(raw, source=f"limits file {path}")


def parse_limits(raw: dict, source: str = "limits") -> Limits:
    """The `Limits` of a parsed TOML document ``{"limits": {...}, "targets": {...}}`` (either table may be left
    out, not both); InputError naming `source` and the key."""
    from magyro.targets import parse_targets

    extra = sorted(k for k in raw if k not in ("limits", "targets"))
    if extra:
        raise InputError(f"{source}: unknown top-level key(s) {', '.join(extra)}; the only ones allowed are the "
                         f"[limits] and [targets] tables")
    if "limits" not in raw and "targets" not in raw:
        raise InputError(f"{source}: no [limits] table; write the limits under a [limits] line "
                         f"(see docs/limits-example.toml)")
    table = raw.get("limits", {})
    if not isinstance(table, dict):
        raise InputError(f"{source}: limits must be a [limits] table, got {type(table).__name__}")
    unknown = sorted(k for k in table if k not in KEYS and k not in OLD_KEYS)
    if unknown:
        raise InputError(f"{source} [limits]: unknown key(s) {', '.join(unknown)}; the keys are "
                         f"{', '.join(KEYS)}")
    table = renamed_keys(table, OLD_KEYS, f"{source} [limits]", _WHY)
    if "targets" in raw:
        both = sorted(k for k in STD_OF_TARGET.values() if k in table)
        if both:
            raise InputError(f"{source}: {', '.join(both)} in [limits] and a [targets] table set the same std "
                             "targets twice; keep them in the [targets] table (observe, watch and report read it too)")
        targets = parse_targets(raw["targets"], source)
        table = {**table, **{key: getattr(targets, name) for name, key in STD_OF_TARGET.items()}}
    values: dict = {}
    for key in NUMBER_KEYS:
        if key in table:
            values[key] = _number(table[key], f"{source} [limits] {key}")
    for key in LIST_KEYS:
        if key in table:
            known = WARNING_KINDS + (ANY,) if key == "reject_warnings" else FINDING_KINDS
            values[key] = _kinds(table[key], f"{source} [limits] {key}", known)
    return Limits(**values)


def with_targets(limits: Limits | None, targets) -> Limits:
    """`limits` with its std limits set to the accuracy targets (``magyro batch --targets``); InputError when the
    limits already set them (one notion of good enough, set in one place)."""
    from dataclasses import replace

    limits = limits if limits is not None else Limits()
    already = [key for name, key in STD_OF_TARGET.items()
               if getattr(limits, key) is not None and getattr(limits, key) != getattr(targets, name)]
    if already:
        raise InputError(f"--targets and the limits file both set the std limits ({', '.join(already)}); "
                         "set them once, in the [targets] table")
    return replace(limits, **{key: getattr(targets, name) for name, key in STD_OF_TARGET.items()})


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise InputError(f"{where} must be a finite number, got {value!r}")
    if value < 0:
        raise InputError(f"{where} must not be negative (it bounds an absolute value or a std), got {value:g}")
    return value


def _kinds(value, where: str, known: tuple) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{where} must be a list of kinds (strings), e.g. [\"saturation\"], got {value!r}")
    kinds = tuple(dict.fromkeys(v.strip() for v in value))
    unknown = [k for k in kinds if k not in known]
    if unknown:
        raise InputError(f"{where}: unknown kind(s) {', '.join(repr(k) for k in unknown)}; the kinds are "
                         f"{', '.join(known)}")
    return kinds


# --------------------------------------------------------------------------- judging


def verdict(row: dict, limits: Limits | None) -> tuple[str, str]:
    """("accepted", ""), ("rejected", every broken limit with its numbers and units, "; "-joined), or, for a row
    whose status is not "calibrated", ("failed", "exit N, class: message")."""
    if row.get("status") != "calibrated":
        return "failed", failure_reason(row)
    limits = limits if limits is not None else Limits()
    reasons: list[str] = []
    acc_limited = [key for key in ACCELEROMETER_KEYS if getattr(limits, key) is not None]
    no_accelerometer = bool(acc_limited) and not any(math.isfinite(number_of(row.get(c)))
                                                     for c in accelerometer_columns())
    for key, (columns, unit, absolute) in CHECKS.items():
        limit = getattr(limits, key)
        if limit is None:
            continue
        if no_accelerometer and key in ACCELEROMETER_KEYS:   # said once, not once per column
            if key == acc_limited[0]:
                reasons.append(f"accelerometer not measured ({ACC_HINT}): {', '.join(acc_limited)} not checked")
            continue
        for column in columns:
            value = number_of(row.get(column))
            if not math.isfinite(value):
                hint = (SPLIT_HINT if column == "split_rms_z" else ACC_HINT if key in ACCELEROMETER_KEYS
                        else "the calibration did not give it")
                reasons.append(f"{column} not measured ({hint})")
            elif (abs(value) if absolute else value) > limit:
                reasons.append(_broken(column, value, limit, unit, absolute))
    warnings = kinds_of(row.get("warning_kinds"))
    rejected = warnings if ANY in limits.reject_warnings else [k for k in warnings if k in limits.reject_warnings]
    reasons += [f"warning {k}" for k in rejected]
    repaired = set(kinds_of(row.get("repaired")))
    reasons += [f"finding {k}{' (repaired)' if k in repaired else ''}" for k in kinds_of(row.get("findings"))
                if k in limits.reject_findings]
    return ("rejected", "; ".join(reasons)) if reasons else ("accepted", "")


def with_verdicts(rows, limits: Limits | None) -> list[dict]:
    """Copies of `rows`, each with the columns ``verdict`` and ``verdict_reason``."""
    out = []
    for row in rows:
        decided, reason = verdict(row, limits)
        out.append({**row, "verdict": decided, "verdict_reason": reason})
    return out


def failure_reason(row: dict) -> str:
    code = row.get("exit_code")
    try:
        code_text = str(int(code))
    except (TypeError, ValueError, OverflowError):
        code_text = "?"
    cls = text_of(row.get("exit_class")) or "not run"
    message = text_of(row.get("message")) or "no message"
    return f"exit {code_text}, {cls}: {message}"


def describe(limits: Limits | None) -> list[tuple[str, str]]:
    """(key, value with unit) of every limit set, for the summary page."""
    out = []
    if limits is None:
        return out
    for key, (_, unit, _absolute) in CHECKS.items():
        value = getattr(limits, key)
        if value is not None:
            out.append((key, f"{value:g} {unit}".strip()))
    for key in LIST_KEYS:
        value = getattr(limits, key)
        if value:
            out.append((key, ", ".join(value)))
    return out


def kinds_of(text) -> list[str]:
    """The kinds of a comma-separated column ("saturation,spikes"), in order, without blanks."""
    return [k for k in (part.strip() for part in text_of(text).split(",")) if k]


def _broken(column: str, value: float, limit: float, unit: str, absolute: bool = False) -> str:
    """"bias_deg_s_y = 0.62 > 0.50 deg/s", or for a limit on the absolute value "|bias_deg_s_y| = 0.62 > 0.50 deg/s" (of -0.62)."""
    digits = _decimals(limit)
    shown = abs(value)
    while digits < 9 and f"{shown:.{digits}f}" == f"{limit:.{digits}f}":  # 0.5004 > 0.50 must not read 0.50 > 0.50
        digits += 1
    said = f"|{column}| = {abs(value):.{digits}f}" if absolute else f"{column} = {value:.{digits}f}"
    return f"{said} > {limit:.{digits}f}{' ' + unit if unit else ''}"


def _decimals(limit: float) -> int:
    """Two significant figures of the limit (0.50, 2000, 0.050), at least none."""
    if limit <= 0:
        return 3
    return max(0, 1 - math.floor(math.log10(limit)))


__all__ = ["Limits", "load_limits", "parse_limits", "with_targets", "STD_OF_TARGET", "verdict", "with_verdicts", "describe", "KEYS",
           "FINDING_KINDS", "WARNING_KINDS"]
