"""Judge a calibration by dead reckoning against the optical truth of a real recording (magyro validate).

    python examples/dead_reckoning.py
"""
from pathlib import Path

import magyro
from magyro.studies.dead_reckoning import validate

session = magyro.load_session(Path(__file__).resolve().parent.parent / "data" / "broad-02.parquet")
report = validate(session, magyro.calibrate(session))
print(report.table())
