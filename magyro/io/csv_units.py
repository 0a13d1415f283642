"""The units a CSV import accepts, by label: time, accelerometer and magnetometer (the gyro's are in `magyro.io.checks`).

`time_factor`, `acc_factor`: seconds or m/s^2 per unit of the file; `acc_unit_from_gravity`: the unit
in which an accelerometer reads gravity as it does; `mag_unit_label`: the
canonical label of a magnetometer unit (the readings keep their unit); `gyro_unit_label`:
rad/s or deg/s. Each refuses an unknown label with the list of known ones.
"""
from __future__ import annotations

import re

from magyro.errors import InputError
from magyro.io.checks import canonical_gyro_unit
from magyro.options import STANDARD_GRAVITY_M_S2

TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0,
              "ms": 1e-3, "msec": 1e-3, "millisecond": 1e-3, "milliseconds": 1e-3,
              "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "usec": 1e-6, "microsecond": 1e-6, "microseconds": 1e-6,
              "ns": 1e-9, "nsec": 1e-9, "nanosecond": 1e-9, "nanoseconds": 1e-9}
ACC_UNITS = {"m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0, "m/s/s": 1.0, "mps2": 1.0,
             "g": STANDARD_GRAVITY_M_S2, "mg": 1e-3 * STANDARD_GRAVITY_M_S2}
# the magnetometer keeps its unit (results come back in it); these are the labels accepted
MAG_UNITS = {"ut": "uT", "µt": "uT", "μt": "uT", "microtesla": "uT", "nt": "nT", "nanotesla": "nT",
             "mt": "mT", "millitesla": "mT", "t": "T", "tesla": "T",
             "g": "G", "gauss": "G", "mg": "mG", "milligauss": "mG",
             "counts": "counts", "count": "counts", "lsb": "counts", "raw": "counts", "adc": "counts",
             "a.u.": "a.u.", "au": "a.u.", "arb": "a.u.", "unitless": "unitless", "1": "unitless",
             "unknown": "unknown"}
# what an accelerometer that holds gravity reads as its median |a| in each unit: how `--acc-unit auto` and the
# recording check (magyro.front.accelerometer_checks) tell the unit
GRAVITY_READS = {"g": (0.5, 2.0), "m/s^2": (4.9, 20.0), "mg": (500.0, 2000.0)}


def canonical_key(unit: str) -> str:
    return "".join(str(unit).split()).lower()


def gyro_unit_label(where, unit: str) -> str:
    try:
        return canonical_gyro_unit(unit, "--gyro-unit")
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def mag_unit_label(where, unit: str) -> str:
    key = canonical_key(unit)
    if key not in MAG_UNITS:
        known = sorted(set(MAG_UNITS.values()))
        raise InputError(f"{where}: unknown magnetometer unit {unit!r}; use one of {', '.join(known)} "
                         f"(the readings keep their unit, it is only a label)")
    return MAG_UNITS[key]


def unit_factor(where, unit: str, table: dict, what: str) -> float:
    key = canonical_key(unit)
    folded = {canonical_key(k): v for k, v in table.items()}
    if key not in folded:
        shown = ", ".join(dict.fromkeys(k for k in table if k.isascii()))
        raise InputError(f"{where}: unknown {what} unit {unit!r}; use one of {shown}")
    return folded[key]


def time_factor(where, unit: str) -> float:
    return unit_factor(where, unit, TIME_UNITS, "time")


def acc_factor(where, unit: str) -> float:
    return unit_factor(where, unit, ACC_UNITS, "accelerometer")


def acc_unit_from_gravity(median_norm: float) -> str | None:
    """The accelerometer unit (a key of GRAVITY_READS) in which gravity reads `median_norm`; None when in none."""
    return next((unit for unit, (low, high) in GRAVITY_READS.items() if low <= median_norm <= high), None)


def time_unit_label(factor: float) -> str:
    return {1.0: "s", 1e-3: "ms", 1e-6: "us", 1e-9: "ns"}[factor]


# --------------------------------------------------------------------------- units a header says

# "gx (deg/s)", "mag_x [uT]", "Accelerometer X (g)": the last bracketed text of a column name
_ANNOTATION = re.compile(r"[\(\[]\s*([^()\[\]]*?)\s*[\)\]]\s*$")
# the kinds of unit, the session columns each is read from, and the option that gives it
UNIT_KINDS = {"time": (("t",), "--time-unit"), "gyro": (("gx", "gy", "gz"), "--gyro-unit"),
              "magnetometer": (("mx", "my", "mz"), "--mag-unit"),
              "accelerometer": (("ax", "ay", "az"), "--acc-unit")}


def canonical_unit(kind: str, unit: str) -> str | None:
    """The canonical label of `unit` as a unit of `kind` (time, gyro, magnetometer, accelerometer), or None."""
    key = canonical_key(unit)
    if kind == "gyro":
        from magyro.io.checks import GYRO_UNIT_ALIASES
        return GYRO_UNIT_ALIASES.get(key)
    if kind == "magnetometer":
        return MAG_UNITS.get(key)
    table = TIME_UNITS if kind == "time" else ACC_UNITS
    folded = {canonical_key(k): k for k in table}
    if key not in folded:
        return None
    factor = table[folded[key]]
    return time_unit_label(factor) if kind == "time" else next(k for k, v in table.items() if v == factor)


def column_annotation(column: str) -> str | None:
    m = _ANNOTATION.search(str(column))
    return m.group(1) if m and m.group(1) else None


def header_units(where, mapping: dict) -> dict[str, tuple[str, str]]:
    """{kind: (unit, column)} for every kind whose mapped columns carry a unit in brackets ("gx (deg/s)",
    "mag_x [uT]"); text in brackets that is no unit of the kind ("X (axis 1)") is not a unit. The axes of
    one sensor that say different units are refused."""
    out = {}
    for kind, (names, _) in UNIT_KINDS.items():
        said = {}
        for name in names:
            if name in mapping:
                text = column_annotation(mapping[name])
                unit = canonical_unit(kind, text) if text else None
                if unit is not None:
                    said.setdefault(unit, mapping[name])
        if len(said) > 1:
            shown = ", ".join(f"{column!r} says {unit}" for unit, column in said.items())
            raise InputError(f"{where}: the {kind} columns' headers say different units ({shown}); "
                             f"fix the header or give {UNIT_KINDS[kind][1]} and the header's units agree")
        if said:
            ((unit, column),) = said.items()
            out[kind] = (unit, column)
    return out


def resolved_unit(where, kind: str, given: str | None, said: dict, default: str | None = None) -> str | None:
    """The unit of `kind`: the option's (`given`, checked against the header), else the header's
    (`said`, from `header_units`), else `default`. An option the header contradicts is refused naming both."""
    option = UNIT_KINDS[kind][1]
    if kind in said:
        unit, column = said[kind]
        if given is not None and canonical_key(given) != "auto":
            mine = canonical_unit(kind, given)
            if mine is not None and mine != unit:
                raise InputError(f"{where}: {option} {given} contradicts the header, whose column {column!r} says "
                                 f"{unit}; leave out {option} (the header's unit is read) or correct the header")
            return given
        return unit
    return given if given is not None else default
