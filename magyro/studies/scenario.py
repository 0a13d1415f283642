"""Problem files: the simulated `Scenario` a TOML file in ``problems/`` describes, read and checked.

A problem file (documented at the top of ``problems/paper-table1.toml``) fixes the
sensors, their errors and the motion of a scenario. The word "problem" stays with the
files and the command line (`magyro simulate PROBLEM`); in code a problem is the joint
least squares (`magyro.nls.problem`), and what a file describes is a `Scenario`. `load_problem` reads one by path or by
the name of a shipped file and raises InputError with a plain message when it
is unusable. Turning a problem into samples is `magyro.studies.simulate`.

The motion (`Motion`) is drawn from its own ``motion.seed``, so every noise
seed of a problem sees the same motion (kind "turns" is a fixed list of `Turn`, nothing drawn); `Scenario` also derives what the sensor
model needs from the file's numbers (C_b^m, K = C_b^m K_g, R, the field m^w).

The optional ``[spread]`` section (`Spread`) is the one-sigma spread of the sensor
errors from device to device around the file's values; it changes nothing in
`simulate`, and `magyro.studies.fleet.device_scenario` draws one device from it.

The optional ``[accelerometer]`` section (`Accelerometer`, issue 26) adds an accelerometer
sampled with the gyro: its errors (K_a, eps_a, C_b^a), its noise, the local gravity and how
far the hand moves the device. A problem without it simulates exactly as before.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magyro import so3
from magyro.errors import InputError
from magyro.io.toml_file import read_toml
from magyro.studies.sizes import check_sizes
from magyro.text import file_name
from magyro.studies.problem_values import (_non_negative, _number, _positive, _string, _upper_triangular,  # noqa: F401
                                          _vector, _vector3)
from magyro.studies.scenario_accelerometer import ACCELEROMETER_KEYS, Accelerometer, _parse_accelerometer  # noqa: F401


# the problems shipped with magyro: installed as package data (magyro/problems), or the
# top-level problems/ of a source checkout
PACKAGE_DIR = Path(__file__).resolve().parent.parent
PROBLEMS_DIR = next(
    (d for d in (PACKAGE_DIR / "problems", PACKAGE_DIR.parent / "problems") if d.is_dir()),
    PACKAGE_DIR.parent / "problems",
)
MOTION_KINDS = ("euler", "sequential", "static", "turns")
AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


# --------------------------------------------------------------------------- problem


@dataclass(frozen=True, eq=False)
class Motion:
    """The excitation: which body axes turn, how far, how fast, when."""

    kind: str                          # "euler" | "sequential" | "static" | "turns"
    seed: int                          # motion seed (frequencies, phases, weights)
    axes: tuple[str, ...]              # body axes of the factors, in product order
    amplitude_deg: np.ndarray          # (len(axes),) bound on |angle| of each factor
    band_hz: tuple[float, float]       # sinusoid frequencies drawn uniformly in here
    components: int                    # sinusoids per factor
    rest_start_s: float                # still at the start
    rest_end_s: float                  # still at the end
    ramp_s: float                      # C^2 ramp of the window (per slot for sequential)
    initial_euler_deg: np.ndarray      # C0 = C_b^w at rest, [roll, pitch, yaw]
    turns: tuple["Turn", ...] = ()     # kind "turns" only: the turns and rests, in order


@dataclass(frozen=True, eq=False)
class Turn:
    """One step of a "turns" motion: a turn by `angle_deg` about the unit body axis `axis` in `seconds`
    (a minimum-jerk angle profile, `motion.smoothstep`), or a rest of `seconds` (axis None, angle 0)."""

    axis: np.ndarray | None            # (3,) unit, gyro frame; None for a rest
    angle_deg: float                   # signed, right-hand rule about axis; 0 for a rest
    seconds: float                     # duration of the step

    @property
    def is_rest(self) -> bool:
        return self.axis is None

    @property
    def peak_rate_deg_s(self) -> float:
        """The peak body rate of the turn: 15/8 of its mean rate (the smoothstep's peak slope)."""
        return 0.0 if self.is_rest else 1.875 * abs(self.angle_deg) / self.seconds


@dataclass(frozen=True)
class Spread:
    """One-sigma spread of the sensor errors from device to device (the ``[spread]`` section); 0 = none.

    scale_ppm             K_g diagonal, relative: K_g[i,i] (1 + 1e-6 scale_ppm z)
    nonorthogonality_deg  K_g above the diagonal, as angles: K_g[i,j] + radians(nonorthogonality_deg) z
    bias_deg_s            eps_b, each axis
    misalignment_deg      each Euler angle of C_b^m
    soft_iron             T: diagonal relative, T[i,i] (1 + soft_iron z); above it absolute, T[i,j] + soft_iron z
    hard_iron             h, each axis, in the magnetometer unit
    time_offset_s         the magnetometer's lag
    """

    scale_ppm: float = 0.0
    nonorthogonality_deg: float = 0.0
    bias_deg_s: float = 0.0
    misalignment_deg: float = 0.0
    soft_iron: float = 0.0
    hard_iron: float = 0.0
    time_offset_s: float = 0.0

    @property
    def is_zero(self) -> bool:
        return all(getattr(self, k) == 0.0 for k in SPREAD_KEYS)

    def to_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in SPREAD_KEYS}


SPREAD_KEYS = ("scale_ppm", "nonorthogonality_deg", "bias_deg_s", "misalignment_deg", "soft_iron", "hard_iron",
               "time_offset_s")
# the relative spreads must leave the diagonals of K_g and T positive: at most 10 % (a draw below -10 sigma
# would be needed to reach zero)
SPREAD_MAX_RELATIVE = {"scale_ppm": 1e5, "soft_iron": 0.1}




@dataclass(frozen=True, eq=False)
class Scenario:
    """A complete simulated scenario; see problems/paper-table1.toml for the keys."""

    name: str
    description: str
    duration_s: float
    gyro_rate_hz: float
    gyro_noise_density_deg_s_sqrt_hz: float
    K_g: np.ndarray                    # (3, 3) upper triangular, positive diagonal
    gyro_bias_deg_s: np.ndarray        # (3,) eps_b
    misalignment_euler_deg: np.ndarray  # (3,) [roll, pitch, yaw] of C_b^m
    mag_rate_hz: float
    mag_time_offset_s: float           # the magnetometer lags the gyro by this much
    mag_noise_std: float               # per axis, in mag_unit
    mag_unit: str
    field_strength: float              # |m^w| in mag_unit
    dip_deg: float
    soft_iron: np.ndarray              # (3, 3) T, upper triangular, positive diagonal
    hard_iron: np.ndarray              # (3,) h, in mag_unit
    motion: Motion
    source_path: str = ""
    spread: Spread = Spread()           # device-to-device spread of the errors ([spread]); none by default
    accelerometer: Accelerometer | None = None   # the [accelerometer] section; None: no accelerometer

    @property
    def gyro_bias_rad_s(self) -> np.ndarray:
        return np.deg2rad(self.gyro_bias_deg_s)

    @property
    def gyro_noise_density_rad_s_sqrt_hz(self) -> float:
        return math.radians(self.gyro_noise_density_deg_s_sqrt_hz)

    @property
    def gyro_sample_std_rad_s(self) -> float:
        return self.gyro_noise_density_rad_s_sqrt_hz * math.sqrt(self.gyro_rate_hz)

    @property
    def C_b_m(self) -> np.ndarray:
        return so3.euler_to_dcm(self.misalignment_euler_deg)

    @property
    def K(self) -> np.ndarray:
        return self.C_b_m @ self.K_g

    @property
    def eps_m_rad_s(self) -> np.ndarray:
        return self.C_b_m @ self.gyro_bias_rad_s

    @property
    def R(self) -> np.ndarray:
        return np.linalg.inv(self.field_strength * self.soft_iron)

    @property
    def field_w(self) -> np.ndarray:
        """m^w in ENU, mag_unit: north, pointing down for positive dip."""
        d = math.radians(self.dip_deg)
        return self.field_strength * np.array([0.0, math.cos(d), -math.sin(d)])

    @property
    def C0(self) -> np.ndarray:
        return so3.euler_to_dcm(self.motion.initial_euler_deg)


_SCHEMA: dict[str, dict[str, bool]] = {  # section -> key -> required
    "problem": {"name": False, "description": False, "duration_s": True},
    "gyro": {"rate_hz": True, "noise_density_deg_s_sqrt_hz": True, "K_g": True, "bias_deg_s": True},
    "misalignment": {"euler_deg": True},
    "magnetometer": {
        "rate_hz": True, "time_offset_s": False, "noise": True, "unit": False,
        "field_strength": False, "dip_deg": False, "soft_iron": False, "hard_iron": False,
    },
    "motion": {
        "kind": True, "seed": False, "axes": False, "amplitude_deg": False, "band_hz": False,
        "components": False, "rest_start_s": False, "rest_end_s": False, "ramp_s": False,
        "initial_euler_deg": False, "turns": False,
    },
    "spread": {k: False for k in SPREAD_KEYS},
    "accelerometer": ACCELEROMETER_KEYS,
}
# sections a problem may leave out altogether (their required keys are required only when the section is there)
OPTIONAL_SECTIONS = ("spread", "accelerometer")
# informational sections: any keys, not read by the simulator (written by `magyro plan`); must be tables
INFORMATIONAL_SECTIONS = ("plan",)
# the [motion] keys that mean something for kind "turns" (the others are refused there, not silently ignored)
TURNS_MOTION_KEYS = ("kind", "turns", "initial_euler_deg")
# what a "turns" motion takes for the fields it has no keys for; they draw only the hand's sway (studies/hand.py),
# so a turns problem built in code (`magyro plan`) takes them too, and its hand is the one its written file reads back
TURNS_HAND = {"seed": 0, "band_hz": (0.05, 0.5), "components": 1, "ramp_s": 1.0}
TURN_KEYS = ("axis", "angle_deg", "seconds")


def resolve_problem_path(path_or_name: str | os.PathLike) -> Path:
    """A path as given, or a bare name like "paper-table1" looked up in problems/."""
    path = Path(path_or_name)
    if path.is_file():
        return path
    text = str(path_or_name)
    if os.sep not in text and "/" not in text:
        stem = text[:-5] if text.endswith(".toml") else text
        candidate = PROBLEMS_DIR / f"{stem}.toml"
        if candidate.is_file():
            return candidate
    known = ", ".join(sorted(p.stem for p in PROBLEMS_DIR.glob("*.toml"))) or "none"
    raise InputError(f"problem '{text}' not found (no such file; shipped problems: {known})")


def load_problem(path_or_name: str | os.PathLike) -> Scenario:
    """Read and check a problem TOML; raise InputError with a plain message if unusable."""
    path = resolve_problem_path(path_or_name)
    raw = read_toml(path)
    return parse_problem(raw, source=str(path), default_name=path.stem)


def parse_problem(raw: dict, source: str = "<dict>", default_name: str = "problem") -> Scenario:
    """Build a Scenario from the parsed TOML tables, checking keys, shapes and ranges."""
    _check_keys(raw, source)
    p, g, mis, mag, mo, sp = (raw.get(s, {}) for s in ("problem", "gyro", "misalignment", "magnetometer", "motion",
                                                        "spread"))
    where = lambda sec: f"{source} [{sec}]"  # noqa: E731
    problem = Scenario(
        name=file_name(_string(p.get("name", default_name), where("problem"), "name"), f"{where('problem')}: name"),
        description=_string(p.get("description", ""), where("problem"), "description"),
        duration_s=_positive(p["duration_s"], where("problem"), "duration_s"),
        gyro_rate_hz=_positive(g["rate_hz"], where("gyro"), "rate_hz"),
        gyro_noise_density_deg_s_sqrt_hz=_non_negative(
            g["noise_density_deg_s_sqrt_hz"], where("gyro"), "noise_density_deg_s_sqrt_hz"),
        K_g=_upper_triangular(g["K_g"], where("gyro"), "K_g"),
        gyro_bias_deg_s=_vector3(g["bias_deg_s"], where("gyro"), "bias_deg_s"),
        misalignment_euler_deg=_vector3(mis["euler_deg"], where("misalignment"), "euler_deg"),
        mag_rate_hz=_positive(mag["rate_hz"], where("magnetometer"), "rate_hz"),
        mag_time_offset_s=_number(mag.get("time_offset_s", 0.0), where("magnetometer"), "time_offset_s"),
        mag_noise_std=_non_negative(mag["noise"], where("magnetometer"), "noise"),
        mag_unit=_string(mag.get("unit", "unitless"), where("magnetometer"), "unit"),
        field_strength=_positive(mag.get("field_strength", 1.0), where("magnetometer"), "field_strength"),
        dip_deg=_number(mag.get("dip_deg", 60.0), where("magnetometer"), "dip_deg"),
        soft_iron=_upper_triangular(mag.get("soft_iron", np.eye(3).tolist()), where("magnetometer"), "soft_iron"),
        hard_iron=_vector3(mag.get("hard_iron", [0.0, 0.0, 0.0]), where("magnetometer"), "hard_iron"),
        motion=_parse_motion(mo, where("motion")),
        source_path=source,
        spread=_parse_spread(sp, where("spread")),
        accelerometer=_parse_accelerometer(raw["accelerometer"], where("accelerometer"))
        if "accelerometer" in raw else None,
    )
    _check_consistency(problem, source)
    return problem


def _check_keys(raw: dict, source: str) -> None:
    unknown = sorted(set(raw) - set(_SCHEMA) - set(INFORMATIONAL_SECTIONS))
    if unknown:
        raise InputError(f"{source}: unknown section(s) {unknown}; expected {sorted(_SCHEMA)} "
                         f"(and the informational {list(INFORMATIONAL_SECTIONS)})")
    for section in INFORMATIONAL_SECTIONS:
        if not isinstance(raw.get(section, {}), dict):
            raise InputError(f"{source}: [{section}] must be a table")
    for section, keys in _SCHEMA.items():
        if section in OPTIONAL_SECTIONS and section not in raw:
            continue
        table = raw.get(section, {})
        if not isinstance(table, dict):
            raise InputError(f"{source}: [{section}] must be a table")
        extra = sorted(set(table) - set(keys))
        if extra:
            raise InputError(f"{source} [{section}]: unknown key(s) {extra}; allowed: {sorted(keys)}")
        missing = sorted(k for k, required in keys.items() if required and k not in table)
        if missing:
            raise InputError(f"{source} [{section}]: missing required key(s) {missing}")


def _parse_motion(mo: dict, where: str) -> Motion:
    kind = _string(mo["kind"], where, "kind")
    if kind not in MOTION_KINDS:
        raise InputError(f"{where}: kind must be one of {list(MOTION_KINDS)}, got '{kind}'")
    if kind == "turns":
        return _parse_turns_motion(mo, where)
    if "turns" in mo:
        raise InputError(f"{where}: turns is for kind \"turns\" only (kind here is \"{kind}\")")
    default_axes = [] if kind == "static" else ["z", "y", "x"]
    axes = mo.get("axes", default_axes)
    if not isinstance(axes, list) or any(a not in AXES for a in axes):
        raise InputError(f"{where}: axes must be a list of \"x\", \"y\", \"z\", got {axes!r}")
    if kind != "static" and not axes:
        raise InputError(f"{where}: kind '{kind}' needs at least one axis")
    amplitude = _vector(mo.get("amplitude_deg", [0.0] * len(axes)), where, "amplitude_deg", len(axes))
    if np.any(amplitude < 0):
        raise InputError(f"{where}: amplitude_deg must be non-negative")
    band = _vector(mo.get("band_hz", [0.05, 0.5]), where, "band_hz", 2)
    if not 0.0 < band[0] <= band[1]:
        raise InputError(f"{where}: band_hz must be [low, high] with 0 < low <= high, got {band.tolist()}")
    components = mo.get("components", 4)
    if not isinstance(components, int) or isinstance(components, bool) or components < 1:
        raise InputError(f"{where}: components must be a positive integer, got {components!r}")
    seed = mo.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise InputError(f"{where}: seed must be a non-negative integer, got {seed!r}")
    return Motion(
        kind=kind,
        seed=seed,
        axes=tuple(axes),
        amplitude_deg=amplitude,
        band_hz=(float(band[0]), float(band[1])),
        components=components,
        rest_start_s=_non_negative(mo.get("rest_start_s", 0.0), where, "rest_start_s"),
        rest_end_s=_non_negative(mo.get("rest_end_s", 0.0), where, "rest_end_s"),
        ramp_s=_positive(mo.get("ramp_s", 2.0), where, "ramp_s"),
        initial_euler_deg=_vector3(mo.get("initial_euler_deg", [0.0, 0.0, 0.0]), where, "initial_euler_deg"),
    )


def _parse_turns_motion(mo: dict, where: str) -> Motion:
    """kind = "turns": `turns` is a list of tables, each a turn {axis, angle_deg, seconds} or a rest {rest_s}."""
    extra = sorted(set(mo) - set(TURNS_MOTION_KEYS))
    if extra:
        raise InputError(f"{where}: key(s) {extra} do not apply to kind \"turns\"; allowed: {list(TURNS_MOTION_KEYS)}")
    if "turns" not in mo:
        raise InputError(f"{where}: kind \"turns\" needs turns = [{{axis = [1, 0, 0], angle_deg = 180, "
                         f"seconds = 2.0}}, {{rest_s = 1.0}}, ...]")
    items = mo["turns"]
    if not isinstance(items, list) or not items:
        raise InputError(f"{where}: turns must be a non-empty list of tables, got {items!r}")
    steps = [_parse_turn(item, f"{where} turns[{k}]") for k, item in enumerate(items)]
    if all(step.is_rest for step in steps):
        raise InputError(f"{where}: turns holds only rests; give at least one turn")
    return Motion(
        kind="turns", axes=(), amplitude_deg=np.zeros(0), rest_start_s=0.0, rest_end_s=0.0, **TURNS_HAND,
        initial_euler_deg=_vector3(mo.get("initial_euler_deg", [0.0, 0.0, 0.0]), where, "initial_euler_deg"),
        turns=tuple(steps),
    )


def _parse_turn(item, where: str) -> Turn:
    if not isinstance(item, dict):
        raise InputError(f"{where}: must be a table {{axis, angle_deg, seconds}} or {{rest_s}}, got {item!r}")
    if "rest_s" in item:
        extra = sorted(set(item) - {"rest_s"})
        if extra:
            raise InputError(f"{where}: a rest has rest_s only, got also {extra}")
        return Turn(None, 0.0, _positive(item["rest_s"], where, "rest_s"))
    extra = sorted(set(item) - set(TURN_KEYS))
    if extra:
        raise InputError(f"{where}: unknown key(s) {extra}; a turn has {list(TURN_KEYS)}, a rest has ['rest_s']")
    missing = [k for k in TURN_KEYS if k not in item]
    if missing:
        raise InputError(f"{where}: missing key(s) {missing}; a turn has {list(TURN_KEYS)}")
    axis = _vector3(item["axis"], where, "axis")
    norm = float(np.linalg.norm(axis))
    if norm < 1e-9:
        raise InputError(f"{where}: axis must be a non-zero vector (it is normalised), got {item['axis']!r}")
    angle = _number(item["angle_deg"], where, "angle_deg")
    if angle == 0.0:
        raise InputError(f"{where}: angle_deg must not be 0 (use {{rest_s = ...}} for a rest)")
    return Turn(axis / norm, angle, _positive(item["seconds"], where, "seconds"))


def _parse_spread(sp: dict, where: str) -> Spread:
    values = {k: _non_negative(sp.get(k, 0.0), where, k) for k in SPREAD_KEYS}
    for key, limit in SPREAD_MAX_RELATIVE.items():
        if values[key] > limit:
            raise InputError(f"{where}: {key} must be at most {limit:g} (a relative spread of 10 %, which keeps the "
                             f"diagonal positive), got {sp[key]!r}")
    return Spread(**values)


def _check_consistency(problem: Scenario, source: str) -> None:
    m = problem.motion
    check_sizes(problem.duration_s, {"gyro": problem.gyro_rate_hz, "magnetometer": problem.mag_rate_hz},
                m.components, source)   # before any work: a simulation is held in memory
    if abs(problem.dip_deg) > 90.0:
        raise InputError(f"{source} [magnetometer]: dip_deg must be within [-90, 90], got {problem.dip_deg}")
    if abs(problem.mag_time_offset_s) >= problem.duration_s:
        raise InputError(f"{source} [magnetometer]: |time_offset_s| must be smaller than the duration")
    acc = problem.accelerometer
    if m.kind == "static":
        if acc is not None and acc.hand_translation_m > 0:
            raise InputError(f"{source} [accelerometer]: a \"static\" motion does not move: hand_translation_m must "
                             f"be 0, got {acc.hand_translation_m:g}")
        return
    if m.kind == "turns":
        total = sum(step.seconds for step in m.turns)
        if total > problem.duration_s + 1e-9:
            raise InputError(f"{source} [motion]: the turns and rests take {total:g} s, longer than duration_s = "
                             f"{problem.duration_s:g} s (the time left after them is a rest)")
        shortest = 10.0 / min(problem.gyro_rate_hz, problem.mag_rate_hz)
        for k, step in enumerate(m.turns):
            if not step.is_rest and step.seconds < shortest:
                raise InputError(f"{source} [motion] turns[{k}]: seconds = {step.seconds:g} is shorter than 10 "
                                 f"samples of the slower sensor ({shortest:g} s): the turn would not be resolved")
        return
    nyquist = 0.5 * min(problem.gyro_rate_hz, problem.mag_rate_hz)
    if m.band_hz[1] >= nyquist:
        raise InputError(f"{source} [motion]: band_hz up to {m.band_hz[1]} Hz is not below the Nyquist "
                         f"frequency {nyquist} Hz of the slower sensor")
    active = problem.duration_s - m.rest_start_s - m.rest_end_s
    slots = len(m.axes) if m.kind == "sequential" else 1
    if active < 2.0 * m.ramp_s * slots:
        raise InputError(f"{source} [motion]: {active:g} s of motion between the rests cannot hold "
                         f"{slots} slot(s) with {m.ramp_s:g} s ramps at both ends")
