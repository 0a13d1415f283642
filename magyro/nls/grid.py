"""Where the attitude nodes, the gyro sub-steps and the magnetometer samples sit: numbers only, no CasADi.

Nodes sit on every `stride`-th segment boundary; segments run from one
magnetometer sample to the next, and a gap in the magnetometer record is cut,
at gyro times, into segments of typical length that carry no magnetometer
residual, so that a gap compiles no new kernel shape. An interval that overlaps a
hole in the gyro record (no gyro data) is not integrated across: inside the hole the
rate is taken as unknown (zero, and the link loose: `gyro_linked`), so the attitude after
it starts a new segment; in such an interval only the sample on its first node
carries a residual: no gyro says where the device turned between the others.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.session import hole_spans_s, overlaps_a_hole

@dataclass(frozen=True)
class Grid:
    """Where nodes, sub-steps and magnetometer samples sit; numbers only.

    Interval n (node n to n+1) holds `stride` segments, each from one
    magnetometer sample to the next, each cut into at most `substeps`
    sub-steps (padded with zero length). A gap in the magnetometer record is
    bridged by segments about one typical interval long that start at no
    sample (weight 0), so one gap does not pad every interval of the session
    to its length.
    """

    t_node_s: np.ndarray         # (N,)
    mag_index: np.ndarray        # (N-1, stride) magnetometer sample at each segment start (the one before, if none)
    dt_s: np.ndarray             # (N-1, stride, L)
    gyro_a: np.ndarray           # (N-1, stride, L, 3) raw gyro at each sub-step start
    gyro_b: np.ndarray           # (N-1, stride, L, 3) raw gyro at each sub-step end
    last_mag_index: int          # magnetometer sample at the last node
    mag_weight: np.ndarray       # (N-1, stride) 1 where a segment starts at a sample, 0 in a gap
    gyro_linked: np.ndarray      # (N-1,) False where the interval overlaps a hole in the gyro record

    @property
    def nodes(self) -> int:
        return len(self.t_node_s)

    @property
    def stride(self) -> int:
        return self.dt_s.shape[1]

    @property
    def substeps(self) -> int:
        return self.dt_s.shape[2]

    @property
    def interval_s(self) -> np.ndarray:
        return np.diff(self.t_node_s)

    @property
    def node_mag_index(self) -> np.ndarray:
        """Magnetometer sample at each node (the one before it, for a node in a gap)."""
        return np.append(self.mag_index[:, 0], self.last_mag_index)

    @property
    def node_on_sample(self) -> np.ndarray:
        """True for the nodes that sit on a magnetometer sample (the last node always does)."""
        return np.append(self.mag_weight[:, 0] > 0, True)

    @property
    def sample_mask(self) -> np.ndarray:
        """(N-1) * stride flags, in residual order: True for segments with a magnetometer sample."""
        return self.mag_weight.reshape(-1) > 0


MAX_SEGMENT_FACTOR = 1.5  # segments longer than this many typical magnetometer intervals are cut


def segment_starts(t_mag_s: np.ndarray, used: np.ndarray, t_gyro_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, magnetometer index, on-a-sample flag) of every segment boundary.

    The used samples' times, plus boundaries inside each gap longer than
    MAX_SEGMENT_FACTOR typical intervals, about one typical interval apart and
    placed on gyro times (so they add no sub-step, and the kernels keep the
    gap-free session's shape); those carry the index of the sample before the
    gap and the flag False.
    """
    t = t_mag_s[used]
    dt = np.diff(t)
    typical = float(np.median(dt)) if len(dt) else 0.0
    long = np.flatnonzero(dt > MAX_SEGMENT_FACTOR * typical) if typical > 0 else np.array([], dtype=int)
    extra_t, extra_i = bridge_points(t, dt, long, typical, t_gyro_s)
    times = np.concatenate([t, extra_t])
    index = np.concatenate([used, used[extra_i]])
    on_sample = np.concatenate([np.ones(len(t), dtype=bool), np.zeros(len(extra_t), dtype=bool)])
    order = np.argsort(times, kind="stable")
    return times[order], index[order], on_sample[order]

def bridge_points(t: np.ndarray, dt: np.ndarray, long: np.ndarray, typical: float,
                  t_gyro_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(times, position in t of the sample before) of the boundaries that cut each long gap t[k] -> t[k+1]
    into pieces about `typical` long: each at the first gyro time at or after its even share of the gap
    (or the gap's last gyro time), duplicates dropped; where no gyro sample falls in the gap, the even share."""
    pieces = np.ceil(dt[long] / typical).astype(int) - 1
    gap = np.repeat(long, pieces)
    share = (np.arange(len(gap)) - np.repeat(np.cumsum(pieces) - pieces, pieces) + 1) / np.repeat(pieces + 1, pieces)
    wanted = t[gap] + dt[gap] * share
    first_after = np.searchsorted(t_gyro_s, t[gap], side="right")           # first gyro time inside the gap
    last_inside = np.searchsorted(t_gyro_s, t[gap + 1], side="left") - 1
    at = np.minimum(np.searchsorted(t_gyro_s, wanted, side="left"), last_inside)
    has_gyro = last_inside >= first_after
    snapped = np.where(has_gyro, t_gyro_s[np.clip(at, 0, len(t_gyro_s) - 1)], wanted)
    keep = np.ones(len(gap), dtype=bool)
    keep[1:] = (snapped[1:] != snapped[:-1]) | (gap[1:] != gap[:-1])
    return snapped[keep], gap[keep]


def build_grid(t_gyro_s, gyro_rad_s, t_mag_s, stride: int = 1) -> Grid:
    """Nodes on every `stride`-th segment boundary (magnetometer samples, gaps cut) inside the gyro's span."""
    usable = np.flatnonzero((t_mag_s >= t_gyro_s[0]) & (t_mag_s <= t_gyro_s[-1]))
    holes = hole_spans_s(t_gyro_s)
    t_bound, idx_bound, on_sample = segment_starts(t_mag_s, usable, t_gyro_s)
    n_int = (len(t_bound) - 1) // stride
    t_seg = t_bound[: n_int * stride + 1]
    seg_idx = idx_bound[: n_int * stride + 1]
    inside = t_gyro_s[(t_gyro_s > t_seg[0]) & (t_gyro_s < t_seg[-1])]
    t_all = np.union1d(inside, t_seg)
    y_all = np.column_stack([np.interp(t_all, t_gyro_s, gyro_rad_s[:, i]) for i in range(3)])
    seg_of_step = np.searchsorted(t_seg, t_all[:-1], side="right") - 1
    first = np.searchsorted(seg_of_step, np.arange(len(t_seg) - 1), side="left")
    pos = np.arange(len(t_all) - 1) - first[seg_of_step]
    L = int(pos.max()) + 1
    interval, segment = np.divmod(seg_of_step, stride)
    dt = np.zeros((n_int, stride, L))
    ya = np.zeros((n_int, stride, L, 3))
    yb = np.zeros((n_int, stride, L, 3))
    dt[interval, segment, pos] = np.diff(t_all)
    measured = ~overlaps_a_hole(t_all[:-1], t_all[1:], holes)[:, None]   # no rate is known inside a hole
    ya[interval, segment, pos] = y_all[:-1] * measured
    yb[interval, segment, pos] = y_all[1:] * measured
    weight = on_sample[: n_int * stride].reshape(n_int, stride).astype(float)
    t_node = t_seg[::stride]
    linked = ~overlaps_a_hole(t_node[:-1], t_node[1:], holes)
    weight[~linked, 1:] = 0.0   # past a node, an interval over a hole cannot say where the device turned
    return Grid(t_node, seg_idx[:-1].reshape(n_int, stride), dt, ya, yb, int(seg_idx[-1]), weight, linked)

def gyro_at_mag_midpoints(grid: Grid, t_gyro_s, gyro_rad_s, t_mag_s, tau0_s: float) -> np.ndarray:
    """Raw gyro at each used magnetometer stamp minus tau0/2: (N-1, stride, 3)."""
    if t_gyro_s is None:
        return np.zeros(grid.mag_index.shape + (3,))
    t = t_mag_s[grid.mag_index] - 0.5 * tau0_s
    return np.stack([np.interp(t, t_gyro_s, gyro_rad_s[:, i]) for i in range(3)], axis=-1)
