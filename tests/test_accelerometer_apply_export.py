"""The accelerometer where a calibration is used (issue 26): `magyro apply` and `magyro export`.

On a real calibration: the shipped BROAD trial 02 solved with the accelerometer in the least squares, once per run
(conftest's broad02_acc_solved). Without an accelerometer every output is what it was before the accelerometer
joined them: the same calibration with its accelerometer dropped writes no accelerometer anywhere, and a fixed
calibration's four export texts keep every word and number they had then (tests/exports/, numbers within what
their format stores).
"""
from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import magyro
from magyro.api import apply_file, export_file
from magyro.errors import InputError
from magyro.front.rests import find_rests
from magyro.io import load_session, write_session
from magyro.result.export import export_text
from test_apply_export import read_params, read_simple_yaml

DATA = Path(__file__).resolve().parents[1] / "data"
BROAD_02 = DATA / "broad-02.parquet"
G = 9.80665


@pytest.fixture(scope="module")
def solved(tmp_path_factory, broad02_acc_solved):
    """(folder, session, calibration read back from its JSON, the JSON's path)."""
    folder = tmp_path_factory.mktemp("acc-out")
    session, cal = broad02_acc_solved
    assert cal.accelerometer is not None
    path = folder / "calib-acc.json"
    cal.to_json(path)
    return folder, session, magyro.Calibration.from_json(path), path


@pytest.fixture(scope="module")
def samples(solved):
    """(gyro rad/s, accelerometer m/s^2) rows of broad-02, 3000 of each."""
    _, session, _, _ = solved
    return session.gyro_rad_s[:3000], session.acc_m_s2[:3000]


def metadata(path) -> dict:
    return {k.decode(): v.decode() for k, v in pq.ParquetFile(path).schema_arrow.metadata.items()}


# --------------------------------------------------------------------------- apply


def test_apply_writes_the_calibrated_specific_force_in_the_rates_frame(solved):
    folder, session, cal, cal_path = solved
    for frame in ("b", "m"):
        out = folder / f"applied-{frame}.parquet"
        apply_file(BROAD_02, cal_path, out, frame=frame)
        corrected = load_session(out)
        rates, field = cal.apply(session.gyro_rad_s, session.mag, frame=frame)
        np.testing.assert_array_equal(corrected.gyro_rad_s, rates)
        np.testing.assert_array_equal(corrected.mag, field)
        np.testing.assert_array_equal(corrected.t_acc_s, session.t_acc_s)
        f = cal.apply_accelerometer(session.acc_m_s2, frame=frame)
        np.testing.assert_array_equal(corrected.acc_m_s2, f)
        f_b = cal.accelerometer.apply(session.acc_m_s2, frame="b")        # C_b_a^T (K_a y + eps_a)
        np.testing.assert_allclose(f, f_b if frame == "b" else f_b @ cal.C_b_m.T, rtol=0, atol=1e-12)
        meta = metadata(out)
        assert meta["calibration_frame"] == frame and meta["calibrated_accelerometer"] == "true"
        assert ("acc = C_b_a^T (K_a y_a + eps_a) (m/s^2, gyro frame b)" if frame == "b" else
                "acc = C_b_m C_b_a^T (K_a y_a + eps_a) (m/s^2, magnetometer frame m)") in meta["calibrated_model"]


def test_the_applied_specific_force_is_gravity_at_the_rests_of_broad_02(solved):
    """At the two rests of the real trial |f| is g (9.80665) within 0.5 %, and nearer to it than the raw |y_a|."""
    folder, session, cal, cal_path = solved
    out = folder / "applied-rests.parquet"
    corrected = apply_file(BROAD_02, cal_path, out)
    rests = find_rests(session)
    assert len(rests.segments_s) == 2
    for t0, t1 in rests.segments_s:
        at = (session.t_acc_s >= t0) & (session.t_acc_s <= t1)
        assert at.sum() > 500
        calibrated = np.linalg.norm(corrected.acc_m_s2[at].mean(axis=0))
        raw = np.linalg.norm(session.acc_m_s2[at].mean(axis=0))
        assert abs(calibrated / G - 1.0) < 0.005, (t0, t1, calibrated)
        assert abs(calibrated - G) < abs(raw - G), (calibrated, raw)
        per_sample = np.linalg.norm(corrected.acc_m_s2[at], axis=1)
        assert abs(np.median(per_sample) / G - 1.0) < 0.005


def test_apply_says_nothing_changes_for_a_session_without_accelerometer(solved, run_magyro):
    folder, session, cal, cal_path = solved
    bare = folder / "no-acc.parquet"
    write_session(dataclasses.replace(session, t_acc_s=None, acc_m_s2=None), bare)
    out = folder / "no-acc-applied.parquet"
    corrected = apply_file(bare, cal_path, out)
    assert corrected.acc_m_s2 is None and load_session(out).acc_m_s2 is None
    meta = metadata(out)
    assert meta["calibrated_accelerometer"] == "false"
    assert "the session has no accelerometer columns" in meta["calibrated_model"]
    cli_out = folder / "no-acc-cli.parquet"
    result = run_magyro("apply", bare, cal_path, "-o", cli_out)
    assert result.returncode == 0, result.stderr
    assert "the session has no accelerometer columns: the calibration's accelerometer is not applied" in result.stdout
    with_acc = run_magyro("apply", BROAD_02, cal_path, "-o", folder / "cli-acc.parquet", "--frame", "m")
    assert with_acc.returncode == 0, with_acc.stderr
    assert (f"{len(session.t_acc_s)} accelerometer samples as the calibrated specific force in m/s^2 (frame m)"
            in with_acc.stdout)


def test_apply_without_an_accelerometer_in_the_calibration_keeps_the_raw_accelerometer(solved):
    folder, session, cal, _ = solved
    plain = folder / "plain.json"
    dataclasses.replace(cal, accelerometer=None).to_json(plain)
    out = folder / "plain-applied.parquet"
    apply_file(BROAD_02, plain, out)
    np.testing.assert_array_equal(load_session(out).acc_m_s2, session.acc_m_s2)
    meta = metadata(out)
    assert "calibrated_accelerometer" not in meta
    assert meta["calibrated_model"] == "gyro = K_g y + eps_b (rad/s, gyro frame b); mag = R (y_m - h) (unit norm)"
    with pytest.raises(InputError, match="has no accelerometer"):
        magyro.Calibration.from_json(plain).apply_accelerometer(session.acc_m_s2)


def test_apply_refuses_a_singular_accelerometer_before_any_work(solved):
    folder, _, cal, _ = solved
    bad = folder / "singular-acc.json"
    acc = dataclasses.replace(cal.accelerometer, K_a=np.diag([1.0, 1.0, 1e-14]))
    dataclasses.replace(cal, accelerometer=acc).to_json(bad)
    with pytest.raises(InputError, match="accelerometer K_a is singular"):
        apply_file(BROAD_02, bad, folder / "never.parquet")
    assert not (folder / "never.parquet").exists()
    with pytest.raises(InputError, match="accelerometer K_a is singular"):
        export_file(bad, "yaml")


# --------------------------------------------------------------------------- export: yaml and C


def test_yaml_export_holds_the_accelerometer_to_the_same_double(solved, samples):
    folder, _, cal, cal_path = solved
    text = export_file(cal_path, "yaml", folder / "calib-acc.yaml")
    assert "# accelerometer:  f_a = K_a y_a + eps_a" in text and "f_b = C_b_a^T f_a" in text
    data = read_simple_yaml(text)
    block, acc = data["accelerometer"], cal.accelerometer
    np.testing.assert_array_equal(np.array(block["K_a"]), acc.K_a)
    np.testing.assert_array_equal(np.array(block["bias_m_s2"]), acc.bias_m_s2)
    np.testing.assert_array_equal(np.array(block["C_b_a"]), acc.C_b_a)
    assert block["g_m_s2"] == acc.g_m_s2 == G
    _, y_a = samples
    f_a = y_a @ np.array(block["K_a"]).T + np.array(block["bias_m_s2"])
    np.testing.assert_allclose(f_a, acc.apply(y_a), rtol=0, atol=1e-12)
    np.testing.assert_allclose(f_a @ np.array(block["C_b_a"]), acc.apply(y_a, frame="b"), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.array(data["gyro"]["K_g"]), cal.K_g)      # the rest is still there


C_PROGRAM = r"""
#include <stdio.h>
#include "calib.h"

int main(void)
{
    double y[3], y_a[3], w[3], f_a[3], f_b[3], f_m[3];
    while (scanf("%lf %lf %lf %lf %lf %lf", &y[0], &y[1], &y[2], &y_a[0], &y_a[1], &y_a[2]) == 6) {
        magyro_apply_gyro(y, w);
        magyro_apply_acc(y_a, f_a);
        magyro_apply_acc_b(y_a, f_b);
        magyro_apply_acc_m(y_a, f_m);
        printf("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
               w[0], w[1], w[2], f_a[0], f_a[1], f_a[2], f_b[0], f_b[1], f_b[2], f_m[0], f_m[1], f_m[2],
               magyro_g_m_s2);
    }
    return 0;
}
"""


def test_c_header_compiled_and_run_gives_accelerometer_calibration_apply(solved, samples):
    compiler = shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler (`cc`) on PATH: the exported C header cannot be compiled here")
    folder, _, cal, cal_path = solved
    build_dir = folder / "c-acc"
    build_dir.mkdir()
    text = export_file(cal_path, "c", build_dir / "calib.h")
    for name in ("magyro_K_a[3][3]", "magyro_bias_m_s2[3]", "magyro_C_b_a[3][3]", "magyro_g_m_s2"):
        assert f"static const double {name}" in text
    (build_dir / "apply.c").write_text(C_PROGRAM)
    build = subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2",
                            "-o", str(build_dir / "apply"), str(build_dir / "apply.c")], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    gyro, y_a = samples
    stdin = "\n".join(" ".join(f"{v:.17g}" for v in row) for row in np.hstack([gyro, y_a])) + "\n"
    run = subprocess.run([str(build_dir / "apply")], input=stdin, capture_output=True, text=True, timeout=30)
    assert run.returncode == 0, run.stderr
    out = np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])
    assert out.shape == (len(y_a), 13)
    np.testing.assert_allclose(out[:, 0:3], cal.apply(gyro)[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[:, 3:6], cal.accelerometer.apply(y_a, frame="a"), rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[:, 6:9], cal.apply_accelerometer(y_a, frame="b"), rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[:, 9:12], cal.apply_accelerometer(y_a, frame="m"), rtol=0, atol=1e-9)
    assert np.all(out[:, 12] == G)


# --------------------------------------------------------------------------- export: Kalibr and PX4


def test_kalibr_accelerometers_block_inverted_as_kalibr_does_gives_calibration_apply(solved, samples):
    """Kalibr: y_a = M_accel f_i + b_accel and y = M C_gyro_i w_i + A C_gyro_i f_i + b, one frame i for both."""
    folder, _, cal, cal_path = solved
    imu = read_simple_yaml(export_file(cal_path, "kalibr", folder / "imu-acc.yaml"))["imu0"]
    assert imu["model"] == "scale-misalignment"
    M_a, b_a = np.array(imu["accelerometers"]["M"]), np.array(imu["accelerometers"]["b"])
    M, A = np.array(imu["gyroscopes"]["M"]), np.array(imu["gyroscopes"]["A"])
    C, b = np.array(imu["gyroscopes"]["C_gyro_i"]), np.array(imu["gyroscopes"]["b"])
    i_to_b = np.array(imu["magyro"]["i_to_b"])
    for L in (M_a, M):
        assert np.all(np.triu(L, 1) == 0) and np.all(np.diag(L) > 0)          # Kalibr's lower-triangular M
    for rotation in (C, i_to_b):
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), rtol=0, atol=1e-12)
        assert abs(np.linalg.det(rotation) - 1.0) < 1e-12
    assert np.all(A == 0) and imu["magyro"]["g_m_s2"] == G
    gyro, y_a = samples
    f_i = np.linalg.solve(M_a, (y_a - b_a).T).T
    f_b = cal.apply_accelerometer(y_a, frame="b")
    np.testing.assert_allclose(f_i @ i_to_b.T, f_b, rtol=0, atol=1e-9)
    np.testing.assert_allclose((f_b @ i_to_b) @ M_a.T + b_a, y_a, rtol=0, atol=1e-9)    # Kalibr's forward model
    w_i = np.linalg.solve(M, (gyro - b - (f_i @ C.T) @ A.T).T).T @ C                  # C^T M^-1 (y - b - A C f)
    np.testing.assert_allclose(w_i @ i_to_b.T, cal.apply(gyro)[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose((w_i @ i_to_b.T) @ np.array(imu["magyro"]["C_b_m"]).T,
                               cal.apply(gyro, frame="m")[0], rtol=0, atol=1e-9)


def test_px4_accelerometer_offsets_and_scales_and_their_stated_cost_at_1_g(solved, samples):
    from magyro.result.export_tools import px4_accelerometer

    folder, session, cal, cal_path = solved
    text = export_file(cal_path, "px4", folder / "calib-acc.params")
    params = read_params(text)
    acc = cal.accelerometer
    off = np.array([params[f"CAL_ACC0_{ax}OFF"] for ax in "XYZ"])
    scale = np.array([params[f"CAL_ACC0_{ax}SCALE"] for ax in "XYZ"])
    np.testing.assert_array_equal(scale, np.diag(acc.K_a))
    np.testing.assert_allclose(acc.apply(off[None, :])[0], 0.0, rtol=0, atol=1e-12)   # the reading at zero force
    _, y_a = samples
    px4 = (y_a - off) * scale                   # PX4 Accelerometer::Correct, rotation none, no thermal offset
    f_a = acc.apply(y_a)
    D = np.diag(np.diag(acc.K_a))
    # what PX4 cannot hold: its error is linear in the true force, (diag(K_a) K_a^-1 - I) f_a
    np.testing.assert_allclose(px4 - f_a, f_a @ (D @ np.linalg.inv(acc.K_a) - np.eye(3)).T, rtol=0, atol=1e-12)
    cost = px4_accelerometer(cal)
    assert f"{cost['worst_m_s2']:.4f} m/s^2 ({100 * cost['worst_m_s2'] / G:.2f} % of g" in text
    assert f"{cost['nonorth_worst_m_s2']:.4f} m/s^2 at most from the non-orthogonality alone" in text
    assert "cannot hold K_a's non-orthogonality" in text and "CAL_ACC0_ID" in text
    # the stated worst: gravity along worst_axis in frame b, read by PX4 as if frame a were b
    for axis, stated in [*zip(np.eye(3), cost["per_axis_m_s2"]), (cost["worst_axis"], cost["worst_m_s2"])]:
        f_b = G * axis
        y = np.linalg.solve(acc.K_a, acc.C_b_a @ f_b - acc.bias_m_s2)        # the reading of that force
        np.testing.assert_allclose(cal.apply_accelerometer(y[None, :])[0], f_b, rtol=0, atol=1e-12)
        assert abs(np.linalg.norm((y - off) * scale - f_b) - stated) < 1e-12
    assert cost["worst_m_s2"] >= np.max(cost["per_axis_m_s2"]) - 1e-12
    # on the real rests PX4's reading is off by no more than the stated worst
    rests = find_rests(session)
    for t0, t1 in rests.segments_s:
        at = (session.t_acc_s >= t0) & (session.t_acc_s <= t1)
        y_rest = session.acc_m_s2[at].mean(axis=0)
        error = np.linalg.norm((y_rest - off) * scale - cal.apply_accelerometer(y_rest[None, :])[0])
        assert error <= cost["worst_m_s2"] * np.linalg.norm(cal.apply_accelerometer(y_rest[None, :])[0]) / G + 1e-12


# --------------------------------------------------------------------------- without an accelerometer


def test_exports_without_an_accelerometer_name_none(solved):
    folder, _, cal, _ = solved
    plain = dataclasses.replace(cal, accelerometer=None)
    for fmt in ("yaml", "c", "kalibr", "px4"):
        text = export_text(plain, fmt, source="plain.json")
        for word in ("K_a", "C_b_a", "CAL_ACC0", "accelerometers:", "magyro_apply_acc", "i_to_b", "f_a"):
            assert word not in text, (fmt, word)


# A fixed calibration's four exports as magyro wrote them before the accelerometer joined the exports (main at
# 5e4c795, whose texts had the SHA-256 0b21e20d.. yaml, 25bed890.. c, 60f5186d.. kalibr, 4fbc0898.. px4 under
# OpenBLAS's Haswell kernels): a calibration without an accelerometer keeps every word and every number. Not every
# bit: K = C_b_m K_g, Kalibr's LQ split and PX4's polar decomposition go through BLAS/LAPACK, whose kernels (AVX-512,
# AVX2, AVX, ...) change the last one to three of the 17 digits (OPENBLAS_CORETYPE=Sandybridge changes all four
# texts), so a number is compared within what its format stores (`same_numbers`).
EXPORTS = Path(__file__).resolve().parent / "exports"
PLAIN_EXPORTS = {"yaml": "plain.yaml", "c": "plain.h", "kalibr": "plain-kalibr.yaml", "px4": "plain-px4.params"}
# a decimal number with a point or an exponent (integers: dimensions, PX4's ids and types, are text, exact)
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+)(?![\w.])")


def close_enough(now: float, before: str, fmt: str) -> bool:
    """PX4 stores REAL32: equal when the two round to the same or neighbouring float32 (within one float32 step of
    the value). The other formats hold doubles: 12 significant digits (a calibration's std is 1e-6 to 1e-3 of its
    parameters; BLAS kernels move the 15th-17th). A number printed short (a comment's 0.7186 deg/s) within one unit
    of its last digit."""
    ref = float(before)
    mantissa = before.lstrip("+-").split("e")[0].split("E")[0]
    exponent = int(before.lower().split("e")[1]) if "e" in before.lower() else 0
    last_digit = 10.0 ** (exponent - len(mantissa.split(".")[1])) if "." in mantissa else 0.0
    if fmt == "px4":
        tolerance = max(float(np.spacing(np.float32(abs(ref)))), 1e-15)
    else:
        tolerance = max(1e-12 * abs(ref), 1e-15)
    return abs(now - ref) <= max(tolerance, last_digit)


def same_numbers(now: str, before: str, fmt: str) -> list[str]:
    """What differs between two export texts: the text around the numbers must be the same to the byte, and each
    number `close_enough`. [] when they agree."""
    if NUMBER.split(now) != NUMBER.split(before):
        words_now, words_before = NUMBER.sub("#", now).splitlines(), NUMBER.sub("#", before).splitlines()
        return [f"{fmt}: text differs: {a!r} != {b!r}" for a, b in zip(words_now, words_before) if a != b][:3] or \
            [f"{fmt}: {len(words_now)} lines instead of {len(words_before)}"]
    return [f"{fmt}: {a} instead of {b}" for a, b in zip(NUMBER.findall(now), NUMBER.findall(before))
            if not close_enough(float(a), b, fmt)]


def plain_calibration():
    from magyro import so3

    return magyro.Calibration.from_parameters(
        K_g=[[1.002, 0.0012, -0.0005], [0.0, 0.9981, 0.0007], [0.0, 0.0, 1.0011]], bias_rad_s=[0.01, -0.02, 0.005],
        C_b_m=so3.euler_to_dcm([0.7, -0.4, 1.3]),
        R=[[0.0222, 0.0003, -0.0002], [0.0, 0.0224, 0.0001], [0.0, 0.0, 0.0221]],
        h=[3.5, -12.25, 40.125], mag_unit="uT", field_i=[0.3, 0.0, -0.95])


def test_exports_without_an_accelerometer_are_as_before():
    cal = plain_calibration()
    for fmt, name in PLAIN_EXPORTS.items():
        before = (EXPORTS / name).read_text(encoding="utf-8")
        assert same_numbers(export_text(cal, fmt, source="given.json"), before, fmt) == [], fmt


def test_an_export_that_changed_is_told_from_one_that_went_through_other_kernels():
    """same_numbers accepts the 16th-17th digits another BLAS kernel gives and nothing more: a changed word, number
    of numbers, 12th digit, or a PX4 value moved by more than its float32 step is reported."""
    px4 = (EXPORTS / PLAIN_EXPORTS["px4"]).read_text(encoding="utf-8")
    yaml = (EXPORTS / PLAIN_EXPORTS["yaml"]).read_text(encoding="utf-8")
    odiag = "6.7213625027793501e-03"                   # CAL_MAG0_XODIAG under Haswell's kernels
    assert odiag in px4
    assert same_numbers(px4.replace(odiag, "6.7213625027793674e-03"), px4, "px4") == []      # Sandybridge's
    assert same_numbers(px4.replace(odiag, "6.7213627e-03"), px4, "px4") == []      # the same REAL32 (step 4.7e-10)
    assert same_numbers(px4.replace(odiag, "6.7213640e-03"), px4, "px4") != []      # 3 float32 steps off
    assert same_numbers(px4.replace("CAL_MAG0_XODIAG", "CAL_MAG0_XOFFDIAG"), px4, "px4") != []
    assert same_numbers(px4.replace("0.7186", "0.7187"), px4, "px4") == []           # a comment's last digit
    assert same_numbers(px4.replace("0.7186", "0.7188"), px4, "px4") != []
    assert same_numbers(px4.replace("\t9\n", "\t6\n", 1), px4, "px4") != []         # PX4's type: an integer, exact
    k = "9.9779392180497717e-01"                        # K[1][1]
    assert k in yaml
    assert same_numbers(yaml.replace(k, "9.9779392180497728e-01"), yaml, "yaml") == []     # Sandybridge's
    assert same_numbers(yaml.replace(k, "9.9779392180597717e-01"), yaml, "yaml") != []     # the 12th digit
    assert same_numbers(yaml.replace(k, k + ", 0.0"), yaml, "yaml") != []
