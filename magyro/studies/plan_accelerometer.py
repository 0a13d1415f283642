"""What `magyro plan` does when the base problem has an [accelerometer]: the six poses its 12 parameters need, and
their predicted one-sigma.

**The poses.** The accelerometer's 12 parameters need gravity's direction to vary in the body, best over the six poses
(`observability/gravity.py`: the information is `(sum [y;1][y;1]^T) (x) I`; observe asks for each of +x -x +y -y
+z -z held FACE_ENOUGH_S = 2 s, the specific force within 45 deg of the axis, weighted by stillness). The gyro's search
(plan.py) does not know that: its rests fall wherever the turns left the device. So, after it, the planner counts the
poses as observe does on the plan's simulated session (`observed_pose_seconds`: observe's rests, g, stillness weight
and `gravity.face_seconds`, on the samples where the device does not turn). The poses depend on which way is up at
the start, unlike the gyro's scores: they are counted from the base problem's start pose. When a pose has less than
HOLD_S (observe's 2 s and a margin for another sway of the hand), two ways to hold them are tried, on the searched
plan and on the search's other finalist templates:

1. holds where the turns pass: for each missing pose, the pause before the turn (or the first rest) where gravity
   lies nearest the pose's axis, within AIM_DEG, is made HOLD_S long (the turns that no longer fit are left out);
2. a tour first: from the start pose, the fewest seconds of 90 and 180 deg turns about the device's x, y, z axes that
   visit the missing poses (or all six), a shortest path over the cube's poses, HOLD_S held at each, then the
   turns (those that still fit).

Observe's stillness weight reads |y| against the size the accelerometer reads still in that direction
(`gravity.expected_size`: an uncalibrated accelerometer's |y| differs from pose to pose by its scale and bias errors,
9.44-10.21 m/s^2 on paper-table1-acc), and the hand's sway lowers it. So the holds observe counts short are
lengthened in proportion (`lengthened`). A way
that observe then counts holding every pose is preferred; where none does (a short plan has no room), one that
holds HOLD_S of rest in each pose on the truth, and the table shows observe's count short. Among them the best gyro
score (the search's: the largest std / the paper motion's over the start poses and the gyro's 12 parameters) is
kept, then ACC_REFINE_EVALUATIONS single-turn changes of the search's refinement, each kept when it lowers the score
and still holds every pose. The gyro's price is that score against the searched plan's.

**The predicted std.** The accelerometer's 12 parameters (K_a upper triangle, bias_m_s2, misalignment) by
`crlb_accelerometer.accelerometer_cramer_rao` on the noise-seed-0 session with the options `magyro montecarlo`
solves with (`montecarlo.study_options`): the bound montecarlo prints as its CRLB column, the hand's acceleration
counted as noise of its ensemble. Beside it the white-noise bound (the hand still) and the spread of the solve's own
weighting (`weighted_accelerometer_std`, not a bound: what a solve reaches, and what a Monte Carlo's actual spread is
to be compared with; docs/accelerometer.md, "It is far from the Cramer-Rao bound").
"""
from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass

import numpy as np

from magyro import so3
from magyro.observability.gravity import FACES, face_seconds
from magyro.studies.plan_turns import AXES, REST_S, layout, plan_scenario, turn_seconds
from magyro.studies.scenario import Scenario

HOLD_S = 2.5                 # a pose's hold: observe's 2 s, and a margin for the stillness weight of the hand's sway
AIM_DEG = 30.0               # a hold placed where the turns pass: gravity within this of the pose's axis
ACC_REFINE_EVALUATIONS = 20  # single-turn changes after the poses are held (each kept when better and still holding)
LENGTHEN_ROUNDS = 3          # holds made longer where observe counts them short
MAX_HOLD_S = 3 * HOLD_S
TOUR_ANGLES_DEG = (90.0, -90.0, 180.0)
UP_W = np.array([0.0, 0.0, 1.0])   # ENU: up, the specific force at rest


@dataclass
class PlanAccelerometer:
    """The accelerometer's part of a plan: its predicted std, the poses held, what holding them cost the gyro."""

    std: dict                  # ACC_ROWS -> the bound with the hand (montecarlo's CRLB column)
    white_std: dict            # ... with the white noise alone
    weighted_std: dict         # ... the spread of the solve's own weighting (not a bound)
    reference_std: dict | None  # the paper motion's bound with the hand, or None with its reason in reference_error
    reference_error: str | None
    comparison_std: list       # per canonical comparison: the bound with the hand, or None
    held_s: dict               # pose -> seconds held still (observe's rule on the simulated session, rests only)
    cone_s: dict               # pose -> observe's own count (turning included)
    how: str                   # how the poses were held
    searched_worst_ratio: float   # the gyro's score before the poses were held
    seconds: float             # CPU of the accelerometer's part (the poses and the bounds)
    pose_seconds: float = 0.0  # CPU of holding the poses (the rest: the bounds)


# --------------------------------------------------------------------------- the poses


def rest_gravity(problem: Scenario) -> tuple[np.ndarray, np.ndarray, list]:
    """(u, seconds, owner): gravity's direction in the body (up, unit; the specific force at rest) at each rest of a
    "turns" motion from the problem's start pose, the rest's seconds (the time after the turns included), and whose
    it is in `layout`'s terms: k for the pause before the k-th turn (0: the first rest), None for the end rest."""
    from magyro.studies.motion import truth_body_attitude

    mids, seconds, owner, t, k = [], [], [], 0.0, 0
    for st in problem.motion.turns:
        if st.is_rest:
            mids.append(t + 0.5 * st.seconds)
            seconds.append(st.seconds)
            owner.append(k)
        else:
            k += 1
        t += st.seconds
    if problem.duration_s > t + 1e-9:
        mids.append(0.5 * (t + problem.duration_s))
        seconds.append(problem.duration_s - t)
        owner.append(None)
    if owner and owner[-1] == k:
        owner[-1] = None                         # the last rest is the end rest, the time left over
    C_b_w = truth_body_attitude(problem, np.array(mids))
    return np.einsum("nji,j->ni", C_b_w, UP_W), np.array(seconds), owner


def rest_pose_seconds(problem: Scenario) -> dict:
    """Seconds of the rests per pose (FACES), by observe's pose rule (`gravity.face_seconds`) on the truth: where
    the plan puts its holds."""
    u, seconds, _ = rest_gravity(problem)
    return face_seconds(u, seconds)


def held_pose_seconds(problem: Scenario) -> dict:
    """Seconds held still per pose as observe counts them on the simulated session (`observed_pose_seconds`): what
    the plan must reach (the hand's sway lowers observe's stillness weight, so a rest of HOLD_S can count less)."""
    return observed_pose_seconds(problem)[0]


def missing_holds(held_s: dict) -> list[str]:
    """The poses held less than HOLD_S, in FACES' order."""
    return [f for f in FACES if held_s[f] < HOLD_S - 1e-9]


def face_axis(face: str) -> np.ndarray:
    return (1.0 if face[0] == "+" else -1.0) * np.eye(3)["xyz".index(face[1])]


def covered(base: Scenario, turns, duration_s: float) -> bool:
    """Every pose held HOLD_S as observe counts it on the plan's simulated session."""
    return not missing_holds(held_pose_seconds(plan_scenario(base, turns, duration_s)))


def lengthened(moves, first: float, base: Scenario, duration_s: float, max_rate_deg_s: float):
    """(moves, first rest s) with the holds of the poses observe counts short made longer, in proportion (the hand's
    sway lowers its stillness weight; the turns that no longer fit are left out), or None when a short pose has no
    rest but the end one to lengthen, or is still short after a few rounds."""
    moves = list(moves)
    for _ in range(LENGTHEN_ROUNDS + 1):
        problem = plan_scenario(base, layout(moves, duration_s, max_rate_deg_s, first), duration_s)
        held = held_pose_seconds(problem)
        short = missing_holds(held)
        if not short:
            return moves, first
        u, seconds, owner = rest_gravity(problem)
        faces = [_face_in_cone(v) for v in u]
        for f in short:
            rests = [n for n in range(len(u)) if faces[n] == f and owner[n] is not None]
            if not rests:
                return None
            n = max(rests, key=lambda r: seconds[r])
            longer = round(min(seconds[n] * HOLD_S / max(held[f], 0.1 * HOLD_S) + 0.1, MAX_HOLD_S), 1)
            if owner[n] == 0:
                first = max(first, longer)
            else:
                axis, angle, pause = moves[owner[n]]
                moves[owner[n]] = (axis, angle, max(pause, longer))
    return None


def _face_in_cone(u: np.ndarray) -> str | None:
    """The pose whose cone (observe's, `face_seconds`) holds the direction u, if any."""
    inside = [f for f, s in face_seconds(u[None, :], np.ones(1)).items() if s > 0]
    return inside[0] if inside else None


def holds_where_turns_pass(moves, base: Scenario, duration_s: float, max_rate_deg_s: float):
    """Way 1 (module doc): (moves, first rest s) with a HOLD_S pause where gravity passes nearest each missing pose,
    or None when a pose is never passed within AIM_DEG."""
    from magyro.studies.motion import truth_body_attitude

    moves, first = list(moves), REST_S
    for _ in range(2 * len(FACES)):
        turns = layout(moves, duration_s, max_rate_deg_s, first)
        problem = plan_scenario(base, turns, duration_s)
        need = missing_holds(rest_pose_seconds(problem))
        if not need:
            return moves, first
        starts = np.cumsum([0.0] + [st.seconds for st in turns])[:-1]
        before = [t for st, t in zip(turns, starts) if not st.is_rest]     # where each fitted move starts
        u = np.einsum("nji,j->ni", truth_body_attitude(problem, np.array(before)), UP_W)
        aim = u @ face_axis(need[0])
        k = int(np.argmax(aim))
        if aim[k] < math.cos(math.radians(AIM_DEG)):
            return None
        if k == 0:
            first = HOLD_S
        else:
            axis, angle, pause = moves[k]
            moves[k] = (axis, angle, max(pause, HOLD_S))
    return None


def pose_tour(u0: np.ndarray, need: list[str], max_rate_deg_s: float) -> list[tuple[str, float, float, bool]]:
    """Way 2 (module doc): the fewest seconds of turns about the device's x, y, z axes (TOUR_ANGLES_DEG) from
    gravity's direction u0 (in the body) that visit every pose of `need`, a HOLD_S hold at each; as (axis, signed
    angle deg, pause s before it, hold after it). A shortest path over (pose, poses still to visit), deterministic
    (ties to the first found)."""
    start = _nearest_face(u0)
    todo0 = frozenset(need) - {start}
    queue, count, done = [(0.0, 0, start, todo0, ())], 1, set()
    while queue:
        cost, _, face, todo, path = heapq.heappop(queue)
        if not todo:
            return list(path)
        if (face, todo) in done:
            continue
        done.add((face, todo))
        for axis in ("x", "y", "z"):
            if axis == face[1]:
                continue                        # about the vertical: gravity stays where it is
            for angle in TOUR_ANGLES_DEG:
                R = so3.exp_so3(math.radians(angle) * np.array(AXES[axis]))
                nxt = _nearest_face(R.T @ face_axis(face))     # C' = C R: gravity in the body turns by R^T
                hold = nxt in todo
                pause = HOLD_S if path and path[-1][3] else 0.0
                heapq.heappush(queue, (cost + pause + turn_seconds(angle, max_rate_deg_s), count, nxt,
                                       todo - {nxt}, path + ((axis, angle, pause, hold),)))
                count += 1
    return []


def tour_first(moves, base: Scenario, duration_s: float, max_rate_deg_s: float, every: bool = False):
    """Way 2 (module doc): (moves, first rest s): the tour from the start pose over the missing poses (`every`: all
    six), then `moves`. The tour moves the searched turns (and their rests) on, so a pose their rests held may no
    longer be: such poses join the tour, until it holds every pose or visits all six."""
    u0 = base.C0.T @ UP_W
    need = set(FACES) if every else set(missing_holds(rest_pose_seconds(
        plan_scenario(base, layout(moves, duration_s, max_rate_deg_s), duration_s))))
    while True:
        tour = pose_tour(u0, [f for f in FACES if f in need], max_rate_deg_s)
        first = HOLD_S if _nearest_face(u0) in need else REST_S
        out = [(axis, angle, pause) for axis, angle, pause, _ in tour] + list(moves)
        if tour:
            axis, angle, _ = out[len(tour)]
            out[len(tour)] = (axis, angle, HOLD_S if tour[-1][3] else 0.0)
        still = set(missing_holds(rest_pose_seconds(plan_scenario(
            base, layout(out, duration_s, max_rate_deg_s, first), duration_s))))
        if not still or still <= need:
            return out, first
        need |= still


def _nearest_face(u: np.ndarray) -> str:
    i = int(np.argmax(np.abs(u)))
    return ("+" if u[i] > 0 else "-") + "xyz"[i]


def hold_poses(best, best_score, score_of, refined, base: Scenario, duration_s: float, max_rate_deg_s: float,
               refine_evaluations: int = ACC_REFINE_EVALUATIONS, others=()):
    """The searched moves with every pose held (module doc): (moves, first rest s, score, how). The ways are tried
    on the searched moves and on `others` (the search's other finalists, named): a plan that holds the poses may
    start from another one. `score_of(moves, first rest s)` is the search's score, `refined` its refinement
    (plan._refined, given by the caller: plan imports this module).

    Two levels of holding: as observe counts it on the simulated session (`covered`), or, where no way reaches that
    (the hand's sway lowers observe's stillness weight, and a short plan has no room to hold a pose longer), HOLD_S of rest in each pose on the truth
    (`rest_pose_seconds`): the first is kept when any way reaches it, else the second, which the table then shows
    short in observe's count."""
    searched = layout(best, duration_s, max_rate_deg_s)
    if covered(base, searched, duration_s):
        return best, REST_S, best_score, "the searched plan's rests hold every pose"
    candidates = []
    ways = (("holds where the turns pass", holds_where_turns_pass), ("a tour of the missing poses first", tour_first),
            ("a tour of all six poses first", lambda *a: tour_first(*a, every=True)))
    for (name, way), (source, start) in itertools.product(ways, [("the searched plan", best), *others]):
        made = way(start, base, duration_s, max_rate_deg_s)
        if made is None:
            continue
        name_from = name if source == "the searched plan" else f"{name}, from {source}"
        longer = lengthened(*made, base, duration_s, max_rate_deg_s)
        moves, first = made if longer is None else longer
        if longer is not None or not missing_holds(rest_pose_seconds(plan_scenario(
                base, layout(moves, duration_s, max_rate_deg_s, first), duration_s))):
            candidates.append((longer is None, score_of(moves, first), len(candidates), name_from, moves, first))
    if not candidates:
        return best, REST_S, best_score, (f"no way found to hold every pose {HOLD_S:g} s (the start pose's gravity "
                                          f"is off the device's axes, or the plan too short); the plan is the "
                                          f"searched one")
    short, score, _, name, moves, first = min(candidates)
    held = rest_pose_seconds if short else held_pose_seconds

    def constrained(m):
        turns = layout(m, duration_s, max_rate_deg_s, first)
        if missing_holds(held(plan_scenario(base, turns, duration_s))):
            return math.inf, math.inf
        return score_of(m, first)

    moves, score, changes = refined(moves, score, constrained, refine_evaluations, duration_s, max_rate_deg_s, first)
    alike = [sc[0] for sh, sc, *_ in candidates if sh == short]
    tried = f"{len(alike)} of {len(candidates)}, the largest gyro ratio {min(alike):.2f}-{max(alike):.2f}"
    level = (f"each pose held at least {HOLD_S:g} s of rest, but observe's stillness weight counts some short "
             f"(no way reached {HOLD_S:g} s in its count)" if short else
             f"each pose held at least {HOLD_S:g} s as observe counts it")
    return moves, first, score, (f"{name} (of the ways and starts tried, those that held them so: {tried}), then "
                                 f"{refine_evaluations} "
                                 f"single-turn changes holding every pose, {changes} kept; {level}")


# --------------------------------------------------------------------------- what observe sees, and the bound


def observed_pose_seconds(problem: Scenario) -> tuple[dict, dict]:
    """(held still, in the cone) per pose on the problem's noise-seed-0 session, by observe's functions on the
    simulated session (its rests, `excitation.gate_inputs`, give g; `gravity.accelerometer_information`'s weights,
    trapezoid x stillness; `face_seconds`): the first counts only the samples where the device does not turn (the
    truth's rate), the second is observe's own count. The stillness weight reads |y| against the size expected in
    its direction (`gravity.expected_size`), so the hand's sway, not the uncalibrated scale and bias, lowers it."""
    from magyro.observability.excitation import gate_inputs
    from magyro.observability.gravity import accelerometer_information, reference_g
    from magyro.options import Options
    from magyro.studies.motion import truth_body_rate
    from magyro.studies.simulate import simulate

    session, _ = simulate(problem, 0)
    _, _, found = gate_inputs(session, Options())
    t, acc = session.t_acc_s, session.acc_m_s2
    g = reference_g(t, acc, found.segments_s, session.t_gyro_s, session.gyro_rad_s)
    _, _, W, u = accelerometer_information(t, acc, g)
    still = np.linalg.norm(truth_body_rate(problem, t), axis=1) == 0.0
    return face_seconds(u, W * still), face_seconds(u, W)


def accelerometer_bound(problem: Scenario):
    """`crlb_accelerometer.accelerometer_cramer_rao` on the noise-seed-0 session, with the options and method
    `magyro montecarlo` uses (its CRLB column)."""
    from magyro.studies.crlb_accelerometer import accelerometer_cramer_rao
    from magyro.studies.montecarlo import METHODS, study_options
    from magyro.studies.simulate import simulate

    session, _ = simulate(problem, 0)
    return accelerometer_cramer_rao(problem, session, study_options(problem, None), METHODS["nls"])


def accelerometer_std(problem: Scenario) -> dict:
    """The bound with the hand of the 12 parameters, ACC_ROWS -> std."""
    return acc_rows(accelerometer_bound(problem).accelerometer_std)


def acc_rows(values) -> dict:
    """The accelerometer's 12 values by name (crlb_accelerometer.ACC_ROWS)."""
    from magyro.studies.crlb_accelerometer import ACC_ROWS

    return dict(zip(ACC_ROWS, map(float, values)))
