"""The session table's column layout (docs/spec.md section 2), and the light table a numeric Parquet file reads into.

One row per timestamp: ``t gx gy gz mx my mz``, optionally ``ax ay az`` and a truth
quaternion ``qw qx qy qz``; a row leaves NaN the sensors with no sample at that instant.
"""
from __future__ import annotations

import numpy as np

TIME_COLUMN = "t"
GYRO_COLUMNS = ("gx", "gy", "gz")
MAG_COLUMNS = ("mx", "my", "mz")
ACC_COLUMNS = ("ax", "ay", "az")
QUAT_COLUMNS = ("qw", "qx", "qy", "qz")
REQUIRED_COLUMNS = (TIME_COLUMN, *GYRO_COLUMNS, *MAG_COLUMNS)
OPTIONAL_GROUPS = (ACC_COLUMNS, QUAT_COLUMNS)
SPEC_NAMES = (*REQUIRED_COLUMNS, *ACC_COLUMNS, *QUAT_COLUMNS)
SENSOR_GROUPS = {"gyro": GYRO_COLUMNS, "magnetometer": MAG_COLUMNS, "accelerometer": ACC_COLUMNS}


class ColumnTable:
    """A table of float64 numpy columns (a numeric Parquet file), with the traits the checks use."""

    def __init__(self, columns: dict[str, np.ndarray]):
        self._columns = columns

    @property
    def columns(self) -> list[str]:
        return list(self._columns)

    def __getitem__(self, name: str) -> np.ndarray:
        return self._columns[name]

    def __len__(self) -> int:
        return len(next(iter(self._columns.values()))) if self._columns else 0
