"""What "good enough" means, in one place: the accuracy targets every command judges a calibration against.

There are two notions, and only two:

* **targets** (`Targets`, this module) -- the one-sigma a user *asks for*. `observe` and `watch` call a
  motion "marginal" (not yet enough) when a predicted std is above one; `report` calls the calibration
  section FAIR, not GOOD, when a std of the calibration (the gyro's, or its accelerometer's) is above one;
  `batch` rejects a device whose std is above one. One set of defaults; one TOML file changes them for
  every command (``--targets FILE``, a ``[targets]`` table; `load_targets`).
* **the refusal bound** (`magyro.options.StdBounds`, ``Options.max_std``, ``--max-std-*``) -- the std
  above which a calibration is *not worth writing*: `solve` and `observe` refuse the motion (exit 3).
  It is 10-50x looser than the targets on purpose: a calibration between the two is still far better than
  none (a phone gyro's raw scale errors are 1-3 %, its biases 0.5-3 deg/s), it just is not as good as asked.

Why the default targets are what they are (a hand-held or vehicle device dead-reckoning its heading):

* scale factor 1000 ppm: a heading error of 1000e-6 x 360 deg = 0.36 deg per full turn about that axis,
  about 1 deg after the three turns of a typical roundabout or a minute of walking about a room; below
  the 1-2 deg a magnetometer heading is good to indoors, so the gyro, not the compass, leads.
* non-orthogonality 0.1 deg: turning about one axis leaks sin(0.1 deg) = 1745 ppm into the others,
  0.6 deg per full turn -- of the same order as the scale target.
* bias 0.01 deg/s: 0.6 deg of heading drift a minute, 36 deg an hour; the same size as the scale error
  over a minute of ordinary turning (a few hundred degrees).
* misalignment 0.1 deg: the gyro's turning expressed in the magnetometer's frame is off by this angle,
  the same size as the non-orthogonality it is confused with.

The accelerometer's own (`target_acc_*` in a file; read by `report`, which judges a calibration's accelerometer against them):
a device that uses its accelerometer for gravity's direction (tilt) and, briefly, for motion:

* bias 0.02 m/s^2: 0.02 / 9.81 rad = 0.12 deg of tilt, and 1 m of position in 10 s of integrating it
  (b t^2 / 2); the size of a consumer accelerometer's bias after a good six-pose calibration.
* scale factor 2000 ppm: 2000e-6 x g = 0.02 m/s^2 along an axis that points up, the bias target's size;
  0.06 deg of tilt at most (half the scale error, at 45 deg).
* non-orthogonality 0.1 deg: sin(0.1 deg) x g = 0.017 m/s^2 of gravity leaks into another axis, again
  the bias target's size.
* misalignment 0.1 deg: gravity's direction, turned into the gyro's frame (C_b_a), off by 0.1 deg; the
  gyro's misalignment target, so that neither frame spoils the other.

A recording of a phone turned by hand for two minutes (data/broad-02.parquet) reaches about 3000 ppm and
0.03 deg/s: "marginal" -- usable, not what was asked for. Loosen the targets in a file when that is enough.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from magyro.errors import InputError

TABLE = "targets"
OTHER_TABLES = ("limits",)   # a batch limits file may carry the [targets] table too: one file for every command


@dataclass(frozen=True)
class Targets:
    """One-sigma accuracy a calibration should reach; a std above any of them is 'marginal' (observe, watch),
    FAIR (report) or rejected (batch). The `acc_*` are the accelerometer's, judged by the report. The defaults
    and why: the module's docstring."""

    scale_factor_ppm: float = 1000.0        # diagonal of K_g
    non_orthogonality_deg: float = 0.1      # off-diagonal of K_g, as an angle
    bias_deg_s: float = 0.01
    misalignment_deg: float = 0.1
    acc_scale_factor_ppm: float = 2000.0    # the accelerometer's (report): diagonal of K_a
    acc_non_orthogonality_deg: float = 0.1  # off-diagonal of K_a, as an angle
    acc_bias_m_s2: float = 0.02
    acc_misalignment_deg: float = 0.1       # C_b_a, gyro to accelerometer frame

    def text(self) -> str:
        """'1000 ppm scale, 0.1 deg non-orthogonality, 0.01 deg/s bias, 0.1 deg misalignment'."""
        return (f"{self.scale_factor_ppm:g} ppm scale, {self.non_orthogonality_deg:g} deg non-orthogonality, "
                f"{self.bias_deg_s:g} deg/s bias, {self.misalignment_deg:g} deg misalignment")

    def accelerometer_text(self) -> str:
        """'2000 ppm scale, 0.1 deg non-orthogonality, 0.02 m/s^2 bias, 0.1 deg misalignment' (the accelerometer's)."""
        return (f"{self.acc_scale_factor_ppm:g} ppm scale, {self.acc_non_orthogonality_deg:g} deg non-orthogonality, "
                f"{self.acc_bias_m_s2:g} m/s² bias, {self.acc_misalignment_deg:g} deg misalignment")


FIELDS = tuple(f.name for f in dataclasses.fields(Targets))
# the file's keys, the same names as the --target-* options (--target-scale-ppm: target_scale_ppm) and as a
# batch limits file's: target_* is an acceptance target, what is asked for; max_std_* names only the solve's
# refusal bound (--max-std-*, Options.max_std)
FILE_KEYS = {"target_scale_ppm": "scale_factor_ppm", "target_nonorth_deg": "non_orthogonality_deg",
             "target_bias_deg_s": "bias_deg_s", "target_misalignment_deg": "misalignment_deg",
             # the accelerometer's, the names of a batch limits file's target_acc_*
             "target_acc_scale_ppm": "acc_scale_factor_ppm", "target_acc_nonorth_deg": "acc_non_orthogonality_deg",
             "target_acc_bias_m_s2": "acc_bias_m_s2", "target_acc_misalignment_deg": "acc_misalignment_deg"}
KEYS = tuple(FILE_KEYS)
# the keys before one vocabulary (magyro up to 2026-12): still read, with a deprecation message
OLD_KEYS = {"scale_factor_ppm": "target_scale_ppm", "non_orthogonality_deg": "target_nonorth_deg",
            "bias_deg_s": "target_bias_deg_s", "misalignment_deg": "target_misalignment_deg"}


class DeprecatedKeyWarning(FutureWarning):
    """An old spelling of a key that is still read (shown by default; `magyro` prints it as one line)."""


def deprecated(message: str) -> None:
    import warnings
    warnings.warn(message, DeprecatedKeyWarning, stacklevel=3)


def renamed_keys(table: dict, old_keys: dict, where: str, why: str = "") -> dict:
    """`table` with every old key in `old_keys` renamed to its new key, each with a deprecation message naming
    both; an old key given beside its new one is refused (two values for one number)."""
    out = dict(table)
    for old, new in old_keys.items():
        if old not in out:
            continue
        if new in out:
            raise InputError(f"{where}: {old} is the old name of {new}, and both are given; keep {new}")
        deprecated(f"{where}: {old} is deprecated, read as {new} ({why or 'the name of --' + new.replace('_', '-')}); "
                   f"rename it")
        out[new] = out.pop(old)
    return out


def targets_from(value) -> Targets:
    """A `Targets` from None (the defaults), a `Targets`, a path of a TOML file, or the tuple
    (scale ppm, non-orthogonality deg, bias deg/s, misalignment deg)."""
    if value is None:
        return Targets()
    if isinstance(value, Targets):
        return value
    if isinstance(value, (str, Path)):
        return load_targets(value)
    return Targets(*value)


def resolve_targets(path=None, scale_factor_ppm: float | None = None, non_orthogonality_deg: float | None = None,
                    bias_deg_s: float | None = None, misalignment_deg: float | None = None) -> Targets:
    """The targets a command uses: the file's (``--targets``), else the defaults, with each number given on the
    command line (``--target-*``; None = not given) in place of the file's."""
    base = load_targets(path) if path is not None else Targets()
    given = {"scale_factor_ppm": scale_factor_ppm, "non_orthogonality_deg": non_orthogonality_deg,
             "bias_deg_s": bias_deg_s, "misalignment_deg": misalignment_deg}
    return dataclasses.replace(base, **{k: float(v) for k, v in given.items() if v is not None})


def load_targets(path) -> Targets:
    """The targets of a TOML file with a ``[targets]`` table (keys `KEYS`, target_scale_ppm ...: the names of the
    --target-* options; the old scale_factor_ppm ... read with a `DeprecatedKeyWarning`; a key left out keeps its default);
    InputError with one plain message if unusable. A ``[limits]`` table beside it (magyro batch's) is allowed."""
    from magyro.io.toml_file import read_toml

    path = Path(path)
    where = f"targets file {path}"
    if not path.exists():
        raise InputError(f"{where} not found (no such file)")
    if path.is_dir():
        raise InputError(f"{where} is a folder; give the path of a TOML file")
    raw = read_toml(path, where)
    extra = sorted(k for k in raw if k != TABLE and k not in OTHER_TABLES)
    if extra:
        raise InputError(f"{where}: unknown top-level key(s) {', '.join(extra)}; the targets go in a [targets] table")
    if TABLE not in raw:
        raise InputError(f"{where}: no [targets] table; write the targets under a [targets] line "
                         "(see docs/targets-example.toml)")
    return parse_targets(raw[TABLE], where)


def parse_targets(table, where: str = "targets") -> Targets:
    """The `Targets` of a parsed ``[targets]`` table; InputError naming `where` and the key."""
    if not isinstance(table, dict):
        raise InputError(f"{where}: targets must be a [targets] table, got {type(table).__name__}")
    unknown = sorted(k for k in table if k not in KEYS and k not in OLD_KEYS)
    if unknown:
        hint = ("; max_std_* names the solve's refusal bound (--max-std-*), a target is target_*"
                if any(k.startswith("max_std_") for k in unknown) else "")
        raise InputError(f"{where} [targets]: unknown key(s) {', '.join(unknown)}; the keys are "
                         f"{', '.join(KEYS)}{hint}")
    table = renamed_keys(table, OLD_KEYS, f"{where} [targets]")
    return Targets(**{FILE_KEYS[k]: _positive(table[k], f"{where} [targets] {k}") for k in KEYS if k in table})


def _positive(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{where} must be a positive finite number (a one-sigma), got {value!r}")
    return value


__all__ = ["Targets", "KEYS", "FILE_KEYS", "DeprecatedKeyWarning", "load_targets", "parse_targets", "resolve_targets", "targets_from"]
