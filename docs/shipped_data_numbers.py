"""Figures of docs/how-it-works.md, docs/ekf.md and docs/real-data.md computed from the shipped BROAD trials
data/broad-02.parquet and data/broad-07.parquet (loaded, the recording check's repairs applied, rests found: no
solve, well under a second each) and from the defaults of the simulated drifting logger in tests/degrade.py.

docs/make_readme_numbers.py, docs/make_ekf_numbers.py and docs/make_record_numbers.py add these blocks to their
pages; tests/test_doc_numbers.py checks them.
"""
from __future__ import annotations

import functools
import importlib.util
import inspect

import numpy as np

from doc_blocks import ROOT, fmt, g

SHIPPED = {"02": ROOT / "data" / "broad-02.parquet", "07": ROOT / "data" / "broad-07.parquet"}


@functools.lru_cache(maxsize=None)
def shipped(trial: str, repaired: bool = True):
    """The shipped BROAD trial as loaded (`repaired`: after the recording check's repairs, as the front end sees it)."""
    from magyro import load_session
    from magyro.front.repairs import repair_recording

    session = load_session(SHIPPED[trial])
    return repair_recording(session)[0] if repaired else session


def rest_readings(session, which: str = "longest", sensor: str = "mag") -> np.ndarray:
    """The readings of one rest the front end finds: the longest, the first or the last."""
    from magyro.front import rests

    segments = rests.find_rests(session).segments_s
    seg = {"longest": max(segments, key=lambda ab: ab[1] - ab[0]), "first": segments[0],
           "last": segments[-1]}[which]
    still = rests.rests_from_segments(session, [seg])
    return still.mag_still if sensor == "mag" else still.gyro_still


def autocorrelations(x: np.ndarray, lags=(1, 2, 3)) -> list[float]:
    """The lag-k autocorrelations, mean over the columns."""
    x = np.asarray(x, dtype=float) - np.mean(x, axis=0)
    return [float(np.mean([(c[:-k] @ c[k:]) / (c @ c) for c in x.T])) for k in lags]


def mag_autocorrelation_block() -> str:
    """BROAD's magnetometer as logged (held rows kept): lag-1..3 autocorrelations at broad-02's longest rest."""
    rho = autocorrelations(rest_readings(shipped("02", repaired=False)))
    return f"lag-1..3 autocorrelations {', '.join(f'{r:.2f}' for r in rho)}"


def ekf_mag_levels_block() -> str:
    """The front end's magnetometer level from third differences against the one from the rest (correlation
    included), on broad-02 as the front end sees it (held rows dropped)."""
    from magyro.front import noise

    s = shipped("02")
    third, _ = noise.third_difference_level(s.mag)
    rest = noise.effective_std(rest_readings(s))
    return (f"give {fmt(third)} {s.mag_unit} against {fmt(rest)} {s.mag_unit} from its longest rest (trial 02, the "
            "held rows dropped, as the front end sees it)")


def rest_drift_block() -> str:
    """The gyro mean of the last rest minus the first's, worst axis, on each shipped trial."""
    parts = []
    for trial in SHIPPED:
        s = shipped(trial)
        d = np.rad2deg(rest_readings(s, "last", "gyro").mean(0) - rest_readings(s, "first", "gyro").mean(0))
        parts.append(f"{fmt(np.max(np.abs(d)))} deg/s on trial {trial}")
    return " and ".join(parts)


def degrade_module():
    spec = importlib.util.spec_from_file_location("degrade", ROOT / "tests" / "degrade.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def serial_drift_block() -> str:
    """The drifting logger the tests simulate (tests/degrade.py's drifting_burst_stamps defaults)."""
    p = inspect.signature(degrade_module().drifting_burst_stamps).parameters
    return (f"wandering by {g(1e3 * p['wander_s'].default)} ms, {p['ppm'].default:+g} ppm, as "
            "tests/test_recording_causes.py simulates it")


HAND_HZ, HAND_AMPLITUDE, NOISE_STD, RATES_HZ = (0.5, 0.8, 1.0), 5.0, 0.001, (25.0, 40.0)


def third_difference_block() -> str:
    """A simulated hand (the three axes turning at 0.5, 0.8 and 1 Hz, as in tests/test_noise_without_rests.py)
    with white noise, sampled at 25 and 40 Hz: what the third differences and the differences' floor read,
    in units of the noise's std."""
    from magyro.front.differences import noise_floor_std, white_noise_std

    third, floor = [], []
    for rate in RATES_HZ:
        t = np.arange(0, 60, 1 / rate)
        hand = np.column_stack([HAND_AMPLITUDE * np.sin(2 * np.pi * f * t) for f in HAND_HZ])
        x = hand + NOISE_STD * np.random.default_rng(0).standard_normal(hand.shape)
        third.extend(white_noise_std(x) / NOISE_STD)
        floor.extend(noise_floor_std(x)[0] / NOISE_STD)
    return (f"on a simulated hand turning at {g(min(HAND_HZ))}-{g(max(HAND_HZ))} Hz sampled at "
            f"{g(RATES_HZ[0])}-{g(RATES_HZ[1])} Hz the third differences read up to {max(third):.0f}x the noise, the "
            f"floor {min(floor):.2f}-{max(floor):.2f}x")
