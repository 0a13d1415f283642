"""A gap in the magnetometer record: bridged by weightless segments, not by padding every interval.

Before the bridge, one 0.5 s gap in BROAD trial 02 (285.7 Hz) padded every interval to
144 sub-steps and the solve took 529 s instead of 4 s.
"""
from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from magyro import calibrate

from magyro.nls.solve import default_stride
from magyro.nls.grid import build_grid, segment_starts
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

from test_calibrate import check_gyro_recovery


def with_gap(session, t0_s: float, length_s: float):
    keep = (session.t_mag_s < t0_s) | (session.t_mag_s > t0_s + length_s)
    return dataclasses.replace(session, t_mag_s=session.t_mag_s[keep], mag=session.mag[keep])


def test_gap_is_cut_into_segments_of_typical_length_on_gyro_times():
    t = np.concatenate([np.arange(0, 1, 0.01), np.arange(1.5, 2.0, 0.01)])
    t_gyro = np.arange(0, 2, 0.0025) + 0.0007
    used = np.arange(len(t))
    times, index, on_sample = segment_starts(t, used, t_gyro)
    assert np.all(np.diff(times) > 0)
    assert np.max(np.diff(times)) <= 0.01 + 0.0025 + 1e-12     # one typical interval, give or take a gyro step
    assert np.array_equal(times[on_sample], t)                # every sample is a boundary, flagged as one
    assert np.array_equal(index[on_sample], used)
    bridged = ~on_sample
    assert bridged.sum() == round(0.51 / 0.01) - 1            # 0.99 -> 1.5 in 51 pieces
    assert np.all(index[bridged] == 99)                       # they carry the sample before the gap
    assert np.all(np.isin(times[bridged], t_gyro))            # on gyro times: no extra sub-step


def test_no_gap_means_no_bridging_segments():
    t = np.arange(0, 2, 0.01) + 1e-4 * np.sin(np.arange(200))   # jitter is not a gap
    _, _, on_sample = segment_starts(t, np.arange(len(t)), np.arange(0, 2, 0.0025))
    assert on_sample.all()


@pytest.mark.slow
def test_a_one_second_gap_costs_nothing_and_changes_little():
    session, truth = simulate(load_problem("paper-table1"), 11)
    gapped = with_gap(session, 50.0, 1.0)
    grid = build_grid(gapped.t_gyro_s, gapped.gyro_rad_s, gapped.t_mag_s, default_stride(gapped))
    plain = build_grid(session.t_gyro_s, session.gyro_rad_s, session.t_mag_s, default_stride(session))
    assert grid.substeps == plain.substeps, grid.substeps    # the kernels keep their shape (padded: 100)
    assert (grid.mag_weight == 0).sum() == pytest.approx(100, abs=2)
    cal = calibrate(gapped)
    check_gyro_recovery(SimpleNamespace(cal=cal, truth=truth))
    n_mag = int(grid.mag_weight.sum())                    # the bridging segments add no residual
    assert cal.fit.residuals == 3 * n_mag + 3 * (grid.nodes - 1)
    assert not cal.fit.suspect_segments, cal.fit.suspect_segments
    full = calibrate(session)                              # 1 % fewer samples: the estimates hardly move
    assert np.all(np.abs(cal.K_g - full.K_g) <= 0.5 * full.std.K_g + 1e-12)
    assert np.all(np.abs(cal.bias_deg_s - full.bias_deg_s) <= 0.5 * full.std.bias_deg_s)
