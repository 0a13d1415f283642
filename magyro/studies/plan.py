"""`magyro plan`: a motion a person can do by hand, chosen for the smallest predicted std of the gyro parameters.

A plan is a short list of turns (`scenario.Turn`: an axis of the device, an angle, a pace) and rests,
written as a problem file of kind "turns" (documented at the top of problems/paper-table1.toml). It
is scored by the predicted one-sigma of the 12 gyro parameters (K_g upper triangle 6, bias 3,
misalignment 3) from the Fisher information the solve uses (`crlb.cramer_rao_covariance` on the
simulated session of that motion, noise seed 0, exactly what `magyro montecarlo` prints as its CRLB
column): std / reference std per parameter, the reference being the paper's motion
(problems/paper-table1.toml's [motion]) on the same sensors, shortened to the same duration and
sped up (or slowed down) to the same peak rate. The score is the largest of the 12 ratios (the issue
asks for every parameter to improve), ties broken by their geometric mean.

The search is small and deterministic (no random draws; the noise seed of the simulated sessions is 0):

1. templates: the device's axes turned in a repeating cycle (x, y, z; x, y, z and the diagonals
   x+y, y+z, z+x; or all 13: x, y, z, the six diagonals between two axes and four between three),
   each turn by 90 or 180 deg at the fastest pace the peak rate allows (peak 1.875 x the mean rate
   of the minimum-jerk profile, the pace rounded up to 0.1 s), in one direction, reversing every
   cycle, or each turn undone right after ("back and forth"), without pauses or with a 1 or 2 s
   pause before every 2nd or 4th turn; 1 s rests at both ends, the turns repeated while they fit
   (the time left over goes to the end rest);
2. refinement of the best template: `REFINE_EVALUATIONS` single-turn changes drawn from a fixed seed
   (one turn's axis, among the 13, and direction; or its angle, 90/180/360 deg; or the pause before
   it, 0/1/2 s), each kept when it lowers the score.

What the search found (60 s, 200 deg/s, the paper's sensors): holding still now and then matters
for the bias (a turning device averages its bias out of the attitude, as carouselling does; a still
one lets it show as a drift), turning fast about many different axes for K_g and the misalignment,
and turns that are reversed or undone for the non-orthogonality; 360 deg turns lose the axis' tilt
(a full turn about a slightly wrong axis ends where it began).

The plan is for the base problem's start pose in its field (paper-table1: C0 = identity in ENU, x east,
y north, z up, dip 60 deg): the search fits the turns to where the field is in the device at the start.
Started from another pose, the same turns do less well (measured for the 60 s, 200 deg/s plan against the
paper's motion started from the same pose: largest ratio 0.69 from [0, 0, 0] and [180, 0, 0], 0.98 from
yaw 90, 1.26 from roll 90, 1.35 from pitch 90, 1.15 and 1.06 from two oblique poses; the bias is the
parameter that suffers).

The comparison rows are the paper's motion and the canonical motions of problems/ (three-axes,
two-axes, axis-x, axis-y, axis-z: their [motion] on the base sensors) at the plan's duration and
peak rate: their frequency band is scaled by the factor k that makes the peak body rate (the
largest |w^b| over the gyro samples) equal the maximum rate, so the device turns through the same
angles, k times faster (every frequency of the motion draw scales by exactly k, phases and
amplitudes stay). k is found by a few fixed-point steps k <- k max_rate / peak(k) (the peak is
nearly proportional to k; the window's ramps, which do not scale, make it not exactly so). A
motion that cannot be rescaled (its ramps do not fit the duration, its band would pass the
Nyquist frequency) has its reason in place of the numbers.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import time
from dataclasses import dataclass

import numpy as np

from magyro.errors import InputError
from magyro.result.reported import REPORTED
from magyro.studies.scenario import Scenario, Turn, load_problem

# the gyro parameters lead the reported vector, in GYRO_ROWS order
assert (REPORTED["K_g"], REPORTED["bias_deg_s"], REPORTED["misalignment_deg"]) == (slice(0, 6), slice(6, 9),
                                                                                   slice(9, 12))
GYRO_ROWS = ([f"K_g[{i},{j}]" for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
             + [f"bias_deg_s[{i}]" for i in range(3)] + [f"misalignment_deg[{i}]" for i in range(3)])
GROUPS = {  # the table's groups of gyro parameters
    "scale factors (K_g diagonal)": ["K_g[0,0]", "K_g[1,1]", "K_g[2,2]"],
    "non-orthogonality (K_g above)": ["K_g[0,1]", "K_g[0,2]", "K_g[1,2]"],
    "bias": ["bias_deg_s[0]", "bias_deg_s[1]", "bias_deg_s[2]"],
    "misalignment": ["misalignment_deg[0]", "misalignment_deg[1]", "misalignment_deg[2]"],
}
PAPER = "paper-table1"
CANONICAL = ("three-axes", "two-axes", "axis-x", "axis-y", "axis-z")

# the templates (module doc, step 1)
_S2, _S3 = 1.0 / math.sqrt(2.0), 1.0 / math.sqrt(3.0)
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0),
        "x+y": (_S2, _S2, 0.0), "y+z": (0.0, _S2, _S2), "z+x": (_S2, 0.0, _S2),
        "x-y": (_S2, -_S2, 0.0), "y-z": (0.0, _S2, -_S2), "z-x": (-_S2, 0.0, _S2),
        "x+y+z": (_S3, _S3, _S3), "x-y+z": (_S3, -_S3, _S3), "x+y-z": (_S3, _S3, -_S3), "-x+y+z": (-_S3, _S3, _S3)}
AXIS_CYCLES = (("x", "y", "z"), ("x", "y", "z", "x+y", "y+z", "z+x"), tuple(AXES))
ANGLES_DEG = (90.0, 180.0)
DIRECTIONS = ("same", "reverse each cycle", "back and forth")
PAUSES = ((0.0, 1), (1.0, 2), (1.0, 4), (2.0, 4))        # (pause s, before every n-th turn)
REST_S = 1.0                   # still at both ends, at least
PACE_STEP_S = 0.1              # turn durations are rounded up to this
PEAK_OVER_MEAN = 1.875         # smoothstep: peak slope 15/8
MIN_DURATION_S = 2 * REST_S + 1.0
# the refinement (module doc, step 2): single-turn changes drawn from a fixed seed
REFINE_EVALUATIONS = 150
REFINE_SEED = 0
REFINE_ANGLES_DEG = (90.0, 180.0, 360.0)
REFINE_PAUSES_S = (0.0, 1.0, 2.0)


# --------------------------------------------------------------------------- turns


@dataclass(frozen=True)
class Template:
    """A family member: a cycle of axes, an angle, a direction rule, a pause before every n-th turn."""

    cycle: tuple[str, ...]
    angle_deg: float
    direction: str                     # one of DIRECTIONS
    pause_s: float
    pause_every: int

    def describe(self) -> str:
        pause = "no pauses" if self.pause_s == 0 else (
            f"a {self.pause_s:g} s pause before every {'' if self.pause_every == 1 else _ordinal(self.pause_every) + ' '}"
            f"turn")
        return f"cycle {', '.join(self.cycle)}; {self.angle_deg:g} deg; {self.direction}; {pause}"

    def moves(self, n: int) -> list[tuple[str, float, float]]:
        """The first n turns as (axis name, signed angle deg, pause before it s)."""
        out, c = [], len(self.cycle)
        for k in range(n):
            if self.direction == "back and forth":   # +a1 -a1 +a2 -a2 ...
                slot, sign = (k // 2) % c, 1.0 if k % 2 == 0 else -1.0
            else:
                slot = k % c
                sign = -1.0 if self.direction == "reverse each cycle" and (k // c) % 2 == 1 else 1.0
            pause = self.pause_s if k > 0 and k % self.pause_every == 0 else 0.0
            out.append((self.cycle[slot], sign * self.angle_deg, pause))
        return out


def _ordinal(n: int) -> str:
    return {2: "2nd", 3: "3rd"}.get(n, f"{n}th")


def turn_seconds(angle_deg: float, max_rate_deg_s: float) -> float:
    """The fastest pace (a multiple of 0.1 s) whose peak rate, 1.875 |angle| / T, is at most max_rate."""
    t = PEAK_OVER_MEAN * abs(angle_deg) / max_rate_deg_s
    return round(max(PACE_STEP_S, math.ceil(t / PACE_STEP_S - 1e-9) * PACE_STEP_S), 6)


def layout(moves, duration_s: float, max_rate_deg_s: float) -> tuple[Turn, ...]:
    """Rest REST_S, the moves (axis name, signed angle, pause before) while they fit with a rest of at least
    REST_S after them, the end rest."""
    steps = [Turn(None, 0.0, REST_S)]
    t = REST_S
    for k, (axis, angle, pause) in enumerate(moves):
        seconds = turn_seconds(angle, max_rate_deg_s)
        pause = pause if k > 0 else 0.0
        if t + pause + seconds + REST_S > duration_s + 1e-9:
            break
        if pause > 0:
            steps.append(Turn(None, 0.0, pause))
        steps.append(Turn(np.array(AXES[axis]), float(angle), seconds))
        t += pause + seconds
    steps.append(Turn(None, 0.0, round(duration_s - t, 9)))
    return tuple(steps)


def fitting(moves, duration_s: float, max_rate_deg_s: float) -> int:
    """How many of the moves the layout holds."""
    return sum(not st.is_rest for st in layout(moves, duration_s, max_rate_deg_s))


def axis_label(axis: np.ndarray) -> str:
    """"+x", "-y", "+x+y" (a diagonal), or the vector itself."""
    a = np.asarray(axis, float)
    nz = np.abs(a) > 1e-9
    if np.allclose(np.abs(a[nz]), np.abs(a[nz])[0], atol=1e-6):
        return "".join(("+" if a[i] > 0 else "-") + "xyz"[i] for i in range(3) if nz[i])
    return "[" + ", ".join(f"{v:.3f}" for v in a) + "]"


def start_pose_instruction(C0: np.ndarray) -> str:
    """Where to hold the device before the first turn, from C0 = C_b^w (body to ENU): the device axes nearest
    to up and to magnetic north (the field's horizontal part points north), with how far off they are."""
    C0 = np.asarray(C0, float)
    up = int(np.argmax(np.abs(C0[2])))
    rest = [i for i in range(3) if i != up]
    north = rest[int(np.argmax(np.abs(C0[1, rest])))]
    label = lambda i, sign: ("+" if sign > 0 else "-") + "xyz"[i]   # noqa: E731
    up_label, north_label = label(up, C0[2, up]), label(north, C0[1, north])
    off_up = np.degrees(np.arccos(min(1.0, abs(C0[2, up]))))
    off_north = np.degrees(np.arccos(min(1.0, abs(C0[1, north]) / max(np.hypot(C0[0, north], C0[1, north]), 1e-12))))
    text = f"start with the device's {up_label} axis pointing up and its {north_label} axis toward magnetic north"
    if off_up > 1 or off_north > 1:
        text += f" (the plan's pose is {off_up:.0f} deg from up and {off_north:.0f} deg from north there)"
    return text


def instructions(turns: tuple[Turn, ...]) -> list[str]:
    """The turns as instructions to a person, one line per step."""
    lines = []
    for k, st in enumerate(turns, 1):
        if st.is_rest:
            lines.append(f"{k:3d}. hold the device still for {st.seconds:.1f} s")
            continue
        axis, angle = (st.axis, st.angle_deg) if st.angle_deg > 0 else (-st.axis, -st.angle_deg)
        label = axis_label(axis)
        what = "axis" if len(label) == 2 or label.startswith("[") else "diagonal axis"
        lines.append(f"{k:3d}. turn about the device's {label} {what} by {angle:g} deg in {st.seconds:.1f} s")
    return lines


# --------------------------------------------------------------------------- scoring


def gyro_covariance(problem: Scenario) -> np.ndarray:
    """The 12x12 Cramer-Rao covariance of the gyro parameters (GYRO_ROWS order) on the problem's noise-seed-0
    session (`crlb.cramer_rao_covariance` with default options: the information a default solve uses); all inf
    when the motion does not make every parameter observable."""
    from magyro.nls.method import NLS
    from magyro.options import Options
    from magyro.studies.crlb import cramer_rao_covariance
    from magyro.studies.simulate import simulate

    session, _ = simulate(problem, 0)
    return cramer_rao_covariance(problem, session, Options(), NLS())[:12, :12]


def gyro_std(problem: Scenario) -> dict[str, float]:
    """Predicted one-sigma of the 12 gyro parameters (the square roots of `gyro_covariance`'s diagonal; the
    layout of the reported vector, magyro.result.reported.REPORTED, starts with them in this order)."""
    sd = np.sqrt(np.maximum(np.diag(gyro_covariance(problem)), 0.0))
    return {name: float(v) for name, v in zip(GYRO_ROWS, sd)}


def ratios(std: dict[str, float], reference: dict[str, float]) -> dict[str, float]:
    return {k: std[k] / reference[k] if reference[k] > 0 else math.inf for k in GYRO_ROWS}


def score(std: dict[str, float], reference: dict[str, float]) -> tuple[float, float]:
    """(largest std / reference over the 12 gyro parameters, their geometric mean): lower is better."""
    r = np.array(list(ratios(std, reference).values()))
    if not np.all(np.isfinite(r)):
        return math.inf, math.inf
    return float(r.max()), float(np.exp(np.mean(np.log(r))))


def peak_rate_deg_s(problem: Scenario) -> float:
    """The largest |w^b| over the gyro sample times, deg/s."""
    from magyro.studies.simulate import sample_times, truth_body_rate

    w = truth_body_rate(problem, sample_times(problem.gyro_rate_hz, problem.duration_s))
    return float(np.rad2deg(np.linalg.norm(w, axis=1).max()))


def rescaled(base: Scenario, motion_source: Scenario, duration_s: float, max_rate_deg_s: float
             ) -> tuple[Scenario, float]:
    """The base sensors with `motion_source`'s motion at `duration_s`, its band scaled by k so its peak body
    rate is max_rate (module doc); (scenario, k). Raises InputError when it cannot be."""
    from magyro.studies.scenario import _check_consistency

    m = motion_source.motion
    if m.kind not in ("euler", "sequential"):
        raise InputError(f"a '{m.kind}' motion has no frequency band to rescale")

    def at(k: float) -> Scenario:
        motion = dataclasses.replace(m, band_hz=(m.band_hz[0] * k, m.band_hz[1] * k))
        s = dataclasses.replace(base, name=motion_source.name, duration_s=duration_s, motion=motion,
                                description=motion_source.description)
        _check_consistency(s, motion_source.name)
        return s

    k = 1.0
    for _ in range(8):
        peak = peak_rate_deg_s(at(k))
        if peak <= 0:
            raise InputError("the motion does not move")
        if abs(peak - max_rate_deg_s) <= 1e-4 * max_rate_deg_s:
            break
        k *= max_rate_deg_s / peak
    return at(k), k


# --------------------------------------------------------------------------- the plan


@dataclass
class Comparison:
    """One motion of the comparison table: its predicted gyro std, or why there is none."""

    name: str
    how: str                          # how it was brought to the plan's duration and peak rate
    std: dict[str, float] | None
    error: str | None = None


@dataclass
class Plan:
    """The chosen turns, their predicted std, and the motions they are compared with."""

    duration_s: float
    max_rate_deg_s: float
    gyro_noise_deg_s_sqrt_hz: float
    mag_noise: float
    base: Scenario                    # the base problem, with the noise levels of the plan
    turns: tuple[Turn, ...]
    template: str                     # the chosen template (after refinement)
    std: dict[str, float]             # predicted one-sigma of the 12 gyro parameters
    reference: Comparison             # the paper's motion at the same duration and peak rate
    comparisons: list[Comparison]     # the canonical motions
    searched: str                     # what the search tried
    evaluations: int
    seconds: float

    @property
    def name(self) -> str:
        return f"plan-{self.duration_s:g}s"

    @property
    def ratio_to_paper(self) -> dict[str, float]:
        return ratios(self.std, self.reference.std)

    @property
    def peak_rate(self) -> float:
        return max(st.peak_rate_deg_s for st in self.turns)

    def problem(self) -> Scenario:
        """The plan as a Scenario (the base sensors, the turns)."""
        return plan_scenario(self.base, self.turns, self.duration_s, self.name,
                             f"magyro plan: {self.duration_s:g} s of turns by hand, peak {self.max_rate_deg_s:g} deg/s")

    # ------------------------------------------------------------------ text

    def table(self) -> str:
        lines = [f"magyro plan: {self.duration_s:g} s, peak rate {self.max_rate_deg_s:g} deg/s, gyro noise "
                 f"{self.gyro_noise_deg_s_sqrt_hz:g} deg/s/sqrt(Hz), magnetometer noise {self.mag_noise:g} "
                 f"{self.base.mag_unit} (sensors of {self.base.name})",
                 "",
                 "The motion (each turn about the device's own axis, wherever the previous turns left it; "
                 "right-hand rule: thumb along the axis, fingers curl the way to turn; start slowly, be "
                 "fastest half way, stop smoothly):"]
        lines.append(f"  0. {start_pose_instruction(self.base.C0)}: the turns are chosen for where the field "
                     "lies in the device, so this start pose matters")
        lines += instructions(self.turns)
        lines += ["", f"Predicted one-sigma (Cramer-Rao bound, the information the solve uses) against the "
                      f"paper's motion ({self.reference.how}):"]
        others = [c for c in self.comparisons]
        head = f"  {'parameter':<22}{'plan':>11}{'paper':>11}{'plan/paper':>11}"
        head += "".join(f"{c.name:>12}" for c in others)
        lines.append(head)
        ref = self.reference.std
        for name in GYRO_ROWS:
            row = f"  {name:<22}{self.std[name]:>11.3g}{ref[name]:>11.3g}{self.std[name] / ref[name]:>11.2f}"
            row += "".join(f"{c.std[name]:>12.3g}" if c.std else f"{'-':>12}" for c in others)
            lines.append(row)
        lines += ["", "By group (plan / other motion; the largest ratio in the group, and the mean):"]
        head = f"  {'group':<32}{'vs paper':>14}" + "".join(f"{'vs ' + c.name:>16}" for c in others)
        lines.append(head)
        for group, names in GROUPS.items():
            row = f"  {group:<32}{_group_ratio(self.std, ref, names):>14}"
            row += "".join(f"{_group_ratio(self.std, c.std, names):>16}" for c in others)
            lines.append(row)
        lines.append("")
        for c in [self.reference] + others:
            lines.append(f"  {c.name}: {c.error if c.error else c.how}")
        e = self.base.motion.initial_euler_deg
        lines += ["", f"The plan is for the start pose of {self.base.name} (C0 = [roll, pitch, yaw] "
                      f"[{e[0]:g}, {e[1]:g}, {e[2]:g}] deg from ENU, x east, y north, z up) in a field of dip "
                      f"{self.base.dip_deg:g} deg; from another start pose the same turns predict a larger std "
                      f"(see magyro/studies/plan.py).",
                  f"Search: {self.searched}", f"Chosen: {self.template}; {self.evaluations} motions scored in "
                  f"{self.seconds:.0f} s."]
        return "\n".join(lines)

    def to_problem_toml(self) -> str:
        """A complete problem file: the base sensors with the plan's noise levels, the turns, and the plan's
        predicted std in an informational [plan] table."""
        b = self.base
        q = _toml_str
        turns = []
        for st in self.turns:
            if st.is_rest:
                turns.append(f"  {{rest_s = {_num(st.seconds)}}},")
            else:
                axis = ", ".join(_num(round(float(v), 12)) for v in st.axis)
                turns.append(f"  {{axis = [{axis}], angle_deg = {_num(st.angle_deg)}, seconds = {_num(st.seconds)}}},")
        ratio = self.ratio_to_paper
        lines = [
            "# magyro problem written by `magyro plan`; every key is documented at the top of paper-table1.toml.",
            "# [plan] is informational (the simulator does not read it): the search, the predicted one-sigma of",
            "# the gyro parameters (the Cramer-Rao bound at noise seed 0, as `magyro montecarlo` prints it), and",
            "# that of the paper's motion at the same duration and peak rate (`reference_std`) with the ratios.",
            "",
            "[problem]",
            f"name = {q(self.name)}",
            f"description = {q(self.problem().description)}",
            f"duration_s = {_num(self.duration_s)}",
            "",
            "[gyro]",
            f"rate_hz = {_num(b.gyro_rate_hz)}",
            f"noise_density_deg_s_sqrt_hz = {_num(b.gyro_noise_density_deg_s_sqrt_hz)}",
            f"K_g = {_matrix(b.K_g)}",
            f"bias_deg_s = {_vec(b.gyro_bias_deg_s)}",
            "",
            "[misalignment]",
            f"euler_deg = {_vec(b.misalignment_euler_deg)}",
            "",
            "[magnetometer]",
            f"rate_hz = {_num(b.mag_rate_hz)}",
            f"time_offset_s = {_num(b.mag_time_offset_s)}",
            f"noise = {_num(b.mag_noise_std)}",
            f"unit = {q(b.mag_unit)}",
            f"field_strength = {_num(b.field_strength)}",
            f"dip_deg = {_num(b.dip_deg)}",
            f"soft_iron = {_matrix(b.soft_iron)}",
            f"hard_iron = {_vec(b.hard_iron)}",
            "",
            "[motion]",
            'kind = "turns"',
            f"initial_euler_deg = {_vec(b.motion.initial_euler_deg)}",
            "turns = [",
            *turns,
            "]",
            "",
            "[plan]",
            'generated_by = "magyro plan"',
            f"max_rate_deg_s = {_num(self.max_rate_deg_s)}",
            f"peak_rate_deg_s = {_num(round(self.peak_rate, 6))}",
            f"base = {q(b.name)}",
            f"template = {q(self.template)}",
            f"search = {q(self.searched)}",
            f"reference = {q(self.reference.how)}",
            f"max_ratio_to_reference = {_num(round(max(ratio.values()), 6))}",
            "",
            "[plan.predicted_std]",
            *[f"{q(k)} = {_num(v)}" for k, v in self.std.items()],
            "",
            "[plan.reference_std]",
            *[f"{q(k)} = {_num(v)}" for k, v in self.reference.std.items()],
            "",
            "[plan.ratio_to_reference]",
            *[f"{q(k)} = {_num(round(v, 6))}" for k, v in ratio.items()],
        ]
        text = "\n".join(lines) + "\n"
        _check_round_trip(text, self)
        return text

    def to_dict(self) -> dict:
        return {
            "duration_s": self.duration_s, "max_rate_deg_s": self.max_rate_deg_s,
            "turns": [{"rest_s": st.seconds} if st.is_rest else
                      {"axis": st.axis.tolist(), "angle_deg": st.angle_deg, "seconds": st.seconds} for st in self.turns],
            "std": self.std, "reference": dataclasses.asdict(self.reference),
            "comparisons": [dataclasses.asdict(c) for c in self.comparisons],
            "template": self.template, "searched": self.searched, "evaluations": self.evaluations,
            "seconds": self.seconds,
        }


def std_ratio_interval(cov: np.ndarray, runs: int, level: float = 0.99, draws: int = 20000) -> tuple[float, float]:
    """The `level` interval of mean_i(s_i / sigma_i) over the parameters of `cov`, s_i the sample std (ddof 1) of
    `runs` draws from N(0, cov): where a Monte Carlo's mean actual / predicted std falls by its sampling error
    alone when the prediction is exact (by simulation, seed 1; the parameters are correlated, so the mean's
    spread is wider than 1/sqrt(n) of one parameter's, about 1/sqrt(2 (runs - 1)))."""
    rng = np.random.default_rng(1)
    sigma = np.sqrt(np.diag(cov))
    L = np.linalg.cholesky(cov / np.outer(sigma, sigma) + 1e-12 * np.eye(len(sigma)))
    z = rng.standard_normal((draws, runs, len(sigma))) @ L.T
    m = np.mean(np.std(z, axis=1, ddof=1), axis=1)
    low, high = np.quantile(m, [(1 - level) / 2, (1 + level) / 2])
    return float(low), float(high)


def _check_round_trip(text: str, plan: "Plan") -> None:
    """The written problem must read back as the plan's motion (a guard on the hand-made TOML)."""
    from magyro.io.toml_file import parse_toml
    from magyro.studies.scenario import parse_problem

    back = parse_problem(parse_toml(text), source=plan.name)
    assert len(back.motion.turns) == len(plan.turns)
    for a, b in zip(back.motion.turns, plan.turns):
        assert a.is_rest == b.is_rest and a.seconds == b.seconds and a.angle_deg == b.angle_deg
        assert a.is_rest or np.allclose(a.axis, b.axis, atol=1e-12)


def _group_ratio(std: dict, other: dict | None, names: list[str]) -> str:
    if not other or not all(math.isfinite(other[n]) and other[n] > 0 for n in names):
        return "-"
    r = [std[n] / other[n] for n in names]
    return f"{max(r):.2f} / {float(np.mean(r)):.2f}"


def _toml_str(text: str) -> str:
    from magyro.text import toml_string   # controls and DEL escaped: TOML forbids them raw in a string

    return toml_string(text)


def _num(v: float) -> str:
    v = float(v)
    if not math.isfinite(v):
        return '"inf"' if v > 0 else '"nan"'
    return repr(v)


def _vec(v) -> str:
    return "[" + ", ".join(_num(x) for x in np.asarray(v, float)) + "]"


def _matrix(M) -> str:
    return "[" + ", ".join(_vec(row) for row in np.asarray(M, float)) + "]"


def plan_scenario(base: Scenario, turns: tuple[Turn, ...], duration_s: float, name: str = "plan",
                  description: str = "") -> Scenario:
    """The base sensors with a "turns" motion (checked like a problem file's)."""
    from magyro.studies.scenario import _check_consistency

    motion = dataclasses.replace(base.motion, kind="turns", seed=0, axes=(), amplitude_deg=np.zeros(0),
                                 rest_start_s=0.0, rest_end_s=0.0, turns=tuple(turns))
    s = dataclasses.replace(base, name=name, description=description, duration_s=duration_s, motion=motion,
                            source_path="")
    _check_consistency(s, name)
    return s


def make_plan(duration_s: float, gyro_noise_deg_s_sqrt_hz: float | None = None, mag_noise: float | None = None,
              max_rate_deg_s: float = 200.0, base_problem: str = PAPER,
              canonical: tuple[str, ...] = CANONICAL) -> Plan:
    """The plan (module doc): templates, then a coordinate-descent refinement, scored against the paper's
    motion at the same duration and peak rate. Noise levels default to the base problem's."""
    from magyro.progress import step

    t_start = time.perf_counter()
    duration_s = _checked(duration_s, "--duration", "s")
    max_rate_deg_s = _checked(max_rate_deg_s, "--max-rate", "deg/s")
    if duration_s < MIN_DURATION_S:
        raise InputError(f"--duration must be at least {MIN_DURATION_S:g} s (1 s still at both ends and a turn), "
                         f"got {duration_s:g}")
    if duration_s > 3600.0:
        raise InputError(f"--duration must be at most 3600 s (an hour of turning by hand), got {duration_s:g}")
    if max_rate_deg_s > 2000.0:
        raise InputError(f"--max-rate must be at most 2000 deg/s (faster than a hand turns, and than most gyros' "
                         f"range), got {max_rate_deg_s:g}")
    base = load_problem(base_problem)
    gyro_noise = base.gyro_noise_density_deg_s_sqrt_hz if gyro_noise_deg_s_sqrt_hz is None else \
        _checked(gyro_noise_deg_s_sqrt_hz, "--gyro-noise", "deg/s/sqrt(Hz)")
    mag_noise = base.mag_noise_std if mag_noise is None else _checked(mag_noise, "--mag-noise", base.mag_unit)
    base = dataclasses.replace(base, gyro_noise_density_deg_s_sqrt_hz=gyro_noise, mag_noise_std=mag_noise)
    if turn_seconds(90.0, max_rate_deg_s) + 2 * REST_S > duration_s:
        raise InputError(f"--duration {duration_s:g} s cannot hold a 90 deg turn at {max_rate_deg_s:g} deg/s "
                         f"between 1 s rests")

    step("planning: the paper's motion at the same duration and peak rate")
    reference = _comparison(base, PAPER, duration_s, max_rate_deg_s)
    if reference.error is not None:
        raise InputError(f"the paper's motion cannot be brought to {duration_s:g} s at {max_rate_deg_s:g} deg/s "
                         f"to compare with: {reference.error}")
    cache: dict[tuple, tuple[tuple[float, float], dict]] = {}
    n_moves = int(duration_s / turn_seconds(90.0, max_rate_deg_s)) + 2     # more than ever fit

    def evaluate(moves) -> tuple[tuple[float, float], dict]:
        turns = layout(moves, duration_s, max_rate_deg_s)
        key = tuple((None if st.is_rest else tuple(np.round(st.axis, 9)), st.angle_deg, st.seconds) for st in turns)
        if key not in cache:
            if all(st.is_rest for st in turns):
                cache[key] = ((math.inf, math.inf), {})
            else:
                try:
                    std = gyro_std(plan_scenario(base, turns, duration_s))
                    cache[key] = (score(std, reference.std), std)
                except InputError:
                    cache[key] = ((math.inf, math.inf), {})
        return cache[key]

    templates = [Template(cycle, angle, direction, pause, every)
                 for cycle, angle, direction, (pause, every)
                 in itertools.product(AXIS_CYCLES, ANGLES_DEG, DIRECTIONS, PAUSES)]
    best_tpl, best, best_score = None, None, (math.inf, math.inf)
    for n, tpl in enumerate(templates, 1):
        step(f"planning: template {n}/{len(templates)}")
        moves = tpl.moves(n_moves)
        sc = evaluate(moves)[0]
        if sc < best_score:
            best_tpl, best, best_score = tpl, moves, sc
    if best is None:
        raise InputError(f"no motion of turns fits {duration_s:g} s at {max_rate_deg_s:g} deg/s with an "
                         f"observable calibration")

    # refinement (module doc, step 2): one turn's axis, angle or pause changed at a time, kept when better
    rng = np.random.default_rng(REFINE_SEED)
    axes = list(AXES)
    changes = 0
    for n in range(REFINE_EVALUATIONS):
        step(f"planning: refining {n + 1}/{REFINE_EVALUATIONS}")
        moves = list(best)
        k = int(rng.integers(0, fitting(best, duration_s, max_rate_deg_s)))
        axis, angle, pause = moves[k]
        what = int(rng.integers(0, 3))
        if what == 0:
            axis, angle = axes[int(rng.integers(0, len(axes)))], float(rng.choice([-1.0, 1.0])) * abs(angle)
        elif what == 1:
            angle = math.copysign(float(rng.choice(REFINE_ANGLES_DEG)), angle)
        else:
            pause = float(rng.choice(REFINE_PAUSES_S))
        moves[k] = (axis, angle, pause)
        sc = evaluate(moves)[0]
        if sc < best_score:
            best, best_score, changes = moves, sc, changes + 1
    std = evaluate(best)[1]
    turns = layout(best, duration_s, max_rate_deg_s)
    chosen = f"{best_tpl.describe()}; then {changes} single-turn changes"

    comparisons = []
    for name in canonical:
        step(f"planning: {name} at the same duration and peak rate")
        comparisons.append(_comparison(base, name, duration_s, max_rate_deg_s))
    searched = (f"{len(templates)} templates (axis cycles {' | '.join(','.join(c) for c in AXIS_CYCLES)}; "
                f"{'/'.join(f'{a:g}' for a in ANGLES_DEG)} deg turns at the fastest pace <= {max_rate_deg_s:g} deg/s "
                f"peak; {', '.join(DIRECTIONS)}; pauses (s, every n-th turn) "
                f"{', '.join(f'{p:g}/{e}' for p, e in PAUSES)}; 1 s rests at both ends), then "
                f"{REFINE_EVALUATIONS} single-turn changes (axis of the 13, angle "
                f"{'/'.join(f'{a:g}' for a in REFINE_ANGLES_DEG)} deg, pause {'/'.join(f'{p:g}' for p in REFINE_PAUSES_S)}"
                f" s; seed {REFINE_SEED}) kept when better, {changes} kept; {len(cache)} distinct motions scored; "
                f"score: the largest std / paper std of the 12 gyro parameters")
    return Plan(duration_s, max_rate_deg_s, gyro_noise, mag_noise, base, turns, chosen, std, reference,
                comparisons, searched, len(cache), time.perf_counter() - t_start)


def _comparison(base: Scenario, name: str, duration_s: float, max_rate_deg_s: float) -> Comparison:
    try:
        scenario, k = rescaled(base, load_problem(name), duration_s, max_rate_deg_s)
    except InputError as exc:
        return Comparison(name, "", None, f"cannot be rescaled: {exc}")
    band = scenario.motion.band_hz
    how = (f"{name}'s motion on these sensors, {duration_s:g} s, its band x {k:.3f} = [{band[0]:.3g}, "
           f"{band[1]:.3g}] Hz so its peak body rate is {max_rate_deg_s:g} deg/s (same angles)")
    std = gyro_std(scenario)
    if not all(math.isfinite(v) for v in std.values()):
        return Comparison(name, how, std, f"{how}: not every gyro parameter is observable (inf)")
    return Comparison(name, how, std)


def _checked(value, option: str, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise InputError(f"{option} must be a positive number ({unit}), got {value!r}")
    return float(value)
