"""The noise file (schema magyro.noise/1, written by `magyro noise`, magyro.noise_allan) read back, and what `magyro
solve --noise` and `magyro export --format kalibr --noise` take from it.

`read_noise` refuses another schema, an unknown key or a number that is not three positive finite ones (exit 2),
as magyro.result.calibration's reader does.
"""
from __future__ import annotations

import json
import math

import numpy as np

from magyro.errors import InputError
from magyro.noise_allan import SCHEMA, SENSORS

KEYS = {"schema", "rate_hz", "duration_s", "still_s", "stretches"}
for _name, (_unit, _walk) in SENSORS.items():
    for _key in (f"{_name}_white_{_unit}_sqrt_hz", f"{_name}_bias_instability_{_unit}",
                 f"{_name}_random_walk_{_walk}_sqrt_hz"):
        KEYS |= {_key, _key + "_std"}
    KEYS |= {f"{_name}_minimum_tau_s", f"{_name}_longest_tau_s"}


def _positive_triple(data: dict, key: str, where: str):
    value = data.get(key)
    if value is None:
        return None
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
                       for v in value)):
        raise InputError(f"{where}{key} must be three positive numbers")
    return [float(v) for v in value]


def read_noise(source) -> dict:
    """A noise file's numbers (a path or its text); InputError for anything this version did not write."""
    from magyro.result.json_input import read_json_object

    data = read_json_object(source, what="noise file")
    where = "" if str(source).lstrip().startswith("{") else f"{source}: "
    if data.get("schema") != SCHEMA:
        raise InputError(f"{where}not a magyro noise file (schema {json.dumps(data.get('schema'))}, expected "
                         f"'{SCHEMA}': magyro noise -o writes one)")
    unknown = sorted(set(data) - KEYS)
    if unknown:
        raise InputError(f"{where}unknown key(s) {', '.join(unknown)} in a {SCHEMA} file")
    rate = data.get("rate_hz")
    if not isinstance(rate, (int, float)) or isinstance(rate, bool) or not math.isfinite(rate) or rate <= 0:
        raise InputError(f"{where}rate_hz must be a positive number")
    out = {"rate_hz": float(rate)}
    for key in KEYS - {"schema", "rate_hz", "duration_s", "still_s", "stretches"}:
        if key.endswith("_tau_s"):
            continue
        out[key] = _positive_triple(data, key, where)
    if out["gyro_white_rad_s_sqrt_hz"] is None:
        raise InputError(f"{where}has no gyro_white_rad_s_sqrt_hz")
    return out


def gyro_density_rad_s_sqrt_hz(noise: dict) -> float:
    """One gyro white noise density for `magyro solve` (Options.gyro_noise_density_rad_s_sqrt_hz): the RMS of the
    three axes', as the solve's own estimate is."""
    return float(np.sqrt(np.mean(np.square(noise["gyro_white_rad_s_sqrt_hz"]))))


def options_values(noise_path) -> dict:
    """The Options values a noise file gives `magyro solve --noise`."""
    return {"gyro_noise_density_rad_s_sqrt_hz": gyro_density_rad_s_sqrt_hz(read_noise(noise_path))}


def gyro_noise_deg_s_sqrt_hz_option(noise_path, gyro_noise_deg_s_sqrt_hz: float | None) -> float:
    """What `magyro solve --noise FILE` passes as --gyro-noise (deg/s/sqrt(Hz), Options.in_user_units' unit);
    InputError when --gyro-noise is given too."""
    if gyro_noise_deg_s_sqrt_hz is not None:
        raise InputError("--noise and --gyro-noise both give the gyro noise: pass one")
    return math.degrees(options_values(noise_path)["gyro_noise_density_rad_s_sqrt_hz"])


def kalibr_values(noise_path) -> dict:
    """Kalibr's noise keys (the largest axis: Kalibr takes one number per sensor) and update_rate; InputError when
    the file lacks one (Kalibr refuses a random walk that is not > 0)."""
    noise = read_noise(noise_path)
    wanted = {"gyroscope_noise_density": "gyro_white_rad_s_sqrt_hz",
              "gyroscope_random_walk": "gyro_random_walk_rad_s2_sqrt_hz",
              "accelerometer_noise_density": "acc_white_m_s2_sqrt_hz",
              "accelerometer_random_walk": "acc_random_walk_m_s3_sqrt_hz"}
    missing = [key for key in wanted.values() if noise[key] is None]
    if missing:
        raise InputError(f"{noise_path}: has no {', '.join(missing)}, which Kalibr needs (a recording too short for "
                         "the random walk, or without an accelerometer: magyro noise on a still recording of 2 h)")
    out = {kalibr: max(noise[key]) for kalibr, key in wanted.items()}
    out["update_rate"] = noise["rate_hz"]
    return out


def kalibr_export_file(calibration_path, noise_path, rostopic: str | None = None, output=None,
                       fmt: str = "kalibr") -> str:
    """`magyro export CALIB --format kalibr --noise NOISE [--rostopic T]`: Kalibr's imu.yaml with its noise keys,
    written whole to `output` when given; the text."""
    from magyro.io import check_outputs, write_text_atomically
    from magyro.result.calibration import Calibration
    from magyro.result.export_tools import kalibr_text

    if fmt != "kalibr":
        raise InputError("--noise and --rostopic are for --format kalibr")
    if noise_path is None:
        raise InputError("--rostopic needs --noise: Kalibr's imu.yaml needs the noise with its topic")
    check_outputs([calibration_path, noise_path], [output])
    if rostopic is not None and not rostopic.strip():
        raise InputError("--rostopic must name a topic, e.g. /imu0")
    noise = kalibr_values(noise_path)
    text = kalibr_text(Calibration.from_json(calibration_path), source=str(calibration_path), noise=noise,
                       rostopic=rostopic)
    if output is not None:
        write_text_atomically(output, text)
    return text
