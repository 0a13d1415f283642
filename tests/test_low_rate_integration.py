"""A gyro logged slowly (a phone's 28 Hz) and a hand's motion: the rate integrated to high order.

Taken as linear between samples, a rate of frequency f sampled at fs integrates short by about
(2 pi f / fs)^2 / 12, which biased the gyro scale of a 28 Hz phone turned by hand up to 1.5 Hz by
+0.6 to 0.8 % (about 10 std). `high_order_samples` pre-filters the samples so the grid's trapezoid is
of high order; next to a hole or a jittered stamp the samples stay raw.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from magyro.nls.grid import build_grid
from magyro.nls.gyro_samples import (FOURTH_ORDER, SIXTH_ORDER, evenly_spaced_interior, filter_widths,
                                     high_order_samples)
from magyro.nls.run import calibrate_nls
from magyro.options import Options
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

PROBLEM = "problems/phone-fast-hand.toml"


def step_errors(t, w, f_hz):
    """Error of each trapezoid step of samples w against the exact integral of sin(2 pi f t) over it."""
    exact = (np.cos(2 * np.pi * f_hz * t[:-1]) - np.cos(2 * np.pi * f_hz * t[1:])) / (2 * np.pi * f_hz)
    return 0.5 * np.diff(t) * (w[1:] + w[:-1]) - exact


def test_filtered_trapezoid_is_of_high_order_at_phone_rates():
    t = np.arange(205) / 28.0                       # 28 Hz, about 7.3 s
    f_hz = 1.5                                      # a quick hand
    w = np.sin(2 * np.pi * f_hz * t)[:, None] * np.ones(3)
    raw = step_errors(t, w[:, 0], f_hz)[2:-2]       # steps between two five-tap samples
    filtered = step_errors(t, high_order_samples(t, w)[:, 0], f_hz)[2:-2]
    h = 1 / 28.0                                    # the largest step integral (unit rate)
    assert np.max(np.abs(raw)) / h > 0.005          # linear in time: (2 pi f h)^2 / 12 = 0.9 % short
    assert np.max(np.abs(filtered)) < 2e-3 * np.max(np.abs(raw))   # 1/2000 of it: sixth order


def test_holes_and_jittered_stamps_stay_raw():
    t = np.arange(40) / 28.0
    t[20:] += 0.5                       # a hole between samples 19 and 20
    t[30] += 0.1 / 28.0                 # one stamp 10 % late
    w = np.random.default_rng(0).standard_normal((40, 3))
    out = high_order_samples(t, w)
    raw = ~evenly_spaced_interior(t)
    assert set(np.flatnonzero(raw)) == {0, 19, 20, 29, 30, 31, 39}
    np.testing.assert_array_equal(out[raw], w[raw])
    widths = filter_widths(t)
    assert list(widths[[1, 2, 18, 21, 28, 32, 38]]) == [3, 5, 3, 3, 3, 3, 3]   # next to them: three taps
    np.testing.assert_allclose(out[10], SIXTH_ORDER @ w[8:13])
    np.testing.assert_allclose(out[18], FOURTH_ORDER @ w[17:20])
    np.testing.assert_allclose(out[18], w[18] - (w[19] - 2 * w[18] + w[17]) / 12)


def test_grid_integrates_the_filtered_samples():
    """Linear interpolation at the magnetometer times between gyro samples keeps each gyro step's total."""
    t_gyro, t_mag = np.arange(57) / 28.0, np.arange(51) / 25.0      # both 0 .. 2 s
    w = np.sin(2 * np.pi * 1.3 * t_gyro)[:, None] * np.array([1.0, -0.5, 2.0])
    grid = build_grid(t_gyro, w, t_mag)
    total = np.einsum("isl,islk->k", grid.dt_s, 0.5 * (grid.gyro_a + grid.gyro_b))
    np.testing.assert_allclose(total, np.trapezoid(high_order_samples(t_gyro, w), t_gyro, axis=0), rtol=1e-12)


@pytest.fixture(scope="module")
def fast_hand():
    """(truth, calibration) of one 45 s phone session at 28/25 Hz turned by hand up to 1.5 Hz, the noise
    levels given (as --gyro-noise / --mag-noise would) so one pass solves it."""
    problem = dataclasses.replace(load_problem(PROBLEM), duration_s=45.0)
    session, truth = simulate(problem, 2)
    options = Options(gyro_noise_density_rad_s_sqrt_hz=truth["noise"]["gyro_density_rad_s_sqrt_hz"],
                      mag_noise_std=truth["noise"]["mag_std"])
    return truth, calibrate_nls(session, options)


def test_fast_hand_scale_lands_within_its_std(fast_hand):
    truth, cal = fast_hand
    K_true = np.array(truth["gyro"]["K_g"])
    z = (np.diag(cal.K_g) - np.diag(K_true)) / np.diag(np.array(cal.std.K_g))
    assert np.max(np.abs(z)) < 3.0, z       # a rate linear between samples put these at +8..+40 std
    z_b = (cal.bias_deg_s - np.array(truth["gyro"]["bias_deg_s"])) / np.array(cal.std.bias_deg_s)
    assert np.max(np.abs(z_b)) < 3.0, z_b
