"""The paper's observability theorem, evaluated on a session.

The 12 gyro parameters [vec K; eps] are observable when the integral of
M^T M over the session is nonsingular (paper eq. 10-11). With real, noisy
data the matrix is never exactly singular, so the rank is counted against a
**noise floor**. Writing M = (ytilde^T (x) S) with ytilde = [y_g; 1] and
S = (m^m x), M^T M = (ytilde ytilde^T) (x) (S^T S), and per-sample noise
adds, in expectation,

    N = integral of ( sigma_g^2 diag(1,1,1,0) (x) (I - m m^T)
                      + 2 sigma_m^2 ytilde ytilde^T (x) I ) dt

(gyro noise through y_g; magnetometer noise through m x, whose outer
product has expectation 2 sigma_m^2 I). An eigen-direction v of the
integral counts as excited only when its eigenvalue exceeds `FLOOR_FACTOR`
times v^T N v, what noise alone puts in that very direction (and a
numerical tolerance). Units: K is dimensionless, eps in rad/s.

This module is shared by `magyro solve` (the gate) and `magyro observe`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from magyro.observability.matrix import information_integral, trapezoid_weights
from magyro.session import hole_spans_s
from magyro.text import significant

FLOOR_FACTOR = 10.0
NUMERICAL_RTOL = 1e-12
WELL_CONDITIONED = 100.0   # "well conditioned": full rank and condition below this (`magyro observe`)
AXES = "xyz"


@dataclass(frozen=True)
class ObservabilityAnalysis:
    rank: int
    condition: float
    eigenvalues: np.ndarray            # raw units, ordered weakest (signal to noise) first
    eigenvectors: np.ndarray           # columns, matching eigenvalues
    tolerance: float                   # FLOOR_FACTOR times the largest noise eigenvalue (for reference)
    noise_floor: float                 # largest eigenvalue of the noise matrix N
    information: np.ndarray            # the 12x12 integral of M^T M
    weak_directions: list[str] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)
    signal_to_noise: np.ndarray | None = None   # per eigen-direction: lambda_v / v^T N v, weakest first

    @property
    def eigenvalues_normalised(self) -> np.ndarray:
        """Ascending, divided by the largest."""
        lam = np.sort(self.eigenvalues)
        return lam / lam[-1]

    @property
    def full_rank(self) -> bool:
        return self.rank == 12

    def summary(self) -> str:
        head = f"rank {self.rank} of 12 (condition {significant(self.condition)})"
        if self.full_rank:
            return head
        return head + ". Unobservable share: " + ", ".join(self.weak_directions) + ". " + " ".join(self.advice)


def noise_floor(t_gyro_s, gyro_rad_s, gyro_sample_std_rad_s: float, mag_std_unit_field: float) -> float:
    """The largest eigenvalue sensor noise alone could add to the integral of M^T M."""
    w = trapezoid_weights(t_gyro_s)
    rate2 = np.sum(gyro_rad_s**2, axis=1)
    return float(np.sum(w * (gyro_sample_std_rad_s**2 + 2.0 * mag_std_unit_field**2 * (1.0 + rate2))))


def noise_matrix(t_gyro_s, gyro_rad_s, t_mag_s, field_m, gyro_sample_std_rad_s: float, mag_std_unit_field: float) -> np.ndarray:
    """N: what per-sample sensor noise adds, in expectation, to the integral of M^T M (12 x 12)."""
    from magyro.observability.matrix import field_on_gyro_times

    inside, f = field_on_gyro_times(t_gyro_s, t_mag_s, field_m)
    w = trapezoid_weights(t_gyro_s[inside])
    y1 = np.column_stack([gyro_rad_s[inside], np.ones(inside.sum())])
    P = np.einsum("k,kij->ij", w, np.eye(3)[None] - np.einsum("ki,kj->kij", f, f))
    gyro_part = np.kron(np.diag([1.0, 1.0, 1.0, 0.0]), gyro_sample_std_rad_s**2 * P)
    mag_part = np.kron(2.0 * mag_std_unit_field**2 * (y1 * w[:, None]).T @ y1, np.eye(3))
    return gyro_part + mag_part


def cumulative_noise_matrix(t_gyro_s, gyro_rad_s, t_mag_s, field_m, gyro_sample_std_rad_s: float,
                            mag_std_unit_field: float, t_checkpoints_s) -> np.ndarray:
    """`noise_matrix` of the session up to each checkpoint time: (C, 12, 12), the twin of
    `matrix.cumulative_information` (same samples, same trapezoid, same checkpoint look-up).

    At a checkpoint on the last gyro sample it equals `noise_matrix` of the whole session.
    """
    from magyro.observability.matrix import field_on_gyro_times

    inside, f = field_on_gyro_times(t_gyro_s, t_mag_s, field_m)
    t = np.asarray(t_gyro_s, dtype=float)[inside]
    y1 = np.column_stack([np.asarray(gyro_rad_s)[inside], np.ones(len(t))])
    per_sample = np.concatenate([(np.eye(3)[None] - np.einsum("ki,kj->kij", f, f)).reshape(-1, 9),
                                 np.einsum("ki,kj->kij", y1, y1).reshape(-1, 16)], axis=1)
    dt = np.diff(t)[:, None]
    cum = np.concatenate([np.zeros((1, 25)), np.cumsum(0.5 * (per_sample[1:] + per_sample[:-1]) * dt, axis=0)])
    idx = np.clip(np.searchsorted(t, t_checkpoints_s, side="right") - 1, 0, len(t) - 1)
    P = cum[idx, :9].reshape(-1, 3, 3)
    Y = cum[idx, 9:].reshape(-1, 4, 4)
    D = np.diag([1.0, 1.0, 1.0, 0.0])
    gyro_part = np.einsum("ab,cij->caibj", D, gyro_sample_std_rad_s**2 * P).reshape(-1, 12, 12)
    mag_part = np.einsum("cab,ij->caibj", 2.0 * mag_std_unit_field**2 * Y, np.eye(3)).reshape(-1, 12, 12)
    return gyro_part + mag_part


def directional_rank(eigenvalues: np.ndarray, eigenvectors: np.ndarray, N: np.ndarray) -> tuple[int, np.ndarray]:
    """(rank, signal-to-noise per eigen-direction): lambda_v / (v^T N v)."""
    floor_v = np.einsum("iv,ij,jv->v", eigenvectors, N, eigenvectors)
    snr = eigenvalues / np.maximum(floor_v, 1e-300)
    excited = (snr > FLOOR_FACTOR) & (eigenvalues > NUMERICAL_RTOL * eigenvalues[-1])
    return int(np.sum(excited)), snr


def analyse(t_gyro_s, gyro_rad_s, t_mag_s, field_m, gyro_sample_std_rad_s: float, mag_std_unit_field: float) -> ObservabilityAnalysis:
    """Rank, condition and plain-language weak directions of the integral of M^T M."""
    info = information_integral(t_gyro_s, gyro_rad_s, t_mag_s, field_m)
    lam, V = np.linalg.eigh(info)
    N = noise_matrix(t_gyro_s, gyro_rad_s, t_mag_s, field_m, gyro_sample_std_rad_s, mag_std_unit_field)
    rank, snr = directional_rank(lam, V, N)
    floor = float(np.linalg.eigvalsh(N)[-1])
    tol = FLOOR_FACTOR * floor
    condition = float(lam[-1] / lam[0]) if lam[0] > 0 else float("inf")
    order = np.argsort(snr)
    lam, V, snr = lam[order], V[:, order], snr[order]  # weakest (by signal to noise) first
    weak = unobservable_groups(V[:, : 12 - rank])
    advice = motion_advice(t_gyro_s, gyro_rad_s, t_mag_s, field_m) if rank < 12 else []
    return ObservabilityAnalysis(rank, condition, lam, V, tol, floor, info, weak, advice, snr)


PARAMETER_GROUPS = {
    "gyro x-axis response (K11 K21 K31)": [0, 1, 2],
    "gyro y-axis response (K12 K22 K32)": [3, 4, 5],
    "gyro z-axis response (K13 K23 K33)": [6, 7, 8],
    "gyro bias (eps)": [9, 10, 11],
}


def unobservable_groups(weak_vectors: np.ndarray, at_least: float = 0.1) -> list[str]:
    """Parameter groups with the share of each that lies in the weak subspace, largest first.

    A parameter's share is the squared length of its unit vector projected onto the
    weak subspace (1 = entirely unobservable); a group's share is the mean over it.
    """
    share = np.sum(weak_vectors**2, axis=1)
    groups = [(float(np.mean(share[idx])), name) for name, idx in PARAMETER_GROUPS.items()]
    return [f"{name} {100 * w:.0f}%" for w, name in sorted(groups, reverse=True) if w >= at_least]


STILL_TURN_DEG = 10.0   # the rates, less their mean, add up to less than this: the device did not turn


def motion_advice(t_gyro_s, gyro_rad_s, t_mag_s, field_m) -> list[str]:
    """What motion would excite the missing directions, in plain words."""
    w = trapezoid_weights(t_gyro_s)
    centred = gyro_rad_s - np.average(gyro_rad_s, axis=0, weights=w)
    cov = (centred * w[:, None]).T @ centred / w.sum()
    lam, V = np.linalg.eigh(cov)
    total = lam.sum()
    if total <= 0 or np.sqrt(lam[-1]) < np.deg2rad(2.0):
        return ["The device was (nearly) still: turn it by hand about all three of its axes, through large angles."]
    turned_deg = np.rad2deg(np.max(np.linalg.norm(np.cumsum(centred * w[:, None], axis=0), axis=1)))
    if turned_deg < STILL_TURN_DEG:   # rates that vary (a vibrating bench) but add up to no turn
        return [f"The device did not turn: at most {turned_deg:.0f} deg from its first attitude, although its rates "
                f"vary by {np.rad2deg(np.sqrt(lam[-1])):.1f} deg/s (vibration); turn it by hand about all three of "
                "its axes, through large angles."]
    out = []
    missing = V[:, lam < 0.02 * lam[-1]]
    if missing.shape[1]:
        out.append(f"Rotate the device about its {axes_in_subspace(missing)} too.")
    mean_field = np.mean(field_m, axis=0)
    if np.linalg.norm(mean_field) > 0.95:
        out.append("The field direction barely changed: rotate so that the field is not along the rotation axis.")
    if not out:
        out.append("Vary the rotation rate and turn about all three device axes, with the field not along the rotation axis.")
    return out


def axes_in_subspace(basis: np.ndarray) -> str:
    """Name the device axes lying (mostly) in the span of `basis`, or give the directions."""
    inside = [AXES[i] for i in range(3) if np.sum(basis[i] ** 2) > 0.8]
    if len(inside) == basis.shape[1]:
        return " and ".join(f"{a} axis" for a in inside)
    return " and ".join("axis [" + ", ".join(f"{c:+.2f}" for c in basis[:, k]) + "]" for k in range(basis.shape[1]))


# --------------------------------------------------------------------------- the predicted accuracy

AXIS_NAMES = "xyz"


def accuracy_shortfalls(std, bounds) -> list[tuple[str, float, float, str]]:
    """(parameter, predicted one-sigma, bound, motion to add) for every gyro parameter the motion pins down
    less well than `bounds` (a `magyro.options.StdBounds`) asks; `std` is a `magyro.result.parts.Std`."""
    out = []
    for i in range(3):
        ppm = 1e6 * float(std.K_g[i, i])
        if not ppm <= bounds.scale_ppm:
            out.append((f"scale K_g[{i},{i}] (ppm)", ppm, bounds.scale_ppm,
                        f"turn the device more, and faster, about its {AXIS_NAMES[i]} axis"))
        for j in range(i + 1, 3):
            deg = float(np.rad2deg(std.K_g[i, j]))
            if not deg <= bounds.nonorthogonality_deg:
                out.append((f"non-orthogonality K_g[{i},{j}] (deg)", deg, bounds.nonorthogonality_deg,
                            f"turn the device more about its {AXIS_NAMES[j]} axis"))
    for k in range(3):
        bias = float(std.bias_deg_s[k])
        if not bias <= bounds.bias_deg_s:
            out.append((f"bias {AXIS_NAMES[k]} (deg/s)", bias, bounds.bias_deg_s,
                        "record longer, turning about every axis in both directions"))
        mis = float(std.misalignment_deg[k])
        if not mis <= bounds.misalignment_deg:
            out.append((f"misalignment about {AXIS_NAMES[k]} (deg)", mis, bounds.misalignment_deg,
                        "turn the device through large angles about all three of its axes"))
    return out


def accuracy_summary(shortfalls: list[tuple[str, float, float, str]], what: str = "predicted one-sigma",
                     motion_advice: bool = True) -> str:
    """The shortfalls in one sentence, worst first, with the motion to add (unless `motion_advice` is False: where
    the motion is not what is missing)."""
    worst = sorted(shortfalls, key=lambda s: -s[1] / s[2])
    parts = [f"{name} {significant(value)} (bound {significant(bound)})" for name, value, bound, _ in worst[:4]]
    advice = list(dict.fromkeys(a for *_, a in worst))
    more = f" and {len(worst) - 4} more" if len(worst) > 4 else ""
    return f"{what} {', '.join(parts)}{more}" + (f"; {'; '.join(advice[:2])}" if motion_advice else "")


REFUSAL_BOUND_NOTE = ("this is the refusal bound, Options.max_std or --max-std-*; the accuracy targets, --targets, "
                      "are a separate and stricter notion")


ROOM_NAMED_ABOVE = 0.002   # a field that wanders by more than 0.2 % along the path is named among a refusal's causes


def room_cause(wander_fraction: float | None) -> str:
    """'; the field wanders by x % ...' when the room's field wander (its std over the field, which the std counts)
    is worth naming as a cause of a large std, else ''."""
    if wander_fraction is None or not wander_fraction > ROOM_NAMED_ABOVE:
        return ""
    return (f"; the field wanders by {100 * wander_fraction:.1f} % along the path, which the std counts: record away "
            "from iron and magnets, or longer")


HOLES_NAMED_ABOVE = 0.2   # gyro holes over this share of the span are named among a refusal's causes


def holes_cause(t_gyro_s) -> str:
    """'; the gyro record has holes over x % of its span ...' when the holes (never integrated across) take a share
    of the recording worth naming as a cause of a large std (a logger's bursts left unrepaired, `--no-repair
    restamp`: the turning the gyro saw is cut into pieces the magnetometer cannot link), else ''."""
    t = np.asarray(t_gyro_s, dtype=float)
    if len(t) < 3 or not t[-1] > t[0]:
        return ""
    share = sum(b - a for a, b in hole_spans_s(t)) / (t[-1] - t[0])
    if not share > HOLES_NAMED_ABOVE:
        return ""
    return (f"; the gyro record has holes over {100 * share:.0f} % of its span, which are never integrated across: "
            "bursts of a logger left unrepaired (--no-repair restamp) or lost data; magyro check says which")


def too_weak_reason(shortfalls: list[tuple[str, float, float, str]], wander_fraction: float | None = None,
                    holes: str = "") -> str:
    """Why a motion is refused although it excites every gyro parameter: the words of `magyro observe`'s verdict and
    of the solve's refusal alike, with the numbers, the motion to add, the room's share and the holes' (`holes_cause`)."""
    return ("all 12 gyro parameters are excited, but too weakly for a calibration worth having: "
            + accuracy_summary(shortfalls) + room_cause(wander_fraction) + holes)


def accuracy_gate(std, options, wander_fraction: float | None = None, holes: str = "") -> list[str]:
    """Refuse (ObservabilityError, exit 3) a motion that excites every parameter too weakly for `options.max_std`;
    with `options.force`, the shortfall comes back as a warning instead."""
    shortfalls = accuracy_shortfalls(std, options.max_std)
    if not shortfalls:
        return []
    if not options.force:
        from magyro.errors import ObservabilityError

        raise ObservabilityError(f"insufficient excitation: {too_weak_reason(shortfalls, wander_fraction, holes)} (magyro "
                                 f"observe says the same; --force solves anyway; {REFUSAL_BOUND_NOTE})")
    return [f"solved with --force although the motion is too weak: {accuracy_summary(shortfalls)}"
            f"{room_cause(wander_fraction)}"]


def unexcited_directions(analysis: ObservabilityAnalysis) -> np.ndarray | None:
    """The 12 x (12 - rank) directions of [vec K; eps] below the noise floor, or None at full rank."""
    if analysis.full_rank:
        return None
    return analysis.eigenvectors[:, : 12 - analysis.rank]
