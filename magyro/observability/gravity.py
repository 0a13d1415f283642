"""Gravity as a second reference vector: what `magyro observe` says when the session has an accelerometer.

Two questions, both answered from the readings alone (no solve):

1. **What the accelerometer's 12 parameters need.** The specific force in the body is f = A y + b (A: scale
   factors, non-orthogonality and the accelerometer's axes; b the bias). Read against a known f, each sample gives
   the rows H = [y^T (x) I, I], so the information over the session is (sum of [y;1][y;1]^T) (x) I: a 4 x 4 matrix
   repeated on each of the three axes. It is singular exactly when the readings stay on a plane: a column of A
   cannot be told from the bias along an axis whose reading never changes. Still, y is g times the direction of
   the specific force (up, in the body), u, so what matters is how gravity's direction varies in the body: the
   covariance of u, whose smallest eigenvalue times 3 is the **spread** (1 for six poses held equally long, or
   for the whole sphere; 0 when gravity stays on one line). The advice names the poses (axis up or down) that
   were held for too short a time.

2. **What gravity adds to the gyro's calibration.** The paper's M (eq. 10) is built from the field's direction:
   d m/dt = m x (K y_g + eps). At each instant it sees the rotation across the field, never about it. Gravity's
   direction obeys the same equation, so the same M built from it, integrated and added to the field's, gives the
   information of both reference vectors; its rank and condition (by the gate's rule, the noise floor of both)
   say what the gyro's calibration could reach with gravity, and the field-only weakest directions' signal to
   noise with and without it say which of them gravity rescues. The verdict stays the paper's theorem (field only).

Samples where the reading's size departs from the size expected in their direction (the hand's acceleration) count
less: w = exp(-((|y| - s(u)) / (STILL_SCALE g))^2 / 2), g the readings' size at the rests and s(u) what an
uncalibrated accelerometer reads still in the direction u (`stillness.expected_size`: its scale and bias errors put
|y| a few % off g in some poses, and against g alone a pose held still counted a fraction of its seconds). The
accelerometer's frame is taken for the magnetometer's (both are the device's axes to within the few degrees the
solve estimates as C_b_a, C_b_m): the rank and the directions do not hinge on a few degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from magyro.observability.advice import describe_direction
from magyro.observability.gate import AXES, FLOOR_FACTOR, NUMERICAL_RTOL, directional_rank, noise_matrix
from magyro.observability.matrix import information_integral, interpolate_rows, trapezoid_weights
from magyro.observability.report import SPHERE_BANDS, SPHERE_GRID, SPHERE_SECTORS, json_list, json_number, sphere_cell
from magyro.observability.stillness import STILL_SCALE, ExpectedSize, expected_size, still_weights, stillness
from magyro.session import hole_spans_s, overlaps_a_hole
from magyro.text import significant

FACE_CONE_DEG = 45.0      # a pose "x axis up": the specific force within 45 deg of +x
FACE_ENOUGH_S = 2.0       # a pose counts as held when gravity sat there this long (seconds, weighted by stillness)
SPREAD_ENOUGH = 0.1       # the spread below which the advice asks for more poses
MIN_SAMPLES = 20
ACC_PARAMETERS = ("A[:,x]", "A[:,y]", "A[:,z]", "b")   # the 4 x 4's coordinates: the columns of A, and b (in g)
FACES = ("+x", "-x", "+y", "-y", "+z", "-z")


@dataclass
class WeakDirection:
    """One of the field-only weakest directions of [vec K; eps], and what gravity does to it."""

    in_words: str
    vector: np.ndarray
    information_gain: float            # v^T (G_field + G_gravity) v / v^T G_field v
    snr_field: float                   # v^T G v / v^T N v of the field alone (the gate's signal to noise)
    snr_gravity: float                 # ... of gravity alone

    @property
    def rescued(self) -> bool:
        """Unexcited by the field, excited by gravity."""
        return self.snr_field <= FLOOR_FACTOR < self.snr_gravity

    def to_dict(self) -> dict:
        return {"in_words": self.in_words, "vector": json_list(self.vector), "information_gain": json_number(self.information_gain),
                "signal_to_noise_field": json_number(self.snr_field), "signal_to_noise_gravity": json_number(self.snr_gravity),
                "rescued": self.rescued}


@dataclass
class GyroWithGravity:
    """The integral of M^T M with gravity's direction added to the field's (part 2)."""

    rank: int
    condition: float
    eigenvalues: np.ndarray            # normalised, ascending
    rank_field_only: int
    condition_field_only: float
    rank_gravity_only: int
    weakest: list                      # [WeakDirection] the field-only analysis's weakest (all unexcited), weakest first
    rotation_about_field: float        # share of the squared (bias-free) rate about the field's direction
    rotation_about_gravity: float      # ... about gravity's (weighted by stillness)
    field_gravity_angle_deg: float     # median angle between the field's and gravity's lines (0-90)

    def to_dict(self) -> dict:
        return {"rank": int(self.rank), "condition": json_number(self.condition), "eigenvalues": json_list(self.eigenvalues),
                "rank_field_only": int(self.rank_field_only), "condition_field_only": json_number(self.condition_field_only),
                "rank_gravity_only": int(self.rank_gravity_only),
                "field_only_weakest": [w.to_dict() for w in self.weakest],
                "rotation_about_field_share": json_number(self.rotation_about_field),
                "rotation_about_gravity_share": json_number(self.rotation_about_gravity),
                "field_gravity_angle_deg": json_number(self.field_gravity_angle_deg)}


@dataclass
class AccelerometerObservability:
    """Part 1 (the accelerometer's own 12 parameters) and part 2 (`gyro`, what gravity adds to the gyro's)."""

    g_reference_m_s2: float            # the readings' size at the rests (or at the stillest samples)
    still_s: float                     # the session's seconds weighted by stillness
    white_noise_m_s2: float
    hand_m_s2: float                   # RMS of |y| - g over the weighted samples, white noise taken out
    rank: int                          # of 12: three times the rank of the 4 x 4
    condition: float                   # of the 4 x 4 (in g)
    eigenvalues: np.ndarray            # of the 4 x 4, normalised, ascending
    directions: list                   # [(eigenvalue normalised, snr, excited, vector (4,), in words)] weakest first
    spread: float                      # 3 x the smallest eigenvalue of the covariance of gravity's direction
    spread_eigenvalues: np.ndarray     # 3 x its eigenvalues, ascending
    spread_weakest: np.ndarray         # the body direction along which gravity varied least (unit, sign: largest > 0)
    face_s: dict                       # "+x" ... "-z": seconds (weighted) the specific force sat within FACE_CONE_DEG
    cells_visited: int
    cells: int
    advice: list = field(default_factory=list)
    gyro: GyroWithGravity | None = None
    # for the figure only (not in the JSON): gravity's still directions (|y| within ~6 % of g), in the body
    gravity_directions: np.ndarray = field(repr=False, default=None)
    expected_size: ExpectedSize | None = field(repr=False, default=None)   # the size read still, by direction

    @property
    def sphere_fraction(self) -> float:
        return self.cells_visited / self.cells

    def expected_size_dict(self) -> dict:
        """The size read still by direction (`expected_size`), m/s^2, when known."""
        if self.expected_size is None:
            return {}
        return {"expected_size_m_s2": {"c": json_list(self.expected_size.c), "d": json_list(self.expected_size.d)}}

    def to_dict(self) -> dict:
        return {
            "frames": "the accelerometer's axes taken for the magnetometer's (within the few degrees of C_b_a, C_b_m)",
            "g_reference_m_s2": json_number(self.g_reference_m_s2),
            "weighting": {"still_scale": STILL_SCALE, "still_seconds": json_number(self.still_s),
                          "rule": "w = exp(-((|y| - s(u)) / (still_scale g))^2 / 2), s(u) = c . u + d . (u * u)",
                          **self.expected_size_dict()},
            "noise": {"white_m_s2": json_number(self.white_noise_m_s2), "hand_m_s2": json_number(self.hand_m_s2)},
            "parameters": {"model": "f = A y + b (12 parameters); information (sum of [u;1][u;1]^T) (x) I, u = y / g",
                           "rank": int(self.rank), "condition": json_number(self.condition),
                           "eigenvalues": json_list(self.eigenvalues), "coordinates": list(ACC_PARAMETERS),
                           "directions": [{"eigenvalue": json_number(e), "signal_to_noise": json_number(s), "excited": bool(x),
                                           "vector": json_list(v), "in_words": w} for e, s, x, v, w in self.directions]},
            "gravity_spread": {"smallest": json_number(self.spread), "eigenvalues": json_list(self.spread_eigenvalues),
                               "weakest_body_direction": json_list(self.spread_weakest), "enough": SPREAD_ENOUGH},
            "poses": {f: {"seconds": json_number(self.face_s[f]), "held": bool(self.face_s[f] >= FACE_ENOUGH_S)}
                      for f in FACES},
            "poses_meaning": "+x: the x axis up (the reading +g on x, gravity along -x in the body); -x: x down",
            "pose_cone_deg": FACE_CONE_DEG, "pose_enough_s": FACE_ENOUGH_S,
            "sphere": {"fraction_visited": json_number(self.sphere_fraction), "cells_visited": int(self.cells_visited),
                       "cells": int(self.cells), "grid": SPHERE_GRID.replace("magnetometer frame", "accelerometer frame")},
            "advice": list(self.advice),
            "gyro_with_gravity": None if self.gyro is None else self.gyro.to_dict(),
        }

    def table_lines(self) -> list[str]:
        out = ["accelerometer (gravity, a second reference vector; the verdict above is the field's alone):",
               f"  gravity's directions in the body: {100 * self.sphere_fraction:.0f}% of the sphere "
               f"({self.cells_visited} of {self.cells} cells); poses held (s, weighted by stillness):",
               "    " + ", ".join(f"{f[1]} {'up' if f[0] == '+' else 'down'} {self.face_s[f]:.1f}" for f in FACES),
               f"  its 12 parameters (f = A y + b): rank {self.rank} of 12, condition {_fmt(self.condition)}; "
               f"spread {self.spread:.2f} (1 = six poses; weakest along {body_direction(self.spread_weakest)})",
               f"    weakest: {self.directions[0][4]} (eigenvalue {self.directions[0][0]:.2g} of the largest)"]
        g = self.gyro
        if g is not None:
            out.append(f"  gyro with gravity (M of the field + M of gravity): rank {g.rank} of 12, condition "
                       f"{_fmt(g.condition)} (field only: rank {g.rank_field_only}, condition "
                       f"{_fmt(g.condition_field_only)}; gravity only: rank {g.rank_gravity_only})")
            out.append(f"    turning about the field (unseen by it): {100 * g.rotation_about_field:.0f}% of the squared "
                       f"rate, about gravity {100 * g.rotation_about_gravity:.0f}%; field and gravity "
                       f"{g.field_gravity_angle_deg:.0f} deg apart")
            if g.weakest:
                out.append("    the field's weakest directions: information with gravity / without; signal to noise "
                           "(x the noise floor) of the field, of gravity")
                out += [f"      {w.in_words}: x{_fmt(w.information_gain)}; {_fmt(w.snr_field)}, {_fmt(w.snr_gravity)}"
                        + ("  RESCUED by gravity" if w.rescued else "") for w in g.weakest]
        if self.advice:
            out.append("  to calibrate the accelerometer well (magyro solve calibrates it by default; these poses make it worth having):")
            out += [f"    - {a}" for a in self.advice]
        return out


# --------------------------------------------------------------------------- part 1: the accelerometer's parameters


def reference_g(t_s, acc, rests_s, t_gyro_s=None, gyro=None) -> float:
    """The readings' size when still: the median |y| at the rests, else at the quarter of samples the gyro says turn
    slowest, else the median |y|."""
    norm = np.linalg.norm(acc, axis=1)
    at_rest = np.zeros(len(t_s), dtype=bool)
    for a, b in rests_s:
        at_rest |= (t_s >= a) & (t_s <= b)
    if at_rest.sum() >= MIN_SAMPLES:
        return float(np.median(norm[at_rest]))
    if gyro is not None and len(gyro) >= MIN_SAMPLES:
        rate = np.interp(t_s, t_gyro_s, np.linalg.norm(gyro, axis=1))
        return float(np.median(norm[rate <= np.percentile(rate, 25)]))
    return float(np.median(norm))


def accelerometer_information(t_s, acc, g: float, sigma_u: float | None = None, size: ExpectedSize | None = None):
    """(J, N, W, u): J = sum over samples of W [u;1][u;1]^T (4 x 4, u = y / g), N what noise of std sigma_u on u puts
    in it (as the gate's floor), W the samples' weights (trapezoid x `still_weights`), u the unit directions."""
    norm = np.linalg.norm(acc, axis=1)
    W = trapezoid_weights(t_s) * still_weights(acc, g, size)
    u = acc / np.where(norm > 0, norm, 1.0)[:, None]
    u1 = np.column_stack([u, np.ones(len(u))])
    J = (u1 * W[:, None]).T @ u1
    N = None if sigma_u is None else sigma_u ** 2 * float(np.sum(W)) * np.diag([1.0, 1.0, 1.0, 0.0])
    return J, N, W, u


def face_seconds(u: np.ndarray, W: np.ndarray) -> dict:
    c = math.cos(math.radians(FACE_CONE_DEG))
    return {f"{s}{AXES[i]}": float(np.sum(W[sign * u[:, i] > c])) for i in range(3) for s, sign in (("+", 1), ("-", -1))}


def body_direction(v: np.ndarray) -> str:
    """A body direction for people: 'z' when within ~25 deg of an axis, else its components."""
    v = np.asarray(v, dtype=float)
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) >= 0.9:
        return AXES[i]
    return "(" + ", ".join(f"{x:.2f}" for x in v) + ")"


def pose_words(face: str) -> str:
    axis, up = face[1], face[0] == "+"
    return (f"its {axis} axis {'up' if up else 'down'} (gravity along {'-' if up else '+'}{axis}, "
            f"a{axis} = {'+' if up else '-'}g)")


def accelerometer_advice(face_s: dict, spread: float, weakest: np.ndarray) -> list[str]:
    missing = missing_poses(face_s)
    advice = []
    if missing:
        advice.append("Hold the device still for a few seconds with " + "; with ".join(pose_words(f) for f in missing)
                      + f": gravity sat there less than {FACE_ENOUGH_S:g} s (a six-pose calibration holds all six).")
    if spread < SPREAD_ENOUGH:
        axis = body_direction(weakest)
        named = f"its {axis} axis" if len(axis) == 1 else f"the body direction {axis}"
        advice.append(f"Gravity's direction hardly varied along {axis} (spread {spread:.2g}, enough from "
                      f"{SPREAD_ENOUGH:g}): the accelerometer's response along it cannot be told from its bias; "
                      f"turn the device so that {named} points up and down.")
    return advice


def describe_acc_direction(v: np.ndarray) -> str:
    """A 4-vector over (A[:,x], A[:,y], A[:,z], b) in words, e.g. '0.71 A[:,z] - 0.71 b'."""
    v = np.asarray(v, dtype=float)
    order = np.argsort(-np.abs(v))
    v = v * np.sign(v[order[0]])
    keep = [i for i in order if v[i] ** 2 >= 0.05] or [order[0]]
    text = ""
    for n, i in enumerate(keep):
        sign = "-" if v[i] < 0 else ("+" if n else "")
        text += (f" {sign} " if n else sign) + f"{abs(v[i]):.2f} {ACC_PARAMETERS[i]}"
    return text


def white_noise_m_s2(acc) -> float:
    """The white noise per sample from robust third differences (no rests needed), m/s^2."""
    from magyro.front.differences import white_noise_std
    return float(np.sqrt(np.mean(white_noise_std(acc) ** 2)))


def accelerometer_noise(t_s, acc, rests_s, g: float, white: float | None = None,
                        size: ExpectedSize | None = None) -> tuple[float, float]:
    """(white noise per sample, the hand's RMS along gravity: the size's departure from the one expected in its
    direction, `expected_size`), m/s^2. `white` given: taken as it is."""
    still = []
    for a, b in rests_s:
        x = acc[(t_s >= a) & (t_s <= b)]
        if len(x) >= 10:
            still.append(x - x.mean(axis=0))
    if white is None:
        white = float(np.sqrt(np.mean(np.concatenate(still) ** 2))) if still else white_noise_m_s2(acc)
    norm = np.linalg.norm(acc, axis=1)
    expected = (size or expected_size(acc, g)).at(acc / np.where(norm > 0, norm, 1.0)[:, None])
    w = stillness(norm, expected, g)
    ms = float(np.sum(w * (norm - expected) ** 2) / max(np.sum(w), 1e-300))
    return white, math.sqrt(max(ms - white ** 2, 0.0))


# --------------------------------------------------------------------------- part 2: gravity beside the field


def weighted_noise_matrix(t_gyro_s, gyro_rad_s, u, W, gyro_sample_std: float, sigma_u: float) -> np.ndarray:
    """The gate's noise matrix N for a reference direction u (on the gyro's times) with per-sample weights W
    (trapezoid x stillness): gyro noise through y_g, the direction's noise (std sigma_u per axis) through u x."""
    y1 = np.column_stack([gyro_rad_s, np.ones(len(W))])
    P = np.sum(W) * np.eye(3) - (u * W[:, None]).T @ u
    gyro_part = np.kron(np.diag([1.0, 1.0, 1.0, 0.0]), gyro_sample_std ** 2 * P)
    ref_part = np.kron(2.0 * sigma_u ** 2 * (y1 * W[:, None]).T @ y1, np.eye(3))
    return gyro_part + ref_part


def gyro_with_gravity(session, field_m, analysis, rates_rad_s, gyro_sample_std: float, mag_std_unit_field: float,
                      g: float, sigma_u: float, most: int = 3, size: ExpectedSize | None = None) -> GyroWithGravity | None:
    """Part 2 on the span the gate analyses (`session`, rests trimmed): the field's integral of M^T M plus gravity's."""
    t, y = session.t_gyro_s, session.gyro_rad_s
    ta, acc = _finite(session.t_acc_s, session.acc_m_s2)
    if ta is None:
        return None
    inside = (t >= ta[0]) & (t <= ta[-1])
    if inside.sum() < MIN_SAMPLES:
        return None
    t_in, y_in = t[inside], y[inside]
    norm_a = np.linalg.norm(acc, axis=1)
    u = interpolate_rows(t_in, ta, acc / np.where(norm_a > 0, norm_a, 1.0)[:, None])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    still = stillness(np.interp(t_in, ta, norm_a), (size or expected_size(acc, g)).at(u), g)
    still[overlaps_a_hole(t_in, t_in, hole_spans_s(ta))] = 0.0     # nothing is known of gravity in a hole
    G_g = information_integral(t_in, y_in, t_in, u * np.sqrt(still)[:, None])   # M^T M is quadratic in u
    W = trapezoid_weights(t_in) * still
    N_g = weighted_noise_matrix(t_in, y_in, u, W, gyro_sample_std, sigma_u)

    G_f = analysis.information
    N_f = noise_matrix(t, y, session.t_mag_s, field_m, gyro_sample_std, mag_std_unit_field)
    G = G_f + G_g
    lam, V = np.linalg.eigh(G)
    rank = combined_rank(lam, V, (G_f, N_f), (G_g, N_g))
    lam_g, V_g = np.linalg.eigh(G_g)
    rank_g, _ = directional_rank(lam_g, V_g, N_g)

    weakest = []
    for k in range(min(max(most, 12 - analysis.rank), 12)):   # the analysis keeps its directions weakest first
        v = analysis.eigenvectors[:, k]
        seen = float(v @ G_f @ v)
        gain = float(v @ G @ v) / seen if seen > NUMERICAL_RTOL * float(np.max(np.linalg.eigvalsh(G_f))) else math.inf
        weakest.append(WeakDirection(describe_direction(v), v, gain, _snr(v, G_f, N_f), _snr(v, G_g, N_g)))

    # which way the device turned, against each reference direction
    m_hat = interpolate_rows(t_in, session.t_mag_s, field_m)
    m_hat /= np.linalg.norm(m_hat, axis=1, keepdims=True)
    r = rates_rad_s[inside]
    dt = trapezoid_weights(t_in)
    r2 = np.sum(r * r, axis=1)
    about_field = float(np.sum(dt * np.sum(r * m_hat, axis=1) ** 2) / max(np.sum(dt * r2), 1e-300))
    about_gravity = float(np.sum(W * np.sum(r * u, axis=1) ** 2) / max(np.sum(W * r2), 1e-300))
    angle = np.degrees(np.arccos(np.clip(np.abs(np.sum(m_hat * u, axis=1)), 0.0, 1.0)))   # between the lines
    held = still >= 0.5
    angle_med = float(np.median(angle[held] if np.any(held) else angle))
    cond = float(lam[-1] / lam[0]) if lam[0] > 0 else math.inf
    return GyroWithGravity(rank, cond, lam / lam[-1], analysis.rank, analysis.condition, rank_g, weakest,
                           about_field, about_gravity, angle_med)


def _snr(v, G, N) -> float:
    return float(v @ G @ v) / max(float(v @ N @ v), 1e-300)


def combined_rank(lam, V, *references) -> int:
    """The rank of the summed integral: an eigen-direction counts when one reference vector alone sees it above
    FLOOR_FACTOR times its own noise floor (the gate's rule, per reference). Each reference is (G_r, N_r).

    Not the gate's rule on the sums: their signal to noise is a weighted mean of the two, so a reference seen
    through a noisier sensor (gravity through the hand) would pull down a direction the other sees well."""
    count = 0
    for k in range(len(lam)):
        v = V[:, k]
        if lam[k] > NUMERICAL_RTOL * lam[-1] and max(_snr(v, G, N) for G, N in references) > FLOOR_FACTOR:
            count += 1
    return count


# --------------------------------------------------------------------------- both


def accelerometer_parameters(t_acc_s, acc_m_s2, rests_s, t_gyro_s=None, gyro_rad_s=None,
                             white_m_s2: float | None = None) -> AccelerometerObservability | None:
    """Part 1 alone (`gyro` None), or None without a usable accelerometer; g and the white noise are read at the
    gyro's `rests_s` (none: `reference_g`'s and `accelerometer_noise`'s fallbacks; `white_m_s2`: given). Called by
    `observe_accelerometer`, and by `magyro watch` on the data received so far."""

    ta, acc = _finite(t_acc_s, acc_m_s2)
    if ta is None:
        return None
    g = reference_g(ta, acc, rests_s, t_gyro_s, gyro_rad_s)
    if not g > 0:
        return None
    size = expected_size(acc, g)
    white, hand = accelerometer_noise(ta, acc, rests_s, g, white_m_s2, size)
    sigma_u = math.hypot(white, hand) / g
    J, N, W, u = accelerometer_information(ta, acc, g, sigma_u, size)
    lam, V = np.linalg.eigh(J)
    rank4, snr = directional_rank(lam, V, N + NUMERICAL_RTOL * lam[-1] * np.eye(4))
    order = np.argsort(snr, kind="stable")
    directions = [(float(lam[k] / lam[-1]), float(snr[k]), bool(i >= 4 - rank4), V[:, k],
                   describe_acc_direction(V[:, k])) for i, k in enumerate(order)]
    mean = (u * W[:, None]).sum(axis=0) / np.sum(W)
    cov = (u * W[:, None]).T @ u / np.sum(W) - np.outer(mean, mean)
    c_lam, c_vec = np.linalg.eigh(cov)
    weakest = c_vec[:, 0] * np.sign(c_vec[np.argmax(np.abs(c_vec[:, 0])), 0])
    faces = face_seconds(u, W)
    held = u[still_weights(acc, g, size) >= 0.5]
    cells = np.unique(sphere_cell(held))
    spread = float(3.0 * max(c_lam[0], 0.0))
    return AccelerometerObservability(
        g_reference_m_s2=g, still_s=float(np.sum(W)), white_noise_m_s2=white, hand_m_s2=hand,
        rank=3 * rank4, condition=float(lam[-1] / lam[0]) if lam[0] > 0 else math.inf, eigenvalues=lam / lam[-1],
        directions=directions, spread=spread, spread_eigenvalues=3.0 * c_lam, spread_weakest=weakest,
        face_s=faces, cells_visited=int(cells.size), cells=SPHERE_BANDS * SPHERE_SECTORS,
        advice=accelerometer_advice(faces, spread, weakest), gyro=None, gravity_directions=held, expected_size=size)


def observe_accelerometer(full_session, moving_session, field_m, analysis, rates_rad_s, rests_s,
                          gyro_sample_std: float, mag_std_unit_field: float) -> AccelerometerObservability | None:
    """Parts 1 and 2, or None when the session has no (usable) accelerometer.

    Part 1 uses every accelerometer sample of `full_session` (the rests are its best poses); part 2 the span the
    gate analyses (`moving_session`), beside the field's integral."""
    out = accelerometer_parameters(full_session.t_acc_s, full_session.acc_m_s2, rests_s, full_session.t_gyro_s,
                                   full_session.gyro_rad_s)
    if out is None:
        return None
    g, sigma_u = out.g_reference_m_s2, math.hypot(out.white_noise_m_s2, out.hand_m_s2) / out.g_reference_m_s2
    out.gyro = gyro_with_gravity(moving_session, field_m, analysis, rates_rad_s, gyro_sample_std, mag_std_unit_field,
                                 g, sigma_u, size=out.expected_size)
    return out


def missing_poses(face_s: dict) -> list[str]:
    """The poses (of FACES) gravity sat in for less than FACE_ENOUGH_S, in FACES' order."""
    return [f for f in FACES if face_s[f] < FACE_ENOUGH_S]


# --------------------------------------------------------------------------- helpers


def _finite(t_s, acc):
    if t_s is None or acc is None:
        return None, None
    keep = np.all(np.isfinite(acc), axis=1) & np.isfinite(t_s)
    if keep.sum() < MIN_SAMPLES:
        return None, None
    return np.asarray(t_s, dtype=float)[keep], np.asarray(acc, dtype=float)[keep]


def _fmt(x) -> str:
    x = float(x)
    return significant(x) if math.isfinite(x) else "inf"
