"""The EKF's estimates over time (the paper's Fig. 3, 6, 7): the table, its Parquet file, the figure."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magyro.errors import InputError
from magyro.text import PLOT_INSTALL
from magyro.io import write_atomically

HISTORY_ROWS = 2000             # default number of recorded instants in a batch run
AXES = "xyz"
K_NAMES = [f"K{i + 1}{j + 1}" for i in range(3) for j in range(3)]   # row-major, like the paper's Fig. 3
BIAS_NAMES = [f"bias_{a}_deg_s" for a in AXES]
FIELD_NAMES = [f"m_i_{a}" for a in AXES]
HISTORY_COLUMNS = ["t_s", *K_NAMES, *BIAS_NAMES, *FIELD_NAMES,
                   *(n + "_std" for n in K_NAMES + BIAS_NAMES + FIELD_NAMES)]


@dataclass
class EkfHistory:
    """Estimates and their 1-sigma over time (the paper's Fig. 3, 6, 7), subsampled.

    Arrays, one row per recorded instant: t_s (N,), K (N,3,3), eps_m_rad_s (N,3),
    m_i (N,3), cov_theta (N,12,12) of [vec K, eps], m_i_std (N,3).
    """

    t_s: np.ndarray
    K: np.ndarray
    eps_m_rad_s: np.ndarray
    m_i: np.ndarray
    cov_theta: np.ndarray
    m_i_std: np.ndarray

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def K_std(self) -> np.ndarray:
        """(N,3,3) one-sigma of K's entries."""
        sd = np.sqrt(np.maximum(np.diagonal(self.cov_theta, axis1=1, axis2=2)[:, :9], 0.0))
        return sd.reshape(-1, 3, 3).transpose(0, 2, 1)  # vec is column-major

    def bias(self) -> tuple[np.ndarray, np.ndarray]:
        """(eps_b deg/s (N,3), its one-sigma (N,3)), eps_b = C_b_m^T eps through the QR split of K.

        The std uses the QR differential: with K = Q U, X = Q^T dK U^-1, the
        rotation change is dQ = Q (w x), w = (X32, -X31, X21) (strict lower
        part of X), and d eps_b = Q^T d eps + eps_b x w.
        """
        Q, U = np.linalg.qr(self.K)
        D = np.sign(np.diagonal(U, axis1=1, axis2=2))
        D[D == 0] = 1.0
        Q = Q * D[:, None, :]
        U = D[:, :, None] * U
        Ui = np.linalg.inv(U)
        eps_b = np.einsum("nji,nj->ni", Q, self.eps_m_rad_s)
        J = np.empty((len(self.t_s), 3, 12))
        for j in range(3):
            for i in range(3):
                w = np.stack([Q[:, i, 2] * Ui[:, j, 1], -Q[:, i, 2] * Ui[:, j, 0], Q[:, i, 1] * Ui[:, j, 0]], axis=1)
                J[:, :, 3 * j + i] = np.cross(eps_b, w)
        J[:, :, 9:] = Q.transpose(0, 2, 1)
        cov = np.einsum("nak,nkl,nbl->nab", J, self.cov_theta, J)
        sd = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))
        return np.rad2deg(eps_b), np.rad2deg(sd)

    def to_frame(self):
        """pandas DataFrame: t_s, K11..K33 (row-major), bias_{x,y,z}_deg_s, m_i_{x,y,z} and each `_std`."""
        import pandas as pd

        bias, bias_sd = self.bias()
        cols = {"t_s": self.t_s}
        K, Ks = self.K.reshape(-1, 9), self.K_std.reshape(-1, 9)
        for n, name in enumerate(K_NAMES):
            cols[name] = K[:, n]
        for n, name in enumerate(BIAS_NAMES):
            cols[name] = bias[:, n]
        for n, name in enumerate(FIELD_NAMES):
            cols[name] = self.m_i[:, n]
        for n, name in enumerate(K_NAMES):
            cols[name + "_std"] = Ks[:, n]
        for n, name in enumerate(BIAS_NAMES):
            cols[name + "_std"] = bias_sd[:, n]
        for n, name in enumerate(FIELD_NAMES):
            cols[name + "_std"] = self.m_i_std[:, n]
        return pd.DataFrame(cols, columns=HISTORY_COLUMNS)

    def write_parquet(self, path) -> None:
        """Write to_frame() as Parquet, whole or not at all."""
        frame = self.to_frame()
        write_atomically(Path(path), lambda tmp: frame.to_parquet(tmp, index=False))


def history_from_rows(rows: list[tuple]) -> EkfHistory:
    """EkfHistory from the filter's recorded rows (t, K, eps, m_i, cov of [vec K, eps], m_i std)."""
    if not rows:
        return EkfHistory(np.zeros(0), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
                          np.zeros((0, 12, 12)), np.zeros((0, 3)))
    return EkfHistory(
        t_s=np.array([r[0] for r in rows]), K=np.stack([r[1] for r in rows]),
        eps_m_rad_s=np.stack([r[2] for r in rows]), m_i=np.stack([r[3] for r in rows]),
        cov_theta=np.stack([r[4] for r in rows]), m_i_std=np.stack([r[5] for r in rows]),
    )


def plot_history(history: EkfHistory, path, title: str | None = None) -> None:
    """Figure like the paper's Fig. 3/6/7: K entries, gyro bias and m^i over time, +/- 3 sigma bands."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError(f"plotting needs matplotlib, which is not installed: {PLOT_INSTALL}") from None
    df = history.to_frame()
    t = df["t_s"].to_numpy()
    fig = Figure(figsize=(15, 4.5), constrained_layout=True)
    axes = fig.subplots(1, 3)
    panels = [
        (axes[0], K_NAMES, "matrix K"),
        (axes[1], BIAS_NAMES, "gyro bias eps_b (deg/s)"),
        (axes[2], FIELD_NAMES, "local magnetic vector m^i"),
    ]
    for ax, names, label in panels:
        for n, name in enumerate(names):
            v, s = df[name].to_numpy(), df[name + "_std"].to_numpy()
            line, = ax.plot(t, v, lw=1.0, label=name.replace("_deg_s", ""))
            ax.fill_between(t, v - 3 * s, v + 3 * s, color=line.get_color(), alpha=0.2, lw=0)
        ax.set_title(label)
        ax.set_xlabel("session time (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncol=3 if len(names) > 3 else 1, loc="best")
    # +/-3 sigma of a barely excited parameter can dwarf the estimates: zoom to the settled part
    for ax, names, _ in panels:
        v = df[list(names)].to_numpy()
        s = df[[n + "_std" for n in names]].to_numpy()
        settled = len(t) // 10  # the first tenth may hold the wide prior bands
        lo = np.min(v[settled:] - 3 * s[settled:])
        hi = np.max(v[settled:] + 3 * s[settled:])
        pad = 0.15 * max(hi - lo, 1e-9)
        ax.set_ylim(lo - pad, hi + pad)
    fig.suptitle(title or "EKF estimates with +/- 3 sigma bands")
    path = Path(path)
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".") or "png"))
