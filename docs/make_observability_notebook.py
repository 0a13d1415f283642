"""Write docs/observability-notebook.ipynb: the observability theorem hands-on, with magyro's own functions.

    python docs/make_observability_notebook.py           write the notebook (without outputs)
    python docs/make_observability_notebook.py --check   exit 1 when the committed notebook differs

The notebook's source lives here, as readable Python strings: `CELLS` is the list of
(kind, source) pairs, kind "md" or "code". The notebook is stored without outputs and
with fixed cell ids, so regenerating it changes nothing unless a cell changed.
tests/test_notebook.py executes it (nbclient) and checks that the committed file is
what `build_notebook()` makes. docs/observability.md is the derivation it follows.
"""
from __future__ import annotations

import sys
from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parent / "observability-notebook.ipynb"

CELLS: list[tuple[str, str]] = []


def md(source: str) -> None:
    CELLS.append(("md", source.strip("\n")))


def code(source: str) -> None:
    CELLS.append(("code", source.strip("\n")))


# --------------------------------------------------------------------------- introduction

md(r"""
# The observability theorem, hands-on

Wu & Pei calibrate a gyroscope with the magnetometer on the same board. Their Section III.B
states when the motion of a recording determines the 12 gyro parameters. This notebook works
through that theorem numerically with magyro's own public functions, on simulated sessions of
the problems shipped in `problems/`. [observability.md](observability.md) derives everything
used here, and this notebook quotes its argument.

1. The model and the matrix `M` (eq. 10), on samples of a simulated session.
2. The integral of `M^T M` (eq. 11): its eigenvalues, and its rank against the noise floor, for
   the canonical motions.
3. What stays unobservable under one- and two-axis rotation, and why.
4. How the predicted accuracy improves as the recording gets longer.
5. Gravity, a second reference vector: what an accelerometer adds (on real data, BROAD trial 2).

The test suite runs this notebook (`tests/test_notebook.py`), so every `assert` below is checked.
""")

code(r"""
%matplotlib inline
import dataclasses

import numpy as np
import pandas as pd
import matplotlib.pyplot as plt
from scipy.linalg import null_space, subspace_angles

import magyro
from magyro.observability import analyse
from magyro.observability.advice import describe_direction
from magyro.observability.gate import FLOOR_FACTOR
from magyro.observability.matrix import PARAMETER_NAMES, information_integral, m_matrices
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

np.set_printoptions(precision=3, suppress=True, linewidth=110)
pd.set_option("display.precision", 3)
""")

# --------------------------------------------------------------------------- 1. the model and M

md(r"""
## 1. The model and the matrix M (eq. 10)

The calibrated gyro (eq. 8) turns the magnetometer frame, and the step-1 calibrated
magnetometer sees the unit field `m^m` in that frame. With `w = K y_g + eps` the field moves as

    dm^m/dt = m^m x w = (m^m x) K y_g + (m^m x) eps.

The vec identity `vec(A B C) = (C^T (x) A) vec(B)` with `A = (m^m x)`, `B = K`, `C = y_g` makes the
first term linear in `vec K`, so

    dm^m/dt = [ y_g^T (x) (m^m x),  m^m x ] [vec K; eps] = M theta          (eq. 10)

`M` is 3 x 12 and contains only measured quantities: the raw gyro reading `y_g` and the field
`m^m`. The unknowns are `theta = [vec K; eps]`, where `K = C_b^m K_g` and `eps = C_b^m eps_b`.
`vec` stacks the columns of `K`, so the 12 columns of `M` are:

| columns | parameters | block of M |
|---|---|---|
| 1-3 | `K11 K21 K31` (column 1 of K: the response to the gyro's x reading) | `y_x (m^m x)` |
| 4-6 | `K12 K22 K32` (column 2: the y reading) | `y_y (m^m x)` |
| 7-9 | `K13 K23 K33` (column 3: the z reading) | `y_z (m^m x)` |
| 10-12 | `eps_x eps_y eps_z` (the bias, in the magnetometer frame) | `m^m x` |

We simulate the `three-axes` problem: paper sensors, 20 s of turning about the gyro x axis,
then 20 s about y, then 20 s about z. Its magnetometer is ideal (unit field, `R = I`, `h = 0`),
so its readings already are the calibrated field `m^m`, plus noise. `magyro solve` and
`magyro observe` get `m^m` from the step-1 ellipsoid fit instead, and evaluate `M` on the gyro's
time base, as `information_integral` does below.
""")

code(r"""
problem = load_problem("three-axes")
session, truth = simulate(problem, 0)
assert np.allclose(truth["magnetometer"]["R"], np.eye(3)) and np.allclose(truth["magnetometer"]["h"], 0)
print(problem.description)
print(f"{len(session.t_gyro_s)} gyro and {len(session.t_mag_s)} magnetometer samples over {session.duration_s:.0f} s")

M = m_matrices(session.gyro_rad_s, session.mag)  # (N, 3, 12), one M per sample
print("M at every sample:", M.shape)
k = int(np.searchsorted(session.t_gyro_s, 10.0))  # t = 10 s: in the x slot
print(f"\nM at t = {session.t_gyro_s[k]:.2f} s (the gyro reads y_g = {session.gyro_rad_s[k]} rad/s):")
pd.DataFrame(M[k], index=["row x", "row y", "row z"], columns=PARAMETER_NAMES).round(4)
""")

md(r"""
Each block of three columns is the skew matrix `(m^m x)` scaled by one gyro reading, and the last
block is `(m^m x)` itself. At `t = 10 s` the device turns about its x axis only, so the x reading
is large and the y and z readings hold little more than the bias. The `K12 ... K33` blocks are
therefore small, and so is how much the data can say about them. Here are a few samples, one in each
slot, as the Frobenius norm of each block:
""")

code(r"""
blocks = {"K col 1 (y_x m x)": slice(0, 3), "K col 2 (y_y m x)": slice(3, 6),
          "K col 3 (y_z m x)": slice(6, 9), "eps (m x)": slice(9, 12)}
rows = {}
for t in (10.0, 30.0, 50.0):
    i = int(np.searchsorted(session.t_gyro_s, t))
    rows[f"t = {t:.0f} s"] = {name: np.linalg.norm(M[i][:, cols]) for name, cols in blocks.items()}
pd.DataFrame(rows).T
""")

md(r"""
Eq. (10) is exact for noise-free data. With the noise switched off (`simulate(..., noise_scale=0)`),
`M theta` with the true `theta` matches the field's time derivative (here a central difference),
sample by sample:
""")

code(r"""
clean, _ = simulate(problem, 0, noise_scale=0.0)
theta = np.concatenate([np.asarray(truth["gyro"]["K"]).ravel(order="F"), truth["gyro"]["eps_rad_s"]])  # [vec K; eps]
predicted = m_matrices(clean.gyro_rad_s, clean.mag) @ theta          # M theta, (N, 3)
measured = np.gradient(clean.mag, clean.t_mag_s, axis=0)             # dm^m/dt
err = np.max(np.abs(predicted - measured)[1:-1])
print(f"largest |M theta - dm/dt| = {err:.2e} (the field moves at up to {np.max(np.abs(measured)):.2f} per second)")
assert err < 1e-2 * np.max(np.abs(measured))

fig, ax = plt.subplots(figsize=(9, 3))
t = clean.t_gyro_s
for j, c in enumerate("xyz"):
    ax.plot(t, measured[:, j], color=f"C{j}", lw=2.5, alpha=0.4, label=f"dm_{c}/dt (difference)")
    ax.plot(t, predicted[:, j], color=f"C{j}", lw=0.8, ls="--", label=f"(M theta)_{c}")
ax.set(xlabel="t (s)", ylabel="1/s", title="eq. 10 on the noise-free three-axes session")
ax.legend(ncol=3, fontsize=8)
plt.show()
""")

# --------------------------------------------------------------------------- 2. the integral and its rank

md(r"""
## 2. The integral of M^T M (eq. 11) and its rank

Multiply eq. (10) by `M^T` and integrate: `integral of M^T dm/dt dt = G theta`, with
`G = integral of M^T M dt`. When `G` is nonsingular, `theta = G^-1 integral of M^T dm/dt dt` (eq. 11)
is determined by the data. Conversely, observability.md argues, take `v != 0` with `G v = 0`:

> Then `integral of |M v|^2 dt = v^T G v = 0`, so `M(t) v = 0` at all times. The parameters
> `theta + v` produce exactly the same field trajectory, and no estimator can tell them apart.
> **The null space of G is exactly the set of unobservable parameter combinations**, and `rank G`
> counts the observable ones.

With noisy data `G` is never exactly singular. `magyro.observability.analyse` counts an
eigen-direction `v` of `G` only when its eigenvalue exceeds `FLOOR_FACTOR = 10` times `v^T N v`,
what sensor noise alone puts in that very direction (`N` is derived in Section 3 of
observability.md). This is the same rule the gate of `magyro solve` applies. The noise levels
here are the simulation's: the gyro's per-sample std, and the magnetometer's in units of the field.

We take the canonical motions: still, one axis, two axes, three axes one after another, and the
paper's Table I motion (all three axes at once).
""")

code(r"""
CANONICAL = {  # problem: (motion, the rank observability.md derives)
    "static": ("none", 2),
    "axis-x": ("about gyro x only", 6),
    "two-axes": ("x, then y", 9),
    "three-axes": ("x, then y, then z", 12),
    "paper-table1": ("x, y, z at once (Table I)", 12),
}


def analysis_of(name, duration_s=None):
    # G, its eigen-directions and the rank against the noise floor, for a simulated session (noise seed 0)
    p = load_problem(name)
    if duration_s is not None:
        p = dataclasses.replace(p, duration_s=duration_s)
    s, _ = simulate(p, 0)
    return analyse(s.t_gyro_s, s.gyro_rad_s, s.t_mag_s, s.mag,
                   gyro_sample_std_rad_s=p.gyro_sample_std_rad_s,
                   mag_std_unit_field=p.mag_noise_std / p.field_strength)


analyses = {name: analysis_of(name) for name in CANONICAL}
G = analyses["three-axes"].information
assert np.allclose(G, information_integral(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, session.mag))
print("G = integral of M^T M over the three-axes session:", G.shape, "symmetric:", np.allclose(G, G.T))

table = pd.DataFrame(
    [{"problem": name, "motion": motion, "rank (theorem)": theorem, "rank (magyro)": analyses[name].rank,
      "condition": analyses[name].condition} for name, (motion, theorem) in CANONICAL.items()]
).set_index("problem")
for name, a in analyses.items():
    print(f"{name:13s} rank {a.rank} of 12 (condition {a.condition:.3g})")
ranks = [analyses[name].rank for name in CANONICAL]
assert ranks == [2, 6, 9, 12, 12], ranks
assert (table["rank (theorem)"] == table["rank (magyro)"]).all()
table
""")

md(r"""
The ranks are the theorem's. (The table of Section 5 of observability.md comes from `magyro observe`,
which estimates the noise levels from the data and fits the magnetometer's ellipsoid; its ranks are the
same and its condition numbers close.) The condition numbers of the rank-deficient motions are large but
finite: their smallest eigenvalues are not zero, they hold noise. The left panel shows the
eigenvalues of `G` (divided by the largest), the right one the signal to noise of each
eigen-direction, `lambda_v / v^T N v`, against the threshold of 10. The directions the motion never
excites sit near 1, whatever their raw eigenvalue, which is why the rank is counted against the noise
floor and not against zero.
""")

code(r"""
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
for n, (name, a) in enumerate(analyses.items()):
    ax1.semilogy(np.arange(1, 13), np.sort(a.eigenvalues) / np.max(a.eigenvalues), "o-", color=f"C{n}",
                 label=f"{name} (rank {a.rank})")
    ax2.semilogy(np.arange(1, 13), np.sort(a.signal_to_noise), "o-", color=f"C{n}", label=name)
ax2.axhline(FLOOR_FACTOR, color="k", ls="--", lw=1, label=f"threshold ({FLOOR_FACTOR:g} x noise)")
ax1.set(xlabel="eigenvalue number (ascending)", ylabel="eigenvalue / largest", title="eigenvalues of G")
ax2.set(xlabel="eigen-direction (ascending)", ylabel="lambda_v / v^T N v", title="signal to noise per direction")
ax1.legend(fontsize=8)
ax2.legend(fontsize=8)
plt.tight_layout()
plt.show()
""")

# --------------------------------------------------------------------------- 3. the null space

md(r"""
## 3. What one- and two-axis rotation leave unobservable, and why

The directions below the noise floor are the (numerical) null space of `G`. `analyse` orders
the eigen-directions weakest first, so the first `12 - rank` columns of `eigenvectors` span it.
Each is a unit 12-vector over `[vec K; eps]`; `describe_direction` names its largest components.
A basis of a null space of dimension more than 1 is not unique (any rotation of it is another), so
the share of each parameter in the null space, the squared length of its unit vector projected onto
it, is the better summary: 1 means entirely unobservable, 0 entirely observable.
""")

code(r"""
def null_basis(a):
    return a.eigenvectors[:, : 12 - a.rank]


for name in ("axis-x", "two-axes"):
    a = analyses[name]
    print(f"{name}: rank {a.rank}, {12 - a.rank} unobservable directions")
    for v in null_basis(a).T:
        print("   ", describe_direction(v))
    print("  share of each parameter group:", "; ".join(a.weak_directions))
    print()

shares = pd.DataFrame({name: np.sum(null_basis(analyses[name]) ** 2, axis=1) for name in ("axis-x", "two-axes")},
                      index=PARAMETER_NAMES)
fig, ax = plt.subplots(figsize=(9, 3))
shares.plot.bar(ax=ax, rot=0)
ax.set(ylabel="share in the null space", title="what the motion leaves unobservable")
plt.show()
shares.T
""")

md(r"""
For `axis-x` the whole of columns 2 and 3 of `K` (`K12 ... K33`) is unobservable, with a fraction of
a percent of the bias. For `two-axes` it is column 3 (`K13 K23 K33`), again with a trace of the bias.
observability.md derives this. A direction `v = (dK, deps)` is in the null space exactly when

    M(t) v = m(t) x (dK y_g(t) + deps) = 0   for all t,   i.e.   dK y_g(t) + deps  is parallel to m(t).

When the body turns about gyro axis `u` at the rate `omega(t)`, the gyro reads `y_g(t) = a + omega(t) b`,
with `a = -K_g^-1 eps_b` and `b = K_g^-1 u`, the direction of that axis in reading space. Quoting
observability.md on **one axis**:

> `y_g` is affine in the one scalar `omega(t)`, so
> `dK y_g + deps = (dK a + deps) + omega(t) dK b = c1 + omega(t) c2`, with `c1 = dK a + deps`, `c2 = dK b`.
> Only the 6 numbers `(c1, c2)` enter. The linear map `v -> (c1, c2)` from R^12 onto R^6 has a
> 6-dimensional kernel that no such motion can see, so the rank is at most 6. [...]
> The six observable combinations are `c2 = dK b`, the column of `K` that responds to the turned axis
> (for `axis-x`, column 1: `K11 K21 K31`), and `c1 = deps + dK a`, which is mostly the bias because `a`
> is small. The two other columns of `K` are unobservable.

In words: the readings of an axis that never turns hold only the (constant) bias and noise, so the
column of `K` that multiplies them acts like one more constant bias term. It cannot be told apart from
`eps`, so only the combination `c1` is seen. And on **two axes** (the integral is the sum over the two
slots, both positive semi-definite, so `null(G) = null(G_x) ∩ null(G_y)`):

> `dK b_x = 0,  dK b_y = 0,  dK a + deps = 0.`
> `dK` vanishes on the plane `span(b_x, b_y)`, which leaves one free column direction (3 numbers), and
> `deps = -dK a` is then fixed. That makes a 3-dimensional null space, so the rank is 12 - 3 = 9. The
> unobservable share is the z-axis response, the column of `K` for the axis that never turned.

With three axes `b_x, b_y, b_z` span R^3, so `dK = 0`, then `deps = 0`: rank 12.

The theorem's null space can be written down from the true `K_g` and `eps_b` alone: the solutions of
`dK b_u = 0` for every turned axis `u` and `dK a + deps = 0`. It should be the subspace the data left
unexcited. The principal angles between the two measure how far apart they are (0 deg: the same
subspace):
""")

code(r"""
def theorem_null_space(p, turned_axes):
    # null space of v = [vec dK; deps] -> (dK b_u for each turned axis u, dK a + deps)
    Kg_inv = np.linalg.inv(p.K_g)
    a = -Kg_inv @ p.gyro_bias_rad_s
    rows = [np.hstack([np.kron(Kg_inv @ np.eye(3)["xyz".index(u)], np.eye(3)), np.zeros((3, 3))])  # dK b_u
            for u in turned_axes]
    rows.append(np.hstack([np.kron(a, np.eye(3)), np.eye(3)]))                                   # dK a + deps
    return null_space(np.vstack(rows))


for name in ("axis-x", "two-axes"):
    p = load_problem(name)
    theory = theorem_null_space(p, p.motion.axes)
    data = null_basis(analyses[name])
    angles = np.rad2deg(subspace_angles(theory, data))
    print(f"{name}: theorem's null space has dimension {theory.shape[1]}; "
          f"principal angles to the unexcited directions of G (deg): {np.sort(angles)}")
    assert theory.shape[1] == data.shape[1]
    assert np.max(angles) < 5.0
""")

# --------------------------------------------------------------------------- 4. predicted std vs duration

md(r"""
## 4. The predicted accuracy as the recording gets longer

Rank 12 says that every parameter is determined. How well it is determined is a question of how
much information the recording holds, and that grows with the motion and with the duration.
`magyro.observe(session)` predicts the one-sigma of every calibration parameter before any solve:
the Fisher information of the joint least squares that `magyro solve` minimises, evaluated at the
linear initial estimate (eq. 13), with the session's noise levels estimated from the data
(`ObservabilityReport.predicted_std`, a `Std` laid out like the calibration's `std`).

We simulate the paper's Table I problem at several durations. The motion is the same kind
(`dataclasses.replace` on the scenario's `duration_s`; the sinusoids are drawn from the fixed
motion seed and windowed to the new length). If the information simply accumulated at a steady
rate, it would grow in proportion to the duration and the std would fall as `1/sqrt(T)`: slope `-1/2`
on log-log axes. That is the rule of thumb `magyro observe` gives in its advice ("the std falls as
1/sqrt(duration)"). Let us measure it.
""")

code(r"""
paper = load_problem("paper-table1")
durations = np.array([20.0, 40.0, 60.0, 90.0])
reports = {T: magyro.observe(simulate(dataclasses.replace(paper, duration_s=T), 0)[0]) for T in durations}
scale_ppm = np.array([1e6 * np.diag(reports[T].predicted_std.K_g) for T in durations])  # (T, 3) scale factors
bias = np.array([reports[T].predicted_std.bias_deg_s for T in durations])              # (T, 3) deg/s
pd.DataFrame({"rank": [reports[T].rank for T in durations],
              "verdict": [reports[T].verdict for T in durations],
              **{f"scale {c} (ppm)": scale_ppm[:, i] for i, c in enumerate("xyz")},
              **{f"bias {c} (deg/s)": bias[:, i] for i, c in enumerate("xyz")}},
             index=pd.Index(durations, name="duration (s)"))
""")

code(r"""
def loglog_slope(T, std):
    # least-squares slope of log(std) against log(T), per column
    return np.polyfit(np.log(T), np.log(std), 1)[0]


slopes = {"scale": loglog_slope(durations, scale_ppm), "bias": loglog_slope(durations, bias)}
fig, axes = plt.subplots(1, 2, figsize=(11, 4))
for ax, (what, values, unit) in zip(axes, [("scale", scale_ppm, "ppm"), ("bias", bias, "deg/s")]):
    for i, c in enumerate("xyz"):
        ax.loglog(durations, values[:, i], "o-", color=f"C{i}", label=f"{what} {c} (slope {slopes[what][i]:.2f})")
    ref = np.mean(values[0]) * np.sqrt(durations[0] / durations)
    ax.loglog(durations, ref, "k--", lw=1, label="1/sqrt(T)")
    ax.set(xlabel="duration T (s)", ylabel=f"predicted one-sigma ({unit})", title=f"gyro {what}")
    ax.set_xticks(durations, [f"{T:g}" for T in durations])
    ax.set_xticks([], minor=True)
    ax.legend(fontsize=8)
plt.tight_layout()
plt.show()

for what, values in (("scale", scale_ppm), ("bias", bias)):
    s = slopes[what]
    print(f"fitted log-log slope of the {what} std (x, y, z): {np.round(s, 2)} (mean {np.mean(s):.2f}; "
          "1/sqrt(T) is -0.5)")
    local = np.diff(np.log(values), axis=0) / np.diff(np.log(durations))[:, None]
    for (T0, T1), row in zip(zip(durations[:-1], durations[1:]), local):
        print(f"    local slope {T0:.0f} -> {T1:.0f} s: {np.round(row, 2)}")
    # measured when this notebook was written: scale -0.75 -0.76 -0.98, bias -0.71 -0.75 -0.92
    assert np.all((-1.2 < s) & (s < -0.4)), s
""")

md(r"""
Every predicted std falls with the duration, and faster than `1/sqrt(T)` over this range: the
fitted slopes are between about -0.7 and -1.0. The local slopes show where: the step from 20 to 40 s
is by far the steepest, and after 40 s the local slopes lie between about -0.4 and -0.75, around
-1/2. The likely reason is the motion itself: the Table I motion is slow (its sinusoids have periods
of 5 to 50 s, and it ramps in and out over 2 s at each end), so a 20 s recording has not yet shown
much of it, and a longer one adds new motion as well as more of the same. `1/sqrt(T)` is therefore
the cautious rule of thumb: recording longer sharpens every parameter at
least about that fast, and halving a std may take up to four times the recording. Turning faster and
through larger angles raises the information per second instead, and a motion that misses an axis
gains nothing there however long it lasts (Section 3). Section 6 of observability.md checks these
predictions against the actual spread of 100 solves: they agree within 10 %.
""")


# --------------------------------------------------------------------------- 5. gravity, a second reference vector

md(r"""
## 5. Gravity, a second reference vector

`M` is built from the field's direction alone: at each instant `dm/dt = m x w` sees the rotation
across the field, never the rotation about it. Gravity's direction in the body obeys the same
equation, so an accelerometer gives a second `M`, built the same way from the specific force's
direction `u` (up, in the body), and its `M^T M` adds to the field's. `magyro observe` does this
when the session has `ax ay az` (`ObservabilityReport.accelerometer`, docs/accelerometer.md); the
verdict stays the theorem's, the field's alone. We use the real BROAD trial 2 shipped in `data/`
(an IMU turned by hand about every axis, with rests at both ends) and cut it in time.

The theorem's still case (Section 2) predicts rank 2 for one reference vector: the bias across it.
Two reference vectors that are not parallel see the whole bias: rank 3. At the start of the motion,
the rate seen fully at each instant (three components instead of two) reaches full rank sooner.
""")

code(r"""
import os
from pathlib import Path
from magyro.io import load_session

# the repository's data/ (the notebook sits in docs/); MAGYRO_DATA elsewhere (tests/test_notebook.py sets it)
data = Path(os.environ.get("MAGYRO_DATA", Path.cwd().parent / "data"))
broad = load_session(data / "broad-02.parquet")
rows = {}
for label, (t0, t1) in {"first rest": (37.1, 39.9), "rest + 1.6 s of motion": (37.1, 41.5),
                        "whole trial": (0.0, 1e9)}.items():
    g = magyro.observe(broad.within(t0, t1)).accelerometer.gyro
    rows[label] = {"field only": g.rank_field_only, "gravity only": g.rank_gravity_only, "both": g.rank,
                   "condition field only": g.condition_field_only, "condition both": g.condition,
                   "angle field-gravity (deg)": g.field_gravity_angle_deg}
    if label == "first rest":
        rest = g
ranks = pd.DataFrame.from_dict(rows, orient="index")
assert tuple(ranks.loc["first rest", ["field only", "gravity only", "both"]]) == (2, 2, 3)
assert tuple(ranks.loc["rest + 1.6 s of motion", ["field only", "gravity only", "both"]]) == (8, 8, 12)
ranks
""")

md(r"""
At rest the direction gravity rescues is the bias along the field, the one component of `eps`
the field cannot see:
""")

code(r"""
rescued = max((w for w in rest.weakest if w.rescued), key=lambda w: w.snr_gravity)
field_direction = magyro.observe(broad.within(37.1, 39.9)).field_directions.mean(axis=0)
cosine = abs(rescued.vector[9:] @ field_direction) / np.linalg.norm(rescued.vector[9:]) / np.linalg.norm(field_direction)
print(f"rescued: {rescued.in_words}; signal to noise, field {rescued.snr_field:.2g}, gravity {rescued.snr_gravity:.3g}")
print(f"its bias part against the mean field direction: cos = {cosine:.3f}")
assert cosine > 0.95
""")

md(r"""
The accelerometer's own 12 parameters need something else: `f = A y + b` read against gravity
gives the information `(sum of [u;1][u;1]^T) (x) I`, singular when gravity's direction stays on a
plane in the body. Cutting trial 2's accelerometer to the samples with the specific force within
30 deg of `+z` (as if the device had never been held otherwise) loses a column of `A` against the bias:
""")

code(r"""
up = broad.acc_m_s2 / np.linalg.norm(broad.acc_m_s2, axis=1, keepdims=True)
keep = up[:, 2] > np.cos(np.radians(30))
z_up = dataclasses.replace(broad, t_acc_s=broad.t_acc_s[keep], acc_m_s2=broad.acc_m_s2[keep])
for label, s in (("whole trial", broad), ("z up only", z_up)):
    a = magyro.observe(s).accelerometer
    print(f"{label:12} rank {a.rank} of 12, spread {a.spread:.3f}, weakest {a.directions[0][4]}")
    print("             poses held (s):", {f: round(sec, 1) for f, sec in a.face_s.items()})
    for advice in a.advice:
        print("             -", advice)
assert a.rank == 9
""")


# --------------------------------------------------------------------------- build and write


CELL_IDS = [f"cell-{i:02d}" for i in range(len(CELLS))]


def build_notebook():
    """The notebook as an nbformat NotebookNode, without outputs, with fixed cell ids."""
    import nbformat
    from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

    cells = []
    for cell_id, (kind, source) in zip(CELL_IDS, CELLS):
        cell = new_markdown_cell(source) if kind == "md" else new_code_cell(source)
        cell["id"] = cell_id
        cells.append(cell)
    nb = new_notebook(cells=cells, metadata={
        "kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"},
        "language_info": {"name": "python"},
    })
    nbformat.validate(nb)
    return nb


def notebook_text() -> str:
    import nbformat

    return nbformat.writes(build_notebook()) + "\n"


def main(argv: list[str]) -> int:
    text = notebook_text()
    if argv == ["--check"]:
        same = NOTEBOOK.is_file() and NOTEBOOK.read_text(encoding="utf-8") == text
        print(f"{NOTEBOOK} is {'up to date' if same else 'out of date: run python docs/make_observability_notebook.py'}")
        return 0 if same else 1
    if argv:
        print(__doc__)
        return 2
    NOTEBOOK.write_text(text, encoding="utf-8")
    print(f"wrote {NOTEBOOK} ({len(CELLS)} cells)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
