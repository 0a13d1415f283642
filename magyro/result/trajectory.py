"""The attitude trajectory of a least-squares solve: a decision variable of the problem, given to the user.

`magyro solve --trajectory traj.parquet` writes one row per attitude node:

    t_s                          node time, on the gyro's clock (s since the session's first sample)
    q_m_i_w q_m_i_x q_m_i_y q_m_i_z
                                 unit quaternion [w, x, y, z] (Hamilton, w >= 0) of C_m_i, the rotation
                                 from the magnetometer frame m to the frame i: v_i = C_m_i v_m
    std_x_deg std_y_deg std_z_deg
                                 one-sigma of the attitude error phi about the m axes
                                 (C_m_i = C_est Exp(phi)), the calibration's own uncertainty included
    field_x field_y field_z      the calibrated field R (y_m - h) at the node's magnetometer sample
                                 (unitless, norm 1 in a homogeneous field; NaN for a node that sits on
                                 no sample: in a gap, or where held rows were dropped)

The frame i is the gauge of the problem (docs/spec.md section 1): the
magnetometer frame at the first node, so the first node is the identity with
zero std, and the std grows with time from there (the heading about the field
is known only through the integrated gyro). The gyro frame's attitude is
C_b_i = C_m_i C_b_m. The nodes cover the part of the session the solve used
(the moving part, rests trimmed, unless --keep-rests).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro import so3

SCHEMA = "magyro.trajectory/1"
QUATERNION_COLUMNS = ("q_m_i_w", "q_m_i_x", "q_m_i_y", "q_m_i_z")
STD_COLUMNS = ("std_x_deg", "std_y_deg", "std_z_deg")
FIELD_COLUMNS = ("field_x", "field_y", "field_z")


@dataclass(frozen=True)
class AttitudeTrajectory:
    """The solved attitude at the nodes, its one-sigma, and the calibrated field there."""

    t_s: np.ndarray          # (N,)
    C_m_i: np.ndarray        # (N, 3, 3): v_i = C_m_i v_m
    std_rad: np.ndarray      # (N, 3): one-sigma of phi about the m axes, C_m_i = C_est Exp(phi)
    field_m: np.ndarray      # (N, 3): calibrated field at the node's magnetometer sample, NaN off a sample

    @property
    def q_m_i_wxyz(self) -> np.ndarray:
        return so3.dcm_to_quat(self.C_m_i)

    @property
    def std_deg(self) -> np.ndarray:
        return np.rad2deg(self.std_rad)

    def columns(self) -> dict[str, np.ndarray]:
        """The table's columns, in order."""
        q, s = self.q_m_i_wxyz, self.std_deg
        return {"t_s": self.t_s, **{c: q[:, k] for k, c in enumerate(QUATERNION_COLUMNS)},
                **{c: s[:, k] for k, c in enumerate(STD_COLUMNS)},
                **{c: self.field_m[:, k] for k, c in enumerate(FIELD_COLUMNS)}}

    def write_parquet(self, path, source: str = "") -> None:
        """The table as Parquet, written whole or not at all, with its schema and frames in the metadata."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        from magyro.io import write_atomically

        metadata = {"schema": SCHEMA, "source": source,
                    "frames": "q_m_i rotates the magnetometer frame m into i (v_i = C_m_i v_m); i is the m frame at the "
                              "first node; gyro frame: C_b_i = C_m_i C_b_m",
                    "units": "t_s s; std_*_deg deg about the m axes (right perturbation); field_* unitless (norm 1)"}
        table = pa.table({k: pa.array(v, pa.float64()) for k, v in self.columns().items()})
        table = table.replace_schema_metadata({k.encode(): v.encode() for k, v in metadata.items()})
        write_atomically(path, lambda tmp: pq.write_table(table, tmp))
