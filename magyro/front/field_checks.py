"""The recording check's look at the magnetometer and the field (issue 22), in the order of causes:

- `normalised`     readings scaled to unit length by the logger (every |m| = 1): the iron cannot be
                   recovered from directions (units; error);
- `stuck`          an axis of a sensor that never changes (error);
- `saturation`     magnetometer axes pinned at their range (an x-IMU at 16 G: mx at one value in 46 %
                   of the samples): those samples are cut; over MAG_SATURATED_ERROR of them, error;
- `slow`           a magnetometer that delivers new values under SLOW_MAG_HZ (warning);
- `field_anomaly`  stretches where the field's magnitude leaves the ellipsoid the rest of the recording
                   fits (a magnet passing by, the device near steel): cut like spikes, the solve does not
                   cross them; over ANOMALY_ERROR of the samples the field is not homogeneous (error);
- `field`          no ellipsoid at all although the gyro says the device turned about every axis: the
                   magnetometer does not follow, or the field is not homogeneous (error; the motion's
                   share of such failures is the gate's, magyro.front.causes).
"""
from __future__ import annotations

import numpy as np

from magyro.front import causes, ellipsoid
from magyro.front.findings import Finding, repairable
from magyro.session import Session, runs_of_true

NORMALISED_TOLERANCE = 0.01        # every |m| within 1 % of 1
MAG_SAT_MIN_FRACTION = 0.01        # an axis at exactly its extreme in this share of the samples ...
MAG_SAT_MIN_RUNS = 3               # ... in this many separate runs ...
MAG_SAT_DOMINANCE = 3.0            # ... and this many times as often as any other value: pinned at the range
MAG_SATURATED_ERROR = 0.5          # more than this share cut: too little of the field is left
SLOW_MAG_HZ = 5.0
ANOMALY_MIN_SIZE = 0.1             # |field| off the fitted ellipsoid by 10 % ...
ANOMALY_NOISE = 8.0                # ... and by 8 robust stds of the norm error
ANOMALY_MIN_S = 0.5                # a stretch this long (shorter: spikes' business)
ANOMALY_MERGE_S = 1.0              # flagged samples closer than this are one stretch
ANOMALY_ERROR = 0.3                # more than this share of the samples off: not homogeneous
ANOMALY_MIN_THICKNESS = 0.25      # the cloud's thinnest spread over its widest (0.44-0.55 on hand-turned ones)
ANOMALY_MAX_SAMPLES = 3000        # the fits look at most this many samples (evenly spread)
ANOMALY_BLOCKS = 8                # the first fit: the best with one of these time blocks left out ...
ANOMALY_FITS, ANOMALY_TRUSTED = 2, 0.75   # ... then refits, each on this share of the samples nearest the last        # the fit looks at most this many samples (evenly spread)


def normalised_finding(t: np.ndarray, mag: np.ndarray) -> list:
    norm = np.linalg.norm(mag, axis=1)
    if not np.all(np.abs(norm - 1.0) < NORMALISED_TOLERANCE):
        return []
    return [Finding(
        "normalised", "magnetometer", "every magnetometer reading has length 1: the logger normalised the "
        "readings, so the hard and soft iron (the ellipsoid magyro fits) are gone from them",
        ((float(t[0]), float(t[-1])),), "error",
        "directions of an uncalibrated magnetometer are not the field's directions: no calibration can be made",
        "log the raw magnetometer readings (in uT, gauss or counts), not the normalised vector")]


def stuck_findings(t_g, gyro, t_m, mag) -> list:
    out = []
    for sensor, t, x in (("gyro", t_g, gyro), ("magnetometer", t_m, mag)):
        dead = [name for k, name in enumerate("xyz") if np.ptp(x[:, k]) == 0]
        if dead:
            out.append(Finding(
                "stuck", sensor, f"the {sensor} {', '.join(dead)} axis{'es read' if len(dead) > 1 else ' reads'} one "
                "value in every sample "
                f"({', '.join(f'{v:.6g}' for v in x[0, ['xyz'.index(n) for n in dead]])})",
                ((float(t[0]), float(t[-1])),), "error",
                f"a {sensor} axis that never changes measures nothing: no calibration can be made from it",
                f"check that the {sensor} columns are mapped right and that the sensor works"))
    return out


def saturation(t: np.ndarray, mag: np.ndarray, unit: str) -> tuple[np.ndarray, list]:
    """(rows with an axis pinned at its extreme, findings): per axis and sign, at least MAG_SAT_MIN_FRACTION of
    the samples at exactly the extreme value, in MAG_SAT_MIN_RUNS runs or more, and MAG_SAT_DOMINANCE times as
    many as at any value inside the range (a quantised axis that only touches its maximum often is not pinned)."""
    cut = np.zeros(len(t), dtype=bool)
    found = []
    for k, name in enumerate("xyz"):
        x = mag[:, k]
        if np.all(x == x[0]):
            continue   # a constant axis is stuck, not saturated
        for sign in (1.0, -1.0):
            at = sign * x >= np.max(sign * x)
            if at.mean() < MAG_SAT_MIN_FRACTION:
                continue
            counts = np.unique(x, return_counts=True)[1]
            other = counts[1:-1].max() if len(counts) > 2 else 0   # the most frequent value inside the range
            if (at.sum() >= MAG_SAT_DOMINANCE * other
                    and len(runs_of_true(at)) >= MAG_SAT_MIN_RUNS):
                cut |= at
                found.append(f"{name} at {sign * np.max(sign * x):+.6g} {unit} in {100 * at.mean():.0f} %")
    if not found:
        return cut, []
    share = float(cut.mean())
    return cut, [Finding(
        "saturation", "magnetometer", f"the magnetometer saturates: {'; '.join(found)} of the samples "
        f"({100 * share:.0f} % in all pinned at the range)", ((float(t[0]), float(t[-1])),),
        "error" if share > MAG_SATURATED_ERROR else "warning",
        "a pinned axis does not measure the field: those samples lie off the ellipsoid and would bend the fit "
        "and the attitude", **repairable(
            "saturation", "magyro cuts the pinned samples", "the pinned samples",
            "so few are left that the recording cannot be used: set the magnetometer to a larger range, or move "
            "it away from the magnet or iron that drives it to its range" if share > MAG_SATURATED_ERROR else ""),
        numbers={"fraction": share})]


def slow_finding(t: np.ndarray, held: np.ndarray) -> list:
    span = float(t[-1] - t[0])
    distinct_hz = (int((~held).sum()) - 1) / span if span > 0 else 0.0
    if distinct_hz >= SLOW_MAG_HZ:
        return []
    return [Finding(
        "slow", "magnetometer", f"the magnetometer gives new values at {distinct_hz:.1f} Hz only (under "
        f"{SLOW_MAG_HZ:g} Hz)", ((float(t[0]), float(t[-1])),), "warning",
        "between two readings a hand turns the device by tens of degrees: few samples, each stale",
        "log the magnetometer faster (10-100 Hz)", numbers={"distinct_rate_hz": distinct_hz})]


def anomalies(t: np.ndarray, mag: np.ndarray, keep: np.ndarray, unit: str) -> tuple[np.ndarray, list, bool]:
    """(samples in a field anomaly, findings, whether an ellipsoid fitted): the ellipsoid of the kept samples,
    the best with a time block left out, refitted ANOMALY_FITS times on the ANOMALY_TRUSTED nearest it (a
    disturbance bends a plain fit); stretches
    of ANOMALY_MIN_S or more off by ANOMALY_MIN_SIZE and ANOMALY_NOISE robust stds. Nothing when no ellipsoid
    fits (the gate's or `cloud_fault`'s business)."""
    cut = np.zeros(len(t), dtype=bool)
    rows = np.flatnonzero(keep)
    if len(rows) < 50:
        return cut, [], True
    used = rows[:: max(1, len(rows) // ANOMALY_MAX_SAMPLES)]
    spread = np.sort(np.linalg.eigvalsh(np.cov(mag[used].T)))
    if spread[0] < ANOMALY_MIN_THICKNESS ** 2 * spread[-1]:
        return cut, [], False   # a near-flat cloud (one circle of directions) fixes no ellipsoid to judge against
    noise = reading_noise(mag[rows])
    fit = best_of_left_out_blocks(mag[used], noise)
    if fit is None:
        return cut, [], False
    for _ in range(ANOMALY_FITS):   # least trimmed squares: refit on the samples nearest the last fit
        r = np.abs(np.linalg.norm((mag[used] - fit.h) @ fit.R.T, axis=1) - 1.0)
        try:
            fit = ellipsoid.fit_ellipsoid(mag[used[r <= np.quantile(r, ANOMALY_TRUSTED)]], noise)
        except (ellipsoid.DegenerateCloud, ellipsoid.InputError, np.linalg.LinAlgError):
            break
    r = np.abs(np.linalg.norm((mag[used] - fit.h) @ fit.R.T, axis=1) - 1.0)
    sigma = 1.4826 * np.median(r)
    limit = max(ANOMALY_MIN_SIZE, ANOMALY_NOISE * sigma)
    if not np.any(r > limit):
        return cut, [], True
    off = np.zeros(len(t), dtype=bool)
    off[rows] = np.abs(np.linalg.norm((mag[rows] - fit.h) @ fit.R.T, axis=1) - 1.0) > limit
    stretches = []
    flagged = np.flatnonzero(off)
    breaks = np.flatnonzero(np.diff(t[flagged]) > ANOMALY_MERGE_S)
    for a, b in zip(np.concatenate([[0], breaks + 1]), np.concatenate([breaks, [len(flagged) - 1]])):
        t0, t1 = float(t[flagged[a]]), float(t[flagged[b]])
        if t1 - t0 >= ANOMALY_MIN_S:
            stretches.append((t0, t1))
            cut |= (t >= t0) & (t <= t1)
    if not stretches:
        return cut, [], True
    share = float(cut[rows].mean())
    r_all = np.linalg.norm((mag - fit.h) @ fit.R.T, axis=1) - 1.0
    largest = float(np.max(np.abs(r_all[cut])))
    shown = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in stretches[:5]) + (" ..." if len(stretches) > 5 else "")
    homogeneous = share <= ANOMALY_ERROR
    return cut, [Finding(
        "field_anomaly", "magnetometer",
        (f"the field's magnitude leaves the ellipsoid of the rest of the recording by up to {100 * largest:.0f} % "
         f"in {len(stretches)} stretch(es), {100 * share:.0f} % of the samples: {shown}" if homogeneous else
         f"the field is not homogeneous: its magnitude is off the best ellipsoid by up to {100 * largest:.0f} % in "
         f"{100 * share:.0f} % of the samples ({shown})"),
        tuple(stretches), "warning" if homogeneous else "error",
        "the calibration assumes one field along the whole path: a magnet or iron near the device there bends "
        "the ellipsoid and the attitude (a magnet passing for 10 s made a good recording 'too uncertain')",
        **(repairable("spikes", "magyro cuts those stretches like spikes, and the solve does not cross them",
                      "those stretches") if homogeneous else
           {"fix": "record away from iron, steel furniture and magnets, turning the device in place"}),
        numbers={"stretches": len(stretches), "fraction": share, "largest": largest})], True


def best_of_left_out_blocks(y: np.ndarray, noise: float):
    """The ellipsoid fit, with each of ANOMALY_BLOCKS time blocks left out in turn, that leaves the fewest samples
    off by half ANOMALY_MIN_SIZE (a disturbance confined to one block bends every fit but the one without it); None
    when no ellipsoid fits the samples at all."""
    block = np.arange(len(y)) * ANOMALY_BLOCKS // len(y)
    fits = []
    for b in range(-1, ANOMALY_BLOCKS):   # -1: all the samples
        try:
            fits.append(ellipsoid.fit_ellipsoid(y[block != b], noise))
        except (ellipsoid.DegenerateCloud, ellipsoid.InputError, np.linalg.LinAlgError):
            continue
    if not fits:
        return None
    return min(fits, key=lambda f: float(np.mean(np.abs(np.linalg.norm((y - f.h) @ f.R.T, axis=1) - 1.0)
                                                 > 0.5 * ANOMALY_MIN_SIZE)))


def reading_noise(mag: np.ndarray) -> float:
    """A rough noise std of the readings (the largest over the axes, from second differences), for telling a
    point or a plane from a cloud."""
    return float(np.max(1.4826 * np.median(np.abs(np.diff(mag, 2, axis=0)), axis=0) / np.sqrt(6.0)))


def cloud_fault(session: Session, keep: np.ndarray) -> list:
    """The `field` error when the kept magnetometer samples fit no ellipsoid although the gyro says the device
    turned far about every axis (magyro.front.causes, causes 3-4); nothing when they fit or the motion is to
    blame (the gate says that, exit 3)."""
    mag = session.mag[keep]
    if len(mag) < 50:
        return []
    try:
        ellipsoid.fit_ellipsoid(mag, reading_noise(mag))
        return []
    except ellipsoid.DegenerateCloud as cloud:
        kind = cloud.kind
    except ellipsoid.NotAnEllipsoid:
        kind = "hyperboloid"
    except (ellipsoid.InputError, np.linalg.LinAlgError):
        return []
    fault = causes.magnetometer_fault(causes.turning(session), kind, mag)
    if fault is None:
        return []
    return [Finding("field", "magnetometer", str(fault), ((float(session.t_mag_s[0]), float(session.t_mag_s[-1])),),
                    "error", "no ellipsoid, no calibration", "")]
