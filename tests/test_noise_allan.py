"""`magyro noise` (magyro.noise_allan): the Allan deviation of a still recording read as Kalibr's noise numbers,
`solve --noise` and `export --format kalibr --noise` (issue 41)."""
from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

pytest.importorskip("allantools")

from magyro.errors import InputError  # noqa: E402
from magyro.io import load_session, write_session  # noqa: E402
from magyro.noise_allan import (SCHEMA, RecordingTooShort, allan_curve, read_axis, require_allantools,  # noqa: E402
                                samples_within, session_noise)
from magyro.noise_file import gyro_noise_deg_s_sqrt_hz_option, kalibr_export_file, read_noise  # noqa: E402
from magyro.session import Session  # noqa: E402

from conftest import SHIPPED_BROAD_02  # noqa: E402

RATE_HZ = 100.0
# a MEMS IMU's noise, per axis: white (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)), bias instability (rad/s, m/s^2) and random
# walk (rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)); the three terms' crossings (about 55 s and 250 s for the gyro) inside
# what 4 h shows with 9 clusters (1600 s)
GYRO = {"white": [2e-4, 2.5e-4, 3e-4], "bias_instability": [4e-5, 5e-5, 6e-5], "random_walk": [3e-6, 4e-6, 5e-6]}
ACC = {"white": [2e-3, 2e-3, 2.5e-3], "bias_instability": [4e-4, 5e-4, 5e-4], "random_walk": [3e-5, 4e-5, 4e-5]}
KALIBR_KEYS = {"gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
               "accelerometer_random_walk", "update_rate", "rostopic"}


def flicker(n: int, B: float, rng) -> np.ndarray:
    """Bias instability B as IEEE Std 952 reads it (flat Allan deviation 0.664 B): one-sided PSD B^2/(pi f),
    white noise shaped in the frequency domain."""
    f = np.fft.rfftfreq(n, 1.0 / RATE_HZ)
    gain = np.zeros_like(f)
    gain[1:] = np.sqrt(B**2 / (np.pi * f[1:]) * RATE_HZ / 2.0)
    return np.fft.irfft(np.fft.rfft(rng.standard_normal(n)) * gain, n)


def still_axes(n: int, terms: dict, rng) -> np.ndarray:
    """(n, 3) still readings: white + flicker + a random walk of the bias, per axis."""
    out = np.empty((n, 3))
    for a in range(3):
        white = terms["white"][a] * math.sqrt(RATE_HZ) * rng.standard_normal(n)
        walk = np.cumsum(terms["random_walk"][a] / math.sqrt(RATE_HZ) * rng.standard_normal(n))
        out[:, a] = white + flicker(n, terms["bias_instability"][a], rng) + walk
    return out


def still_session(seconds: float, seed: int) -> Session:
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    t_mag = t[::10]
    mag = np.array([20.0, 0.0, 40.0]) + 0.1 * rng.standard_normal((len(t_mag), 3))
    return Session(t, still_axes(n, GYRO, rng), t_mag, mag, "uT", t, still_axes(n, ACC, rng) + [0.0, 0.0, 9.81])


def assert_within_std(readings, truth: dict, name: str, sigmas: float = 3.0) -> None:
    for term, attr in (("white", "white"), ("bias_instability", "bias_instability"), ("random_walk", "random_walk")):
        for axis, r in enumerate(readings):
            value, std = getattr(r, attr), getattr(r, attr + "_std")
            assert value is not None, (name, term, axis, r.why_not)
            assert std < 0.5 * truth[term][axis], (name, term, axis, std)     # a std that says something
            assert abs(value - truth[term][axis]) <= sigmas * std, (name, term, axis, value, truth[term][axis], std)


@pytest.mark.slow
def test_a_4_h_still_recording_gives_each_term_within_its_std():
    report = session_noise(still_session(4 * 3600.0, seed=3), whole=True)
    assert_within_std(report.sensors["gyro"], GYRO, "gyro")
    assert_within_std(report.sensors["acc"], ACC, "acc")
    data = report.to_dict()
    assert data["schema"] == SCHEMA and data["stretches"]["how"].startswith("the whole recording")
    assert len(data["gyro_random_walk_rad_s2_sqrt_hz"]) == 3 and len(data["acc_random_walk_m_s3_sqrt_hz_std"]) == 3


@pytest.fixture(scope="module")
def short_still(tmp_path_factory):
    """A 10 min still recording written as a session file (its rests: the whole of it)."""
    path = tmp_path_factory.mktemp("noise") / "still-10min.parquet"
    write_session(still_session(600.0, seed=7), path)
    return path


def test_10_min_still_gives_the_white_noise_and_refuses_the_random_walk_saying_how_long(short_still):
    session = load_session(short_still)
    with pytest.raises(RecordingTooShort) as refused:
        session_noise(session)
    assert refused.value.exit_code == 3
    hours = float(str(refused.value).split("record at least ")[1].split(" h still")[0])
    assert 1.0 <= hours <= 24.0, str(refused.value)
    report = session_noise(session, white_only=True)
    assert report.stretches_s and report.stretches_how.startswith("the rests")   # found still from end to end
    assert sum(b - a for a, b in report.stretches_s) > 590.0
    for name, truth in (("gyro", GYRO), ("acc", ACC)):
        for axis, r in enumerate(report.sensors[name]):
            assert r.random_walk is None and r.bias_instability is None
            assert abs(r.white - truth["white"][axis]) <= 3.0 * r.white_std, (name, axis, r.white, r.white_std)


def test_the_command_refuses_a_short_recording_with_exit_3_and_writes_nothing(short_still, tmp_path, run_magyro,
                                                                                assert_plain_failure):
    out = tmp_path / "noise.json"
    message = assert_plain_failure(run_magyro("noise", short_still, "-o", out), 3)
    assert "h still" in message and "--white-only" in message
    assert not out.exists()


def test_the_command_writes_a_noise_file_its_reader_reads_and_solve_takes(short_still, tmp_path, run_magyro):
    pytest.importorskip("matplotlib")
    out, figure = tmp_path / "noise.json", tmp_path / "allan.png"
    done = run_magyro("noise", short_still, "-o", out, "--plot", figure, "--white-only", "-q")
    assert done.returncode == 0, done.stderr
    assert figure.read_bytes().startswith(b"\x89PNG")
    noise = read_noise(out)
    assert noise["rate_hz"] == pytest.approx(RATE_HZ, rel=1e-6)
    assert noise["gyro_random_walk_rad_s2_sqrt_hz"] is None
    rms = math.sqrt(np.mean(np.square(GYRO["white"])))
    assert gyro_noise_deg_s_sqrt_hz_option(out, None) == pytest.approx(math.degrees(rms), rel=0.02)
    with pytest.raises(InputError, match="--gyro-noise"):
        gyro_noise_deg_s_sqrt_hz_option(out, 0.01)


def written(tmp_path, data: dict, name: str = "noise.json"):
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def complete_noise(**changed) -> dict:
    data = {"schema": SCHEMA, "rate_hz": 200.0, "duration_s": 7200.0, "still_s": 7200.0,
            "stretches": {"how": "the whole recording (--still)", "segments_s": [[0.0, 7200.0]]},
            "gyro_white_rad_s_sqrt_hz": [1e-4, 2e-4, 1.5e-4], "gyro_random_walk_rad_s2_sqrt_hz": [1e-6, 3e-6, 2e-6],
            "acc_white_m_s2_sqrt_hz": [2e-3, 1e-3, 1.5e-3], "acc_random_walk_m_s3_sqrt_hz": [4e-5, 2e-5, 3e-5]}
    data.update(changed)
    return data


@pytest.mark.parametrize("change, words", [
    ({"schema": "magyro.calibration/1"}, "not a magyro noise file"),
    ({"gyro_white_deg_s": [1, 2, 3]}, "unknown key"),
    ({"gyro_white_rad_s_sqrt_hz": [1e-4, -1e-4, 1e-4]}, "three positive numbers"),
    ({"rate_hz": 0}, "rate_hz"),
])
def test_the_reader_refuses_what_it_does_not_know(tmp_path, change, words):
    with pytest.raises(InputError, match=words):
        read_noise(written(tmp_path, complete_noise(**change)))


def calibration_file(tmp_path):
    import magyro
    from magyro import so3

    cal = magyro.Calibration.from_parameters(
        K_g=[[1.002, 0.0012, -0.0005], [0.0, 0.9981, 0.0007], [0.0, 0.0, 1.0011]], bias_rad_s=[0.01, -0.02, 0.005],
        C_b_m=so3.euler_to_dcm([0.7, -0.4, 1.3]), R=[[0.0222, 0.0003, -0.0002], [0.0, 0.0224, 0.0001], [0.0, 0.0, 0.0221]],
        h=[3.5, -12.25, 40.125], mag_unit="uT", field_i=[0.3, 0.0, -0.95])
    path = tmp_path / "calib.json"
    cal.to_json(path)
    return path


def test_the_kalibr_export_with_noise_has_every_key_kalibrs_reader_reads(tmp_path, run_magyro):
    yaml = pytest.importorskip("yaml")
    out = tmp_path / "imu.yaml"
    done = run_magyro("export", calibration_file(tmp_path), "--format", "kalibr", "--noise",
                      written(tmp_path, complete_noise()), "--rostopic", "/imu/data", "-o", out)
    assert done.returncode == 0, done.stderr
    text = out.read_text()
    assert "add yours" not in text
    loaded = yaml.safe_load(text)
    # Kalibr's ImuParameters (kalibr_common/ConfigReader.py) reads these from the --imu file's top level; its
    # results-imu.yaml holds them under imu0
    for block in (loaded, loaded["imu0"]):
        assert KALIBR_KEYS <= set(block), KALIBR_KEYS - set(block)
        assert block["rostopic"] == "/imu/data"
        assert block["update_rate"] == pytest.approx(200.0)
        # one number per sensor, the largest axis, in Kalibr's units (the file's are the same: rad/s/sqrt(Hz),
        # rad/s^2/sqrt(Hz), m/s^2/sqrt(Hz), m/s^3/sqrt(Hz))
        assert block["gyroscope_noise_density"] == pytest.approx(2e-4, rel=1e-12)
        assert block["gyroscope_random_walk"] == pytest.approx(3e-6, rel=1e-12)
        assert block["accelerometer_noise_density"] == pytest.approx(2e-3, rel=1e-12)
        assert block["accelerometer_random_walk"] == pytest.approx(4e-5, rel=1e-12)
    assert loaded["imu0"]["model"] == "scale-misalignment" and "gyroscopes" in loaded["imu0"]


def test_the_kalibr_export_refuses_a_noise_file_without_random_walk(tmp_path):
    noise = written(tmp_path, complete_noise(gyro_random_walk_rad_s2_sqrt_hz=None))
    with pytest.raises(InputError, match="gyro_random_walk_rad_s2_sqrt_hz"):
        kalibr_export_file(calibration_file(tmp_path), noise)
    with pytest.raises(InputError, match="--format kalibr"):
        kalibr_export_file(calibration_file(tmp_path), noise, fmt="px4")


def test_without_allantools_the_command_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "allantools", None)
    with pytest.raises(InputError, match=r"magyro\[noise\]"):
        require_allantools()


# --------------------------------------------------------------------------- BROAD's rests


def longest_rest_white(session, segment):
    curve = allan_curve(samples_within(session.t_gyro_s, session.gyro_rad_s, [segment]), session.gyro_rate_hz)
    return [read_axis(curve, axis) for axis in range(3)]


@pytest.fixture(scope="module")
def broad02_rest():
    from magyro.front.rests import find_rests

    session = load_session(SHIPPED_BROAD_02)
    found = find_rests(session)
    return session, found, max(found.segments_s, key=lambda ab: ab[1] - ab[0])


def test_broad_02_rest_white_noise_agrees_with_the_spectrum_below_5_hz(broad02_rest):
    """The white noise read on the -1/2 line (0.1-0.4 s on BROAD's 3.4 s rest) against an independent reading of
    the same rest's low-frequency density: Welch's one-sided PSD over 0 < f <= 5 Hz, as a two-sided density."""
    from scipy.signal import welch

    session, _, segment = broad02_rest
    readings = longest_rest_white(session, segment)
    still = samples_within(session.t_gyro_s, session.gyro_rad_s, [segment])[0]
    f, psd = welch(still, fs=session.gyro_rate_hz, nperseg=256, axis=0)
    low = (f > 0) & (f <= 5.0)
    welch_density = np.sqrt(psd[low].mean(axis=0) / 2.0)
    for axis, r in enumerate(readings):
        assert abs(r.white - welch_density[axis]) <= 3.0 * r.white_std, (axis, r.white, welch_density[axis], r.white_std)


@pytest.mark.xfail(strict=True, reason="solve's gyro density on BROAD-02's 3.4 s rest (magyro.front.noise.effective_std: "
                   "per-sample std x sqrt(integrated autocorrelation time), 4.76e-4 rad/s/sqrt(Hz)) is 3.1x the Allan "
                   "white noise of the same rest (1.55e-4) and 3.7x Welch's density below 5 Hz (1.28e-4): the "
                   "autocorrelation of the rest's 24 Hz oscillation is summed over its positive lobe only (cut at "
                   "0.05), which a periodic component inflates; strict: this fails once the two agree")
def test_broad_02_rest_white_noise_is_within_10_percent_of_what_solve_uses(broad02_rest):
    from magyro.front.noise import noise_levels
    from magyro.options import Options

    session, found, segment = broad02_rest
    solve_density = noise_levels(session, Options(), found).gyro_density_rad_s_sqrt_hz   # what solve weights with
    white = math.sqrt(np.mean([r.white**2 for r in longest_rest_white(session, segment)]))
    assert abs(white - solve_density) <= 0.10 * solve_density, (white, solve_density)
