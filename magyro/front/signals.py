"""The recording check's look at the signals: gyro saturation (`plateaus`, the rule the accelerometer's shares),
magnetometer spikes, and whether the gyro turns with the field (units both ways, the magnetometer's lag and its
drift). `magyro.front.recording` puts the findings together.
"""
from __future__ import annotations

import numpy as np

from magyro.front.findings import Finding, repairable
from magyro.session import runs_of_true
from magyro.text import significant

SAT_MIN_DEG_S = 30.0              # nobody's full scale is below this
SAT_MIN_SAMPLES = 3
SAT_MIN_RUNS = 3                  # or one steep entry/exit:
SAT_LONG_RUN = 5                  # or one plateau this long (no measured rate stays at its extreme so long)
SAT_STEEP_FRACTION = 0.01         # a step of this share of the range into or out of the plateau
FULL_SCALES_DEG_S = (125, 250, 245, 500, 1000, 2000, 4000)   # named when within 3 % (250 before ST's 245)
SPIKE_NOISE = 8.0                 # a spike is off the neighbours' median by SPIKE_SPREAD x
SPIKE_SPREAD = 3.0                #   (SPIKE_NOISE noise std + the neighbours' inner spread)
SPIKE_ALWAYS = 3                  # up to this many are spikes whatever the share
SPIKE_MAX_FRACTION = 0.01         # more than this share of the samples "far off" is the noise's shape, not spikes
LAG_GRID_S, LAG_SMOOTH_S, LAG_MAX_S = 0.005, 0.05, 0.5
LAG_SHARP_S, LAG_MIN_SHARPNESS = 0.05, 0.02   # the correlation must drop this much 50 ms off its peak
DRIFT_MIN_S = 0.02                # lag change between the first and last part of the recording
SOLVE_LAG_SEARCH_S = 0.1          # the solve's time-offset search (docs/how-it-works.md step 5)


def saturation(t: np.ndarray, gyro: np.ndarray) -> tuple[np.ndarray, list]:
    """(rows with an axis on a saturation plateau, findings): `plateaus` beyond SAT_MIN_DEG_S."""
    cut = np.zeros(len(t), dtype=bool)
    findings = []
    for axis, sign, extreme, at, begin, end in plateaus(gyro, np.radians(SAT_MIN_DEG_S)):
        cut |= at
        findings.append(saturation_finding("xyz"[axis], sign, extreme, t, at, begin, end))
    return cut, findings


def plateaus(x: np.ndarray, minimum: float):
    """The saturation plateaus of a sensor's samples x (N, 3), one (axis, sign, extreme, at, begin, end) per axis
    and sign that has one: at least SAT_MIN_SAMPLES samples at exactly the extreme value (`at`, a mask), which
    lies beyond `minimum` (in x's unit: below every full scale of the sensor, above what it reads at rest), in
    SAT_MIN_RUNS separate runs, entered/left steeply, or held for SAT_LONG_RUN samples in a row; begin and end are
    the runs' first and last indices. The gyro's rule (`saturation`), and the accelerometer's
    (`magyro.front.accelerometer_checks`)."""
    for axis in range(x.shape[1]):
        col = x[:, axis]
        for sign in (1.0, -1.0):
            extreme = float(np.max(sign * col))
            if extreme < minimum:
                continue
            at = sign * col >= extreme * (1 - 1e-9)
            n_at = int(at.sum())
            if n_at < SAT_MIN_SAMPLES:
                continue
            begin, end = (np.array(v, dtype=int) for v in zip(*runs_of_true(at)))
            steps = np.concatenate([np.abs(col[begin[begin > 0]] - col[begin[begin > 0] - 1]),
                                    np.abs(col[end[end < len(col) - 1] + 1] - col[end[end < len(col) - 1]])])
            steep = bool(len(steps) and steps.max() > SAT_STEEP_FRACTION * extreme)
            long_run = int(np.max(end - begin + 1)) >= SAT_LONG_RUN   # a smooth motion clipped flat for a while
            if len(begin) < SAT_MIN_RUNS and not steep and not long_run:
                continue
            yield axis, sign, extreme, at, begin, end


def saturation_finding(name, sign, extreme, t, at, begin, end) -> Finding:
    limit = float(np.degrees(extreme))
    scale = [s for s in FULL_SCALES_DEG_S if abs(limit - s) <= 0.03 * s]
    where = tuple((float(t[a]), float(t[b])) for a, b in zip(begin, end))
    return Finding(
        "saturation", "gyro", f"gyro {name} saturates at {'+' if sign > 0 else '-'}{limit:.1f} deg/s: "
        f"{int(at.sum())} samples ({100 * at.mean():.2f} %) on {len(begin)} plateau(s)"
        + (f", a +/-{scale[0]} deg/s full scale" if scale else ""),
        where, "warning",
        "the true rate was beyond the range there: integrating the plateau under-turns the attitude "
        "(10 % of samples clipped gave K_g 0.44 and a bias 4.9 deg/s off with exit 0)",
        **repairable("saturation", "magyro cuts the saturated samples and never integrates across them",
                     "the saturated samples", "record with a larger gyro range or turn more slowly"),
        numbers={"axis": name, "limit_deg_s": sign * limit, "samples": int(at.sum()), "plateaus": len(begin)})


def spikes(t: np.ndarray, mag: np.ndarray, unit: str, held: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """(rows that are spikes, findings): a sample off the median of its four neighbours by more than
    SPIKE_SPREAD x (SPIKE_NOISE noise std + the neighbours' inner spread), on any axis. Rows that repeat the
    previous one (`held`) are left out of the comparison (repeats make the neighbours agree exactly). More
    than SPIKE_MAX_FRACTION of the samples flagged is the noise's own shape: nothing is dropped, and the
    finding says so."""
    flagged = np.zeros(len(mag), dtype=bool)
    rows = np.flatnonzero(~held) if held is not None else np.arange(len(mag))
    x = mag[rows]
    n = len(x)
    if n < 5:
        return flagged, []
    a, b, c, d = x[:-4], x[1:-3], x[3:-1], x[4:]
    lo1, hi1, lo2, hi2 = np.minimum(a, b), np.maximum(a, b), np.minimum(c, d), np.maximum(c, d)
    p, q = np.maximum(lo1, lo2), np.minimum(hi1, hi2)
    second, third = np.minimum(p, q), np.maximum(p, q)      # the middle two of the four neighbours
    off = np.abs(x[2:-2] - 0.5 * (second + third))
    noise = 1.4826 * np.median(off, axis=0)
    if np.any(noise == 0):   # quantised readings that mostly agree: the quantisation step is the noise's floor
        noise = np.maximum(noise, resolution(x))
    far = np.any(off > SPIKE_SPREAD * (SPIKE_NOISE * noise + (third - second)), axis=1)
    if not far.any():
        return flagged, []
    i = np.flatnonzero(far) + 2
    size = off[i - 2].max(axis=1)
    ratio = float(np.max(off[i - 2] / noise))
    shown = ", ".join(f"{t[rows[j]]:.3f}" for j in i[:5]) + (" ..." if len(i) > 5 else "")
    numbers = {"count": len(i), "largest": float(size.max()), "noise_std": float(noise.max()),
               "fraction": len(i) / n}
    if len(i) > max(SPIKE_MAX_FRACTION * n, SPIKE_ALWAYS):
        return flagged, [Finding(
            "spikes", "magnetometer", f"{len(i)} magnetometer samples ({100 * len(i) / n:.1f} %) are far off their "
            f"neighbours (up to {significant(size.max())} {unit}, {ratio:.0f}x the noise): too many to be spikes, so none is "
            f"dropped (more than {100 * SPIKE_MAX_FRACTION:g} % is the noise's own shape or a field that changes "
            "faster than it is sampled)", ((float(t[0]), float(t[-1])),), "info",
            "a noise with heavy tails weighs a little more in the least squares than its std says",
            "nothing; if the samples are truly disturbed, check the wiring or the I2C bus", numbers=numbers)]
    flagged[rows[i]] = True
    where = tuple((float(t[rows[j]]), float(t[rows[j]])) for j in i)
    return flagged, [Finding(
        "spikes", "magnetometer", f"{len(i)} magnetometer sample(s) far off their neighbours (up to "
        f"{significant(size.max())} {unit}, {ratio:.0f}x the noise) at {shown} s",
        where, "warning",
        "the ellipsoid fit is least squares: 20 spikes in 7500 samples made it call a good recording "
        "'too little of the sphere' (exit 3)",
        **repairable("spikes", "magyro drops them", "the spikes", "check the wiring or the I2C bus"),
        numbers=numbers)]


def resolution(x: np.ndarray) -> np.ndarray:
    """Per axis, the smallest step between two different readings (the quantisation; 0 for a constant axis)."""
    out = np.zeros(x.shape[1])
    for k in range(x.shape[1]):
        steps = np.diff(np.unique(x[:, k]))
        if len(steps):
            out[k] = float(steps.min())
    return out


def field_directions(mag: np.ndarray):
    """The field after a sphere fit (unit radius), or None when the cloud does not cover enough of the
    sphere to trust it (a cap or one circle: the gate's business, not this check's)."""
    if len(mag) < 50:
        return None
    c0 = mag.mean(axis=0)
    y = mag - c0
    A = np.column_stack([2 * y, np.ones(len(y))])
    sol = np.linalg.solve(A.T @ A + 1e-12 * np.eye(4), A.T @ np.einsum("ij,ij->i", y, y))
    centre = sol[:3]
    r = np.linalg.norm(y - centre, axis=1)
    radius = float(np.sqrt(max(sol[3] + centre @ centre, 0.0)))
    if radius <= 0 or np.sqrt(np.mean((r - radius) ** 2)) > 0.15 * radius:
        return None
    f = (y - centre) / r[:, None]
    if np.sqrt(max(np.linalg.eigvalsh(np.cov(f.T))[0], 0.0)) < 0.15:
        return None
    return (y - centre) / radius   # unit field as a sphere calibrates it: its norm keeps the noise


def field_turning_findings(t_g, gyro, t_m, mag) -> tuple[list, tuple]:
    """(findings, ((lag at the start, at the end), (their times)) or ()): the gyro unit both ways, and the
    magnetometer's lag behind the gyro, drifting or beyond the solve's search."""
    f = field_directions(mag)
    t0, t1 = max(t_g[0], t_m[0]), min(t_g[-1], t_m[-1])
    if f is None or t1 - t0 < 2.0:
        return [], ()
    findings = gyro_unit_findings(t_g, gyro, t_m, mag, f)
    if findings:
        return findings, ()
    measured = lags(t_g, gyro, t_m, f, t0, t1)
    if measured is None:
        return [], ()
    lag, at = measured
    where = ((t0, t1),)
    numbers = {"lag_start_s": lag[0], "lag_end_s": lag[1]}
    if abs(lag[1] - lag[0]) > DRIFT_MIN_S:
        ppm = (lag[1] - lag[0]) / (0.65 * (t1 - t0)) * 1e6   # the windows' centres are 0.65 of the span apart
        findings.append(Finding(
            "clock_drift", "both", f"the magnetometer lags the gyro by {lag[0] * 1e3:.0f} ms at the start and "
            f"{lag[1] * 1e3:.0f} ms at the end: the two clocks run at different rates (about {ppm:+.0f} ppm)",
            where, "warning", f"the solve fits one constant lag: the rest, up to "
            f"{abs(lag[1] - lag[0]) * 500:.0f} ms, turns into attitude error at every rotation",
            **repairable("clocks", "magyro takes the drift of the measured lag (and the lag itself "
                         "when beyond the solve's search) off the magnetometer's times", "the magnetometer's times",
                         "better: stamp both sensors on one clock"), numbers=numbers))
    elif max(abs(lag[0]), abs(lag[1])) > SOLVE_LAG_SEARCH_S:
        findings.append(Finding(
            "time_offset", "both", f"the magnetometer lags the gyro by about {np.mean(lag) * 1e3:.0f} ms, more than "
            f"the +/-{SOLVE_LAG_SEARCH_S * 1e3:.0f} ms the solve searches", where, "warning",
            "a lag the solve does not find turns into attitude error at every rotation",
            **repairable("clocks", f"magyro shifts the magnetometer's times by {-np.mean(lag):+.3f} s",
                         "the magnetometer's times"), numbers=numbers))
    return findings, (tuple(lag), tuple(at))


def gyro_unit_findings(t_g, gyro, t_m, mag, field) -> list:
    """The gyro must turn the field as fast as the magnetometer sees it turn, both ways: the solve's own check
    (`magyro.front.prepare.check_gyro_unit`) on the sphere-fitted field, as a finding."""
    from magyro.errors import InputError
    from magyro.front.prepare import check_gyro_unit
    from magyro.session import Session

    try:
        check_gyro_unit(Session(t_g, gyro, t_m, mag), field)
    except InputError as wrong:
        return [Finding("gyro_unit", "gyro", str(wrong), ((float(t_g[0]), float(t_g[-1])),), "error",
                        "the gyro scale would come out 57x (or 1/57x) and the solve could not converge",
                        "")]   # the message names the --gyro-unit to pass
    return []


def lags(t_g, gyro, t_m, f, t0, t1):
    """((lag at the start, lag at the end), (the times they are measured at)) of the magnetometer behind the
    gyro, s, or None when the motion is too smooth to tell: the peak of the correlation of the field's turning rate with the gyro's |w x f|
    (frames taken as aligned) or |w| (frame-free), whichever agrees better, over the first and last 35 %."""
    grid = np.arange(t0, t1, LAG_GRID_S)
    f_grid = np.column_stack([np.interp(grid, t_m, f[:, i]) for i in range(3)])
    w_grid = np.column_stack([np.interp(grid, t_g, gyro[:, i]) for i in range(3)])
    seen = np.zeros(len(grid))
    seen[1:-1] = np.linalg.norm(f_grid[2:] - f_grid[:-2], axis=1) / (2 * LAG_GRID_S)
    width = max(1, int(round(LAG_SMOOTH_S / LAG_GRID_S)))
    kernel = np.ones(width) / width
    seen = np.convolve(seen, kernel, "same")
    signals = [np.convolve(np.linalg.norm(np.cross(w_grid, f_grid), axis=1), kernel, "same"),
               np.convolve(np.linalg.norm(w_grid, axis=1), kernel, "same")]
    n, max_lag = len(grid), int(LAG_MAX_S / LAG_GRID_S)
    part = int(0.35 * n)
    if part < 4 * max_lag:
        return None
    windows = (max_lag, n - part - max_lag)
    first = [correlation(seen, w, windows[0], part, max_lag) for w in signals]
    best = int(np.argmax([rho.max() for rho in first]))
    out = []
    for rho in (first[best], correlation(seen, signals[best], windows[1], part, max_lag)):
        i = int(np.argmax(rho))
        step = int(round(LAG_SHARP_S / LAG_GRID_S))
        if i < step or i >= len(rho) - step or rho[i] - max(rho[i - step], rho[i + step]) < LAG_MIN_SHARPNESS:
            return None
        y0, y1, y2 = rho[i - 1:i + 2]
        out.append((max_lag - i - 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)) * LAG_GRID_S)
    centres = (t0 + (windows[0] + part / 2) * LAG_GRID_S, t0 + (windows[1] + part / 2) * LAG_GRID_S)
    return (float(out[0]), float(out[1])), centres


def correlation(seen, w, lo, part, max_lag) -> np.ndarray:
    """Pearson correlation of seen[lo:lo+part] with w shifted by max_lag ... -max_lag samples."""
    s = seen[lo:lo + part] - seen[lo:lo + part].mean()
    ws = w[lo - max_lag:lo + part + max_lag]
    c1, c2 = np.concatenate([[0.0], np.cumsum(ws)]), np.concatenate([[0.0], np.cumsum(ws * ws)])
    m = np.arange(2 * max_lag + 1)
    ss = (c2[m + part] - c2[m]) - (c1[m + part] - c1[m]) ** 2 / part
    return np.correlate(ws, s, "valid") / np.sqrt(np.maximum(ss, 1e-30) * np.dot(s, s))
