"""A plan (`magyro plan`) as its result: the chosen turns with their predicted std beside the comparison
motions (`Plan`, `Comparison`), printed as a table with the instructions, and written as a problem file
(TOML, motion kind "turns", the predicted std in an informational [plan] table) that reads back as the plan.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from magyro.studies.plan_scoring import GROUPS, GYRO_ROWS, ratios
from magyro.studies.plan_turns import instructions, plan_scenario, start_pose_instruction
from magyro.studies.scenario import Scenario, Turn


@dataclass
class Comparison:
    """One motion of the comparison table: its predicted gyro std, or why there is none."""

    name: str
    how: str                          # how it was brought to the plan's duration and peak rate
    std: dict[str, float] | None
    error: str | None = None
    scenario: Scenario | None = dataclasses.field(default=None, repr=False)   # the motion as compared


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
    start_poses: tuple = ()           # (name, [roll, pitch, yaw] deg) the search scored the plan from
    pose_std: list = dataclasses.field(default_factory=list)             # the plan's std from each start pose
    pose_reference_std: list = dataclasses.field(default_factory=list)   # the paper's motion's, from each
    accelerometer: object = None      # plan_accelerometer.PlanAccelerometer: the base's accelerometer's std and poses

    @property
    def name(self) -> str:
        return f"plan-{self.duration_s:g}s"

    @property
    def ratio_to_paper(self) -> dict[str, float]:
        return ratios(self.std, self.reference.std)

    @property
    def ratio_by_pose(self) -> list[dict[str, float]]:
        """std / the paper motion's std started from the same pose, per start pose."""
        return [ratios(std, ref) for std, ref in zip(self.pose_std, self.pose_reference_std)]

    @property
    def worst_ratio(self) -> float:
        """The largest std / paper motion's over the start poses and the 12 gyro parameters."""
        return max(max(r.values()) for r in self.ratio_by_pose)

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
        if self.accelerometer is None:
            lines.append(f"  0. start in any pose, e.g. {start_pose_instruction(self.base.C0).removeprefix('start ')}: "
                         f"the turns were scored from the {len(self.start_poses)} start poses below")
        else:
            lines.append(f"  0. {start_pose_instruction(self.base.C0)}: the accelerometer's poses below need this "
                         f"axis up (the gyro's scores hold from any of the {len(self.start_poses)} start poses below)")
        lines += instructions(self.turns)
        lines += ["", *self.pose_table()]
        e = self.base.motion.initial_euler_deg
        lines += ["", f"Predicted one-sigma (Cramer-Rao bound, the information the solve uses) from {self.base.name}'s "
                      f"start pose [{e[0]:g}, {e[1]:g}, {e[2]:g}] deg, against the paper's motion ({self.reference.how}) "
                      f"and the canonical motions:"]
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
        if self.accelerometer is not None:
            lines += ["", *self.accelerometer_table()]
        lines += ["", f"Search: {self.searched}", f"Chosen: {self.template}; {self.evaluations} scorings in "
                      f"{self.seconds:.0f} s."]
        return "\n".join(lines)

    def accelerometer_table(self) -> list[str]:
        """The accelerometer's block: the poses held, what holding them cost the gyro, its predicted std."""
        from magyro.observability.gravity import FACE_CONE_DEG, FACE_ENOUGH_S, FACES
        from magyro.studies.plan_accelerometer import HOLD_S

        a = self.accelerometer
        lines = [f"The accelerometer ([accelerometer] of {self.base.name}, kept in the written plan): its six poses, "
                 f"the specific force within {FACE_CONE_DEG:g} deg of each axis (observe's rule, weighted by "
                 f"stillness, on the plan's simulated session), seconds; observe asks for {FACE_ENOUGH_S:g} s each, "
                 f"the plan holds {HOLD_S:g}:",
                 f"  {'pose':<30}" + "".join(f"{f:>8}" for f in FACES),
                 f"  {'held still':<30}" + "".join(f"{a.held_s[f]:>8.1f}" for f in FACES),
                 f"  {'in all (turning too)':<30}" + "".join(f"{a.cone_s[f]:>8.1f}" for f in FACES),
                 f"  how: {a.how}",
                 f"  the gyro's largest std / paper motion's over the start poses: {a.searched_worst_ratio:.2f} as "
                 f"searched, {self.worst_ratio:.2f} with the poses held "
                 f"(x{self.worst_ratio / a.searched_worst_ratio:.2f})"
                 f"; {a.seconds:.0f} s of CPU for the accelerometer's part ({a.pose_seconds:.0f} s for the poses)",
                 "",
                 "Predicted one-sigma of the accelerometer's 12 parameters (crlb_accelerometer: the Cramer-Rao bound "
                 "with the hand's acceleration as noise of its ensemble, magyro montecarlo's CRLB column), with the "
                 "white-noise bound (the hand still) and the spread of the solve's own weighting (not a bound: what a "
                 "solve reaches with the same hand, docs/accelerometer.md):"]
        others = [self.reference] + list(self.comparisons)
        lines.append(f"  {'parameter':<24}{'plan':>11}{'white':>11}{'solve':>11}"
                     + "".join(f"{c.name:>12}" for c in others))
        for name in a.std:
            row = f"  {name:<24}{a.std[name]:>11.3g}{a.white_std[name]:>11.3g}{a.weighted_std[name]:>11.3g}"
            row += "".join(f"{o[name]:>12.3g}" if o else f"{'-':>12}" for o in [a.reference_std, *a.comparison_std])
            lines.append(row)
        return lines

    def pose_table(self) -> list[str]:
        """Per start pose: the field in the device, the largest std / paper motion's (and which parameter), the
        geometric mean of the 12 ratios."""
        from magyro.studies.plan_scoring import field_in_device

        lines = [f"From any of these start poses every gyro parameter's predicted std is at most "
                 f"{self.worst_ratio:.2f}x that of the paper's motion started from the same pose (C0 = [roll, pitch, "
                 f"yaw] deg from ENU: x east, y north, z up; the field of dip {self.base.dip_deg:g} deg in the device):",
                 f"  {'start pose':<12}{'C0 deg':>18}{'field in device':>24}{'worst ratio':>13}  {'(parameter)':<20}"
                 f"{'geo. mean':>10}"]
        for (name, pose), r in zip(self.start_poses, self.ratio_by_pose):
            worst = max(r, key=r.get)
            field = "[" + ", ".join(f"{v:+.2f}" for v in field_in_device(self.base, pose)) + "]"
            pose_text = "[" + ", ".join(f"{v:g}" for v in pose) + "]"
            mean = float(np.exp(np.mean(np.log(list(r.values())))))
            lines.append(f"  {name:<12}{pose_text:>18}{field:>24}{r[worst]:>13.2f}  {'(' + worst + ')':<20}{mean:>10.2f}")
        return lines + ["", "Per parameter: std / the paper motion's from the same start pose:", *self.pose_ratio_table()]

    def pose_ratio_table(self) -> list[str]:
        """The 12 ratios (rows) from each start pose (columns), and the largest of each column."""
        names = [name for name, _ in self.start_poses]
        lines = [f"  {'parameter':<22}" + "".join(f"{n:>11}" for n in names)]
        for row in GYRO_ROWS:
            lines.append(f"  {row:<22}" + "".join(f"{r[row]:>11.2f}" for r in self.ratio_by_pose))
        lines.append(f"  {'largest':<22}" + "".join(f"{max(r.values()):>11.2f}" for r in self.ratio_by_pose))
        return lines

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
            *self._accelerometer_section(),
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
            f"max_ratio_over_start_poses = {_num(round(self.worst_ratio, 6))}",
            "",
            "[plan.start_poses]   # [roll, pitch, yaw] deg from ENU: the plan's std / the paper motion's from there",
            *[f"{q(name)} = {{euler_deg = {_vec(pose)}, max_ratio = {_num(round(max(r.values()), 6))}}}"
              for (name, pose), r in zip(self.start_poses, self.ratio_by_pose)],
            "",
            "[plan.predicted_std]",
            *[f"{q(k)} = {_num(v)}" for k, v in self.std.items()],
            "",
            "[plan.reference_std]",
            *[f"{q(k)} = {_num(v)}" for k, v in self.reference.std.items()],
            "",
            "[plan.ratio_to_reference]",
            *[f"{q(k)} = {_num(round(v, 6))}" for k, v in ratio.items()],
            *self._accelerometer_plan_tables(),
        ]
        text = "\n".join(lines) + "\n"
        _check_round_trip(text, self)
        return text

    def _accelerometer_section(self) -> list[str]:
        """The base's [accelerometer], so that simulate and montecarlo of the written plan calibrate it."""
        acc = self.base.accelerometer
        if acc is None:
            return []
        return ["[accelerometer]",
                f"K_a = {_matrix(acc.K_a)}",
                f"bias_m_s2 = {_vec(acc.bias_m_s2)}",
                f"misalignment_euler_deg = {_vec(acc.misalignment_euler_deg)}",
                f"noise_density_ug_sqrt_hz = {_num(acc.noise_density_ug_sqrt_hz)}",
                f"g_m_s2 = {_num(acc.g_m_s2)}",
                f"hand_translation_m = {_num(acc.hand_translation_m)}",
                ""]

    def _accelerometer_plan_tables(self) -> list[str]:
        """[plan.accelerometer]: the poses held and the accelerometer's predicted std (informational)."""
        a = self.accelerometer
        if a is None:
            return []
        q = _toml_str
        ref = [] if a.reference_std is None else ["", "[plan.accelerometer.reference_std]",
                                                   *[f"{q(k)} = {_num(v)}" for k, v in a.reference_std.items()]]
        return ["",
                "[plan.accelerometer]   # the bound: crlb_accelerometer's with the hand at noise seed 0 (montecarlo's)",
                f"how = {q(a.how)}",
                f"max_ratio_over_start_poses_as_searched = {_num(round(a.searched_worst_ratio, 6))}",
                "",
                "[plan.accelerometer.pose_held_s]   # observe's pose rule on the simulated session, still samples only",
                *[f"{q(k)} = {_num(round(v, 6))}" for k, v in a.held_s.items()],
                "",
                "[plan.accelerometer.predicted_std]",
                *[f"{q(k)} = {_num(v)}" for k, v in a.std.items()],
                "",
                "[plan.accelerometer.white_noise_std]",
                *[f"{q(k)} = {_num(v)}" for k, v in a.white_std.items()],
                "",
                "[plan.accelerometer.solve_weighting_std]   # not a bound: the spread of the solve's own weighting",
                *[f"{q(k)} = {_num(v)}" for k, v in a.weighted_std.items()],
                *ref]

    def to_dict(self) -> dict:
        out = {
            "duration_s": self.duration_s, "max_rate_deg_s": self.max_rate_deg_s,
            "turns": [{"rest_s": st.seconds} if st.is_rest else
                      {"axis": st.axis.tolist(), "angle_deg": st.angle_deg, "seconds": st.seconds} for st in self.turns],
            "std": self.std, "reference": _comparison_dict(self.reference),
            "comparisons": [_comparison_dict(c) for c in self.comparisons],
            "start_poses": [{"name": name, "euler_deg": list(pose), "std": std, "ratio": r}
                            for (name, pose), std, r in zip(self.start_poses, self.pose_std, self.ratio_by_pose)],
            "template": self.template, "searched": self.searched, "evaluations": self.evaluations,
            "seconds": self.seconds,
        }
        a = self.accelerometer
        if a is not None:    # only then: a plan without an accelerometer is what it always was
            out["accelerometer"] = {
                "std": a.std, "white_noise_std": a.white_std, "solve_weighting_std": a.weighted_std,
                "reference_std": a.reference_std, "comparison_std": a.comparison_std, "pose_held_s": a.held_s,
                "pose_seconds_observe": a.cone_s, "how": a.how,
                "max_ratio_over_start_poses_as_searched": a.searched_worst_ratio, "cpu_s": a.seconds}
        return out


def _comparison_dict(c: Comparison) -> dict:
    return {"name": c.name, "how": c.how, "std": c.std, "error": c.error}


def _check_round_trip(text: str, plan: "Plan") -> None:
    """The written problem must read back as the plan's motion (a guard on the hand-made TOML)."""
    from magyro.io.toml_file import parse_toml
    from magyro.studies.scenario import parse_problem

    back = parse_problem(parse_toml(text), source=plan.name)
    assert len(back.motion.turns) == len(plan.turns)
    assert (back.accelerometer is None) == (plan.base.accelerometer is None)
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
