"""`magyro apply` and `magyro export` (issue 12): the calibration applied to a session, and exported.

Solved once per module on the shipped BROAD trial 02; the corrected session must dead-reckon
exactly as `validate` does with the calibration.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import magyro
from magyro.api import apply_file
from magyro.errors import InputError
from magyro.io import load_session
from magyro.studies.dead_reckoning import validate

DATA = Path(__file__).resolve().parents[1] / "data"
BROAD_02 = DATA / "broad-02.parquet"
TRUTH_FILE = DATA / "simulated-phone-module.truth.json"


def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def solved(tmp_path_factory, broad02_solved):
    """(folder, session, calibration, calibration path): broad-02 calibrated once (conftest's broad02_solved)."""
    folder = tmp_path_factory.mktemp("apply")
    session, cal = broad02_solved
    path = folder / "calib.json"
    cal.to_json(path)
    return folder, session, magyro.Calibration.from_json(path), path


@pytest.fixture(scope="module")
def applied(solved):
    """The corrected session written by apply_file (frame b), and its path."""
    folder, _, _, cal_path = solved
    out = folder / "corrected.parquet"
    before = sha256(BROAD_02), sha256(cal_path)
    apply_file(BROAD_02, cal_path, out)
    assert (sha256(BROAD_02), sha256(cal_path)) == before   # the inputs are never changed
    return out


def test_applied_gyro_and_field_equal_calibration_apply(solved, applied):
    _, session, cal, cal_path = solved
    corrected = load_session(applied)
    rates, field = cal.apply(session.gyro_rad_s, session.mag)
    np.testing.assert_array_equal(corrected.t_gyro_s, session.t_gyro_s)
    np.testing.assert_array_equal(corrected.t_mag_s, session.t_mag_s)
    np.testing.assert_array_equal(corrected.gyro_rad_s, rates)
    np.testing.assert_array_equal(corrected.mag, field)
    np.testing.assert_array_equal(corrected.t_quat_s, session.t_quat_s)   # truth kept for validation
    assert abs(np.median(np.linalg.norm(corrected.mag, axis=1)) - 1.0) < 0.05
    meta = {k.decode(): v.decode() for k, v in pq.ParquetFile(applied).schema_arrow.metadata.items()}
    assert meta["calibrated"] == "true"
    assert meta["calibration"] == str(cal_path)
    assert meta["calibration_frame"] == "b"
    assert meta["gyro_unit"] == "rad/s" and meta["mag_unit"] == "unitless"


def test_frame_m_gives_the_magnetometer_frame_rates(solved):
    folder, session, cal, cal_path = solved
    out = folder / "corrected-m.parquet"
    corrected = apply_file(BROAD_02, cal_path, out, frame="m")
    np.testing.assert_array_equal(load_session(out).gyro_rad_s, cal.apply(session.gyro_rad_s, frame="m")[0])
    assert corrected.metadata["calibration_frame"] == "m"


def test_dead_reckoning_the_applied_session_equals_validate(solved, applied):
    """The issue's target: apply, then dead-reckon with no calibration == validate's calibrated, to 1e-9."""
    _, session, cal, _ = solved
    after = validate(load_session(applied), None)
    direct = validate(session, cal)
    assert after.mode == direct.mode == "truth"
    np.testing.assert_array_equal(after.t_s, direct.t_s)
    np.testing.assert_allclose(after.error_deg["raw"], direct.error_deg["calibrated"], rtol=0, atol=1e-9)
    for key, value in direct.summary["calibrated"].items():
        assert abs(after.summary["raw"][key] - value) <= 1e-9, key


def test_apply_refuses_a_wrong_frame_an_output_that_is_the_input_and_a_calibrated_session(solved, applied):
    folder, _, _, cal_path = solved
    with pytest.raises(InputError, match="unknown frame"):
        apply_file(BROAD_02, cal_path, folder / "x.parquet", frame="q")
    with pytest.raises(InputError, match="is the input"):
        apply_file(BROAD_02, cal_path, BROAD_02)
    with pytest.raises(InputError, match="already calibrated"):
        apply_file(applied, cal_path, folder / "x.parquet")
    assert not (folder / "x.parquet").exists()


def test_cli_apply_exit_0_and_exit_2_for_a_truth_file(solved, run_magyro, assert_plain_failure):
    folder, session, cal, cal_path = solved
    out = folder / "cli-corrected.parquet"
    ok = run_magyro("apply", BROAD_02, cal_path, "-o", out, "--frame", "m")
    assert ok.returncode == 0, ok.stderr
    assert "corrected session written" in ok.stdout
    np.testing.assert_array_equal(load_session(out).gyro_rad_s, cal.apply(session.gyro_rad_s, frame="m")[0])
    bad = folder / "bad.parquet"
    message = assert_plain_failure(run_magyro("apply", BROAD_02, TRUTH_FILE, "-o", bad), 2)
    assert "true parameters of a simulated session" in message and "not a calibration" in message
    assert not bad.exists()


# --------------------------------------------------------------------------- export


def read_simple_yaml(text: str) -> dict:
    """The YAML that `magyro export --format yaml` writes (PyYAML is not a dependency): comments, `key:` opening
    a mapping by indentation, `key: value` with a JSON value (flow lists of numbers, quoted strings)."""
    import json

    root: dict = {}
    stack = [(-1, root)]
    for raw in text.splitlines():
        line = raw.split(" #")[0] if not raw.lstrip().startswith("#") else ""
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        key, _, value = line.strip().partition(":")
        while stack[-1][0] >= indent:
            stack.pop()
        parent = stack[-1][1]
        if value.strip():
            parent[key] = json.loads(value)
        else:
            parent[key] = {}
            stack.append((indent, parent[key]))
    return root


def apply_export(cal_path, fmt, out):
    from magyro.api import export_file

    return export_file(cal_path, fmt, out)


@pytest.fixture(scope="module")
def samples(solved):
    """(gyro rad/s, magnetometer) rows of broad-02, 3000 of each."""
    _, session, _, _ = solved
    return session.gyro_rad_s[:3000], session.mag[:3000]


def test_yaml_export_reads_back_to_the_same_corrected_rates(solved, samples):
    folder, _, cal, cal_path = solved
    out = folder / "calib.yaml"
    text = apply_export(cal_path, "yaml", out)
    assert out.read_text() == text
    assert "w_b = K_g y + eps_b" in text and "ADDED" in text
    data = read_simple_yaml(text)
    assert data["schema"] == "magyro.calibration/1" and data["magnetometer"]["unit"] == cal.mag_unit
    gyro, mag = samples
    K_g, bias = np.array(data["gyro"]["K_g"]), np.array(data["gyro"]["bias_rad_s"])
    K, eps = np.array(data["gyro"]["K"]), np.array(data["gyro"]["eps_rad_s"])
    R, h = np.array(data["magnetometer"]["R"]), np.array(data["magnetometer"]["h"])
    np.testing.assert_array_equal(np.array(data["misalignment"]["C_b_m"]), cal.C_b_m)   # every number exact
    rates_b, field = cal.apply(gyro, mag)
    np.testing.assert_allclose(gyro @ K_g.T + bias, rates_b, rtol=0, atol=1e-12)
    np.testing.assert_allclose(gyro @ K.T + eps, cal.apply(gyro, frame="m")[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose((mag - h) @ R.T, field, rtol=0, atol=1e-12)


C_PROGRAM = r"""
#include <stdio.h>
#include "calib.h"

int main(void)
{
    double y[3], y_m[3], w[3], w_m[3], m[3];
    while (scanf("%lf %lf %lf %lf %lf %lf", &y[0], &y[1], &y[2], &y_m[0], &y_m[1], &y_m[2]) == 6) {
        magyro_apply_gyro(y, w);
        magyro_apply_gyro_m(y, w_m);
        magyro_apply_mag(y_m, m);
        printf("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
               w[0], w[1], w[2], w_m[0], w_m[1], w_m[2], m[0], m[1], m[2]);
    }
    return 0;
}
"""


def test_c_header_compiled_and_run_gives_the_same_corrected_rates(solved, samples):
    import shutil
    import subprocess

    compiler = shutil.which("cc")
    if compiler is None:
        pytest.skip("no C compiler (`cc`) on PATH: the exported C header cannot be compiled here")
    folder, _, cal, cal_path = solved
    apply_export(cal_path, "c", folder / "calib.h")
    (folder / "apply.c").write_text(C_PROGRAM)
    build = subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2",
                            "-o", str(folder / "apply"), str(folder / "apply.c")], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    gyro, mag = samples
    stdin = "\n".join(" ".join(f"{v:.17g}" for v in row) for row in np.hstack([gyro, mag])) + "\n"
    run = subprocess.run([str(folder / "apply")], input=stdin, capture_output=True, text=True, timeout=30)
    assert run.returncode == 0, run.stderr
    out = np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])
    assert out.shape == (len(gyro), 9)
    rates_b, field = cal.apply(gyro, mag)
    np.testing.assert_allclose(out[:, 0:3], rates_b, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[:, 3:6], cal.apply(gyro, frame="m")[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[:, 6:9], field, rtol=0, atol=1e-9)


def test_cli_export_prints_without_output_and_refuses_an_unknown_format(solved, run_magyro, assert_plain_failure):
    folder, _, _, cal_path = solved
    shown = run_magyro("export", cal_path, "--format", "c")
    assert shown.returncode == 0, shown.stderr
    assert "static inline void magyro_apply_gyro(const double y[3], double w[3])" in shown.stdout
    message = assert_plain_failure(run_magyro("export", cal_path, "--format", "nope", "-o", folder / "x.txt"), 2)
    assert "unknown export format" in message
    assert not (folder / "x.txt").exists()
    message = assert_plain_failure(run_magyro("export", TRUTH_FILE, "--format", "yaml"), 2)
    assert "not a calibration" in message


# --------------------------------------------------------------------------- kalibr, px4 (result/export_tools.py)


def test_kalibr_export_inverted_as_kalibr_does_gives_calibration_apply(solved, samples):
    """Kalibr: y = M C_gyro_i w_i + A (C_gyro_i a_i) + b; its consumer inverts it for w_i (frame i = magyro's b)."""
    folder, _, cal, cal_path = solved
    text = apply_export(cal_path, "kalibr", folder / "imu.yaml")
    imu = read_simple_yaml(text)["imu0"]
    assert imu["model"] == "scale-misalignment"
    M, A = np.array(imu["gyroscopes"]["M"]), np.array(imu["gyroscopes"]["A"])
    C, b = np.array(imu["gyroscopes"]["C_gyro_i"]), np.array(imu["gyroscopes"]["b"])
    assert np.all(np.triu(M, 1) == 0) and np.all(np.diag(M) > 0)          # Kalibr's lower-triangular M
    np.testing.assert_allclose(C @ C.T, np.eye(3), rtol=0, atol=1e-12)
    assert abs(np.linalg.det(C) - 1.0) < 1e-12
    assert np.all(A == 0)
    gyro, _ = samples
    a_i = np.zeros_like(gyro)                      # A = 0: any specific force gives the same rates
    w_i = np.linalg.solve(M, (gyro - b - (a_i @ C.T) @ A.T).T).T @ C          # C^T M^-1 (y - b - A C a)
    rates_b = cal.apply(gyro)[0]
    np.testing.assert_allclose(w_i, rates_b, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rates_b @ C.T @ M.T + b, gyro, rtol=0, atol=1e-9)   # Kalibr's forward model
    extra = imu["magyro"]
    np.testing.assert_array_equal(np.array(extra["C_b_m"]), cal.C_b_m)
    np.testing.assert_array_equal(np.array(extra["R"]), cal.R)
    np.testing.assert_array_equal(np.array(extra["h"]), cal.h)
    np.testing.assert_allclose(w_i @ np.array(extra["C_b_m"]).T, cal.apply(gyro, frame="m")[0], rtol=0, atol=1e-9)


def read_params(text: str) -> dict:
    """A QGroundControl .params file: '#' header lines, then vehicle id, component id, name, value, type."""
    values = {}
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        vid, cid, name, value, ptype = line.split("\t")
        assert (vid, cid, ptype) == ("1", "1", "9")               # REAL32 on vehicle 1, component 1
        values[name] = float(value)
    return values


def test_px4_gyro_offset_exact_at_rest_and_its_cost_at_360_deg_s(solved, samples):
    from magyro.result.export_tools import RAD2DEG, px4_gyro_cost

    folder, _, cal, cal_path = solved
    text = apply_export(cal_path, "px4", folder / "calib.params")
    params = read_params(text)
    off = np.array([params[f"CAL_GYRO0_{ax}OFF"] for ax in "XYZ"])
    # PX4: corrected = y - OFF. At rest magyro reads y0 with K_g y0 + eps_b = 0: there PX4 gives 0 as magyro does.
    y0 = off[None, :]
    np.testing.assert_allclose(cal.apply(y0)[0], 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(y0 - off, cal.apply(y0)[0], rtol=0, atol=1e-15)
    assert np.max(np.abs(cal.apply(off.astype(np.float32)[None, :].astype(float))[0])) < 1e-9   # PX4's REAL32
    cost = px4_gyro_cost(cal, 360.0)
    assert f"{cost['worst_deg_s']:.4f} deg/s about the worst direction" in text
    for axis, stated in [*zip(np.eye(3), cost["per_axis_deg_s"]), (cost["worst_axis"], cost["worst_deg_s"])]:
        w_true = np.deg2rad(360.0) * axis
        y = np.linalg.solve(cal.K_g, w_true - cal.bias_rad_s)[None, :]         # the reading of that true rate
        magyro_w = cal.apply(y)[0][0]
        np.testing.assert_allclose(magyro_w, w_true, rtol=0, atol=1e-12)
        assert abs(np.linalg.norm((y[0] - off) - magyro_w) * RAD2DEG - stated) < 1e-9
    assert cost["worst_deg_s"] >= np.max(cost["per_axis_deg_s"]) - 1e-12
    gyro, _ = samples       # on real samples PX4's error is (K_g^-1 - I) w, w = magyro's rate
    rates = cal.apply(gyro)[0]
    np.testing.assert_allclose((gyro - off) - rates, rates @ (np.linalg.inv(cal.K_g) - np.eye(3)).T, rtol=0, atol=1e-12)


def test_px4_magnetometer_is_calibration_apply_in_gauss_up_to_pxs_scale_and_a_stated_rotation(solved, samples):
    from magyro.result.export_tools import px4_parameters

    folder, _, cal, cal_path = solved
    assert cal.mag_unit == "uT"
    params = read_params(apply_export(cal_path, "px4", None))
    off = np.array([params[f"CAL_MAG0_{ax}OFF"] for ax in "XYZ"])
    xy, xz, yz = (params[f"CAL_MAG0_{ax}ODIAG"] for ax in "XYZ")
    S = np.diag([params[f"CAL_MAG0_{ax}SCALE"] for ax in "XYZ"]) + np.array([[0, xy, xz], [xy, 0, yz], [xz, yz, 0]])
    _, mag = samples
    px4_field = (mag / 100.0 - off) @ S.T          # PX4 Magnetometer::Correct, rotation none, no power comp.
    field = cal.apply(np.zeros((len(mag), 3)), mag)[1]
    p = px4_parameters(cal)
    k = p["mag_field_gauss"]
    assert 0.2 < k < 0.7                                              # a field strength on Earth, in gauss
    np.testing.assert_allclose(px4_field, k * field @ p["mag_rotation_U"], rtol=0, atol=1e-9)   # k U^T m
    # without U: lengths and angles are magyro's, scaled by k
    np.testing.assert_allclose(np.linalg.norm(px4_field, axis=1), k * np.linalg.norm(field, axis=1), rtol=0, atol=1e-9)
    np.testing.assert_allclose(px4_field[:50] @ px4_field[:50].T, k**2 * field[:50] @ field[:50].T, rtol=0, atol=1e-9)


def test_px4_refuses_a_magnetometer_unit_it_cannot_convert(solved, run_magyro, assert_plain_failure):
    import dataclasses

    from magyro.result.export import export_text
    from magyro.result.export_tools import px4_parameters

    folder, _, cal, _ = solved
    for unit in ("counts", "unknown"):
        with pytest.raises(InputError, match=f"magnetometer unit '{unit}' cannot be converted to gauss"):
            export_text(dataclasses.replace(cal, mag_unit=unit), "px4")
    path = folder / "counts.json"
    dataclasses.replace(cal, mag_unit="counts").to_json(path)
    message = assert_plain_failure(run_magyro("export", path, "--format", "px4", "-o", folder / "c.params"), 2)
    assert "cannot be converted to gauss" in message and not (folder / "c.params").exists()
    for unit, factor in (("G", 1.0), ("mG", 1e-3), ("nT", 1e-5)):    # a unit it can convert gives the same gauss
        scaled = dataclasses.replace(cal, mag_unit=unit, h=cal.h * 1e-2 / factor, R=cal.R / (1e-2 / factor))
        np.testing.assert_allclose(px4_parameters(scaled)["mag_offset_gauss"], cal.h / 100.0, rtol=1e-12, atol=0)


def test_cli_export_kalibr_and_px4(solved, run_magyro):
    folder, _, _, cal_path = solved
    shown = run_magyro("export", cal_path, "--format", "kalibr")
    assert shown.returncode == 0, shown.stderr
    assert '  model: "scale-misalignment"' in shown.stdout and "C_gyro_i:" in shown.stdout
    out = folder / "cli.params"
    written = run_magyro("export", cal_path, "--format", "px4", "-o", out)
    assert written.returncode == 0, written.stderr
    assert "# Vehicle-Id Component-Id Name Value Type" in out.read_text()
    assert "kalibr" in run_magyro("export", "--help").stdout
