"""`--accelerometer` on real recordings other than BROAD trial 2 (benchmarks/accelerometer_real.py measures them
all; docs/accelerometer.md "On real recordings"): what a user gets on each, asserted where it is fast.

The shipped PX4 log always; the corpus of other devices' recordings (../shared/data/wild) and the BROAD trials
(../shared/data/broad) when present.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from magyro import calibrate
from magyro.errors import InputError, ObservabilityError
from magyro.options import Options
from magyro.studies.dead_reckoning import validate

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
if not SHARED.is_dir():
    SHARED = Path("/work/shared/data")


def shared(*parts: str) -> Path:
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"needs {path} (../shared/data), absent here")
    return path


def test_a_board_that_never_turned_is_refused_for_its_motion_with_the_accelerometer_too():
    """The shipped PX4 log (a board on a bench): its accelerometer saw gravity from one direction only, and the
    refusal is the motion's, the same exit 3 and cause as without --accelerometer, not one about the
    accelerometer (which the gate would reach only once the device is turned)."""
    from magyro.io import import_ulog

    session = import_ulog(ROOT / "data" / "px4-sample-appended-multiple.ulg")
    assert session.acc_m_s2 is not None
    causes = []
    for options in (Options(), Options(accelerometer=True)):
        with pytest.raises(ObservabilityError) as refused:
            calibrate(session, options)
        assert refused.value.exit_code == 3
        causes.append(str(refused.value).split(":")[0])
    assert causes[0] == causes[1] == "the device turned too little", causes


def test_an_iphone_export_without_gravity_is_told_it_has_no_accelerometer():
    """Sensor Logger on an iPhone (bennyjhui) exported Accelerometer.csv only (the acceleration without gravity):
    --accelerometer is exit 2 naming the file, before the motion's exit 3 that a solve without it gives."""
    from magyro.io import import_preset

    session = import_preset([shared("wild", "bennyjhui")], "sensor-logger")
    assert session.acc_m_s2 is None
    with pytest.raises(InputError, match="Accelerometer.csv left out, it is the phone's acceleration without grav"):
        calibrate(session, Options(accelerometer=True))


def test_a_recording_shorter_than_30_s_gets_an_answer_not_a_traceback():
    """The shipped BROAD trial 2's first 25 s (its first rest and some turning), forced: a calibration, not an
    internal error (40 s solved; shorter ended in a ValueError while the hand's size was averaged over a 30 s window
    longer than the recording, fixed in 57967c9)."""
    from magyro import load_session

    session = load_session(ROOT / "data" / "broad-02.parquet")
    short = session.within(session.t_gyro_s[0], session.t_gyro_s[0] + 25.0)
    cal = calibrate(short, Options(accelerometer=True, force=True))
    assert cal.accelerometer is not None


def test_an_android_phone_with_its_uncalibrated_accelerometer_gets_an_answer_not_a_traceback():
    """Sensor Logger on an Android phone (simorxb), uncalibrated files: 27 s turned by hand (shorter than the
    hand's 30 s window, where it was a traceback). Without the accelerometer it is exit 3 for the gyro's std; with
    it the same refusal, for the same reason."""
    from magyro.errors import ObservabilityError
    from magyro.io import import_preset

    session = import_preset([shared("wild", "simorxb")], "sensor-logger")
    assert session.acc_m_s2 is not None
    with pytest.raises(ObservabilityError, match="the calibration is too uncertain") as without:
        calibrate(session, Options(accelerometer=False))
    with pytest.raises(ObservabilityError, match="the calibration is too uncertain") as with_it:
        calibrate(session, Options(accelerometer=True))
    assert without.value.exit_code == with_it.value.exit_code == 3


@pytest.mark.slow
def test_beside_a_magnet_gravity_rescues_the_gyros_dead_reckoning():
    """BROAD trial 30 (a magnet beside the path): calibrated against the bent field alone, the gyro dead-reckons
    no better than raw against the optical truth; with gravity as a second reference (forced: the accelerometer's
    own std is past its bound, the hand is large) several times better. docs/accelerometer.md "On real
    recordings"."""
    from magyro.io import import_broad_movement

    found = sorted(shared("broad").glob("30_*.mat"))
    if not found:
        pytest.skip("BROAD trial 30 absent")
    session = import_broad_movement(found[0], 10.0)
    rms = {}
    for name, options in {"without": Options(), "with": Options(accelerometer=True, force=True)}.items():
        summary = validate(session, calibrate(session, options)).to_dict()["summary"]
        rms["raw"], rms[name] = summary["raw"]["rms_deg"], summary["calibrated"]["rms_deg"]
    assert rms["without"] > 0.8 * rms["raw"], rms
    assert rms["with"] < 0.4 * rms["without"], rms
