"""The weak directions of the integral of M^T M in words, and the motion that would excite them.

`magyro observe` reports these (`ObservabilityReport.weak_directions`, `.advice`);
`gate.analyse` has its own, shorter advice for the refusal message of `magyro solve`.
A direction is a unit 12-vector over [vec K; eps] (`matrix.PARAMETER_NAMES`).
"""
from __future__ import annotations

import numpy as np

from magyro.observability.gate import AXES, FLOOR_FACTOR, WELL_CONDITIONED, ObservabilityAnalysis
from magyro.observability.matrix import PARAMETER_NAMES
from magyro.text import significant


def describe_direction(v: np.ndarray, at_least: float = 0.05, most: int = 4) -> str:
    """A unit 12-vector over [vec K; eps] as its largest components, e.g. '0.71 K13 - 0.52 eps_z'."""
    v = np.asarray(v, dtype=float)
    order = np.argsort(-np.abs(v))
    v = v * np.sign(v[order[0]])
    keep = [i for i in order[:most] if v[i] ** 2 >= at_least] or [order[0]]
    text = ""
    for n, i in enumerate(keep):
        sign = "-" if v[i] < 0 else ("+" if n else "")
        text += (f" {sign} " if n else sign) + f"{abs(v[i]):.2f} {PARAMETER_NAMES[i]}"
    return text.strip()


def direction_advice(v: np.ndarray) -> str:
    """The motion that excites a direction of [vec K; eps]: turn about the gyro axes whose column of K it holds."""
    share = np.array([np.sum(v[3 * j: 3 * j + 3] ** 2) for j in range(3)] + [np.sum(v[9:] ** 2)])
    parts = []
    axes = [AXES[j] for j in range(3) if share[j] >= 0.2]
    if axes:
        one = len(axes) == 1
        parts.append("turn more about the gyro " + " and ".join(axes) + (" axis" if one else " axes")
                     + " (larger angles, varied rates), with the field not along " + ("it" if one else "them"))
    if share[3] >= 0.2:
        parts.append("vary the rotation rate (turn back and forth, start and stop) so the bias separates "
                     "from the scale factors")
    return "; ".join(parts) or "turn about all three axes with varied rates"


def weak_directions(analysis: ObservabilityAnalysis, most: int = 3, verdict: str = "") -> tuple[list[str], list[str]]:
    """(weak directions, advice) in plain words.

    Rank deficient: the share of each gyro axis's response and of the bias that is
    unobservable, the unobservable direction itself when there is just one, and the
    gate's motion advice. Full rank: the `most` weakest eigen-directions of the integral (by
    signal to noise, as the gate ranks them) in parameter names, with the motion that
    excites the weakest when it is poorly excited or the verdict is marginal.
    """
    a = analysis
    snr = direction_snr(a)
    order = np.argsort(snr, kind="stable")   # weakest first (the analysis already keeps them so)
    V, lam, snr = a.eigenvectors[:, order], a.eigenvalues[order], snr[order]
    top = float(np.max(a.eigenvalues))
    if not a.full_rank:
        weak = [f"unobservable: {w}" for w in a.weak_directions]
        if 12 - a.rank == 1:  # a single null direction is unique (up to sign): name it
            weak.append(f"unobservable direction: {describe_direction(V[:, 0])}")
        return weak, list(a.advice)
    weak, advice = [], []
    for k in range(min(most, 12)):
        weak.append(f"{describe_direction(V[:, k])} (eigenvalue {lam[k] / top:.2g} of the largest, "
                    f"{significant(snr[k])} x its noise floor)")
    if lam[0] / top < 1.0 / WELL_CONDITIONED or snr[0] < 10 * FLOOR_FACTOR:
        advice.append(f"The weakest direction is poorly excited: {direction_advice(V[:, 0])}.")
    elif verdict == "marginal":
        advice.append(f"To sharpen the weakest direction ({describe_direction(V[:, 0])}): {direction_advice(V[:, 0])}; "
                      "recording longer with the same motion also helps (the std falls as 1/sqrt(duration)).")
    return weak, advice


def direction_snr(a: ObservabilityAnalysis) -> np.ndarray:
    """Signal to noise per eigen-direction of the analysis (eigenvalue over its noise floor), analysis order.

    `gate.analyse` always sets it; an analysis built without it falls back on the scalar noise floor.
    """
    snr = getattr(a, "signal_to_noise", None)
    if snr is None:
        return np.asarray(a.eigenvalues, dtype=float) / max(a.noise_floor, 1e-300)
    return np.asarray(snr, dtype=float)
