"""Where the attitude nodes, the gyro sub-steps and the magnetometer samples sit: numbers only, no CasADi.

Segments run from one boundary to the next, and a boundary sits at every magnetometer sample and at every
gyro time, so a segment is one sub-step whatever the two sensors' rates and clocks; a segment that starts
at no magnetometer sample (the gyro is faster, or a gap in the magnetometer record) carries no
magnetometer residual. Nodes sit on every `stride`-th boundary. The kernels' shape is then the stride
alone: one solve compiles what another rate, a gap or a second session needs. An interval that overlaps a
hole in the gyro record (no gyro data) is not integrated across: inside the hole the rate is taken as
unknown (zero, and the link loose: `gyro_linked`), so the attitude after it starts a new segment; in such
an interval only the sample on its first node carries a residual: no gyro says where the device turned
between the others.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magyro.nls.gyro_samples import high_order_samples
from magyro.session import hole_spans_s, overlaps_a_hole

@dataclass(frozen=True)
class Grid:
    """Where nodes, sub-steps and magnetometer samples sit; numbers only.

    Interval n (node n to n+1) holds `stride` segments, each cut into at
    most `substeps` sub-steps (padded with zero length; one, with the
    boundaries of `segment_starts`). A segment that starts at no
    magnetometer sample has weight 0. The sub-steps' lengths and gyro rates
    (`sub_steps`) are made from the gyro record when asked, not kept: the
    problem's parameter vector holds them (19 MB at 360k samples, resident
    beside it through the solve when they were kept here too).
    """

    t_node_s: np.ndarray         # (N,)
    mag_index: np.ndarray        # (N-1, stride) magnetometer sample at each segment start (the one before, if none)
    last_mag_index: int          # magnetometer sample at the last node
    mag_weight: np.ndarray       # (N-1, stride) 1 where a segment starts at a sample, 0 in a gap
    gyro_linked: np.ndarray      # (N-1,) False where the interval overlaps a hole in the gyro record
    t_segment_s: np.ndarray      # ((N-1) stride + 1,) the segment boundaries, nodes on every stride-th
    substeps: int                # sub-steps per segment at most (L)
    t_gyro_s: np.ndarray         # the gyro record the sub-steps are made from (the session's arrays, not copies)
    gyro_rad_s: np.ndarray
    last_on_sample: bool = True  # whether the last node sits on a magnetometer sample

    @property
    def nodes(self) -> int:
        return len(self.t_node_s)

    @property
    def stride(self) -> int:
        return self.mag_index.shape[1]

    def sub_steps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dt_s (N-1, stride, L), gyro_a, gyro_b (N-1, stride, L, 3)): each sub-step's length and the gyro at its
        start and end (`high_order_samples`, interpolated; zero inside a hole of the gyro record)."""
        t_all, seg_of_step, pos = step_layout(self.t_gyro_s, self.t_segment_s)
        y_all = np.column_stack([np.interp(t_all, self.t_gyro_s, f) for f in
                                 high_order_samples(self.t_gyro_s, self.gyro_rad_s).T])
        interval, segment = np.divmod(seg_of_step, self.stride)
        shape = (len(self.mag_index), self.stride, self.substeps)
        dt, ya, yb = np.zeros(shape), np.zeros(shape + (3,)), np.zeros(shape + (3,))
        dt[interval, segment, pos] = np.diff(t_all)
        measured = ~overlaps_a_hole(t_all[:-1], t_all[1:], hole_spans_s(self.t_gyro_s))[:, None]   # no rate is known inside a hole
        ya[interval, segment, pos] = y_all[:-1] * measured
        yb[interval, segment, pos] = y_all[1:] * measured
        return dt, ya, yb

    @property
    def dt_s(self) -> np.ndarray:
        """(N-1, stride, L) the sub-steps' lengths (`sub_steps`, made on each use)."""
        return self.sub_steps()[0]

    @property
    def gyro_a(self) -> np.ndarray:
        """(N-1, stride, L, 3) the gyro at each sub-step start (`sub_steps`, made on each use)."""
        return self.sub_steps()[1]

    @property
    def gyro_b(self) -> np.ndarray:
        """(N-1, stride, L, 3) the gyro at each sub-step end (`sub_steps`, made on each use)."""
        return self.sub_steps()[2]

    @property
    def interval_s(self) -> np.ndarray:
        return np.diff(self.t_node_s)

    @property
    def node_mag_index(self) -> np.ndarray:
        """Magnetometer sample at each node (the one before it, for a node in a gap)."""
        return np.append(self.mag_index[:, 0], self.last_mag_index)

    @property
    def node_on_sample(self) -> np.ndarray:
        """True for the nodes that sit on a magnetometer sample."""
        return np.append(self.mag_weight[:, 0] > 0, self.last_on_sample)

    @property
    def sample_mask(self) -> np.ndarray:
        """(N-1) * stride flags, in residual order: True for segments with a magnetometer sample."""
        return self.mag_weight.reshape(-1) > 0


STRIDES = (4, 12)         # the strides magyro picks from (solve.default_stride): each one set of kernels
MAX_SEGMENT_FACTOR = 1.5  # segments longer than this many typical segments (a hole in both records) are cut


def segment_starts(t_mag_s: np.ndarray, used: np.ndarray, t_gyro_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, magnetometer index, on-a-sample flag) of every segment boundary.

    A boundary at every used magnetometer sample and at every gyro time between the first and the last, so a
    segment is one sub-step whatever the two rates, and the kernels' shape does not depend on them; where
    neither sensor has data for longer than MAX_SEGMENT_FACTOR typical segments, boundaries about one typical
    segment apart. A boundary that is no magnetometer sample carries the index of the sample before it and
    the flag False (its segment has no magnetometer residual).
    """
    t = t_mag_s[used]
    inside = t_gyro_s[(t_gyro_s > t[0]) & (t_gyro_s < t[-1])] if len(t) else t_gyro_s[:0]
    times = np.union1d(t, inside)
    dt = np.diff(times)
    typical = float(np.median(dt)) if len(dt) else 0.0
    long = np.flatnonzero(dt > MAX_SEGMENT_FACTOR * typical) if typical > 0 else np.array([], dtype=int)
    extra_t, _ = bridge_points(times, dt, long, typical, t_gyro_s)
    times = np.union1d(times, extra_t)
    before = np.searchsorted(t, times, side="right") - 1
    return times, used[before], t[before] == times

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


def usable_magnetometer(t_gyro_s, t_mag_s) -> np.ndarray:
    """Indices of the magnetometer samples inside the gyro's span: the only ones the grid can place."""
    return np.flatnonzero((t_mag_s >= t_gyro_s[0]) & (t_mag_s <= t_gyro_s[-1]))


def typical_segment_s(t_gyro_s, t_mag_s) -> float | None:
    """The median length of the grid's segments (`segment_starts`); None with fewer than two usable samples."""
    usable = usable_magnetometer(t_gyro_s, t_mag_s)
    if len(usable) < 2:
        return None
    return float(np.median(np.diff(segment_starts(t_mag_s, usable, t_gyro_s)[0])))


def step_layout(t_gyro_s: np.ndarray, t_seg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the sub-steps' boundaries: every gyro time between the segment boundaries t_seg and those, each sub-step's
    segment, its position in the segment)."""
    inside = t_gyro_s[(t_gyro_s > t_seg[0]) & (t_gyro_s < t_seg[-1])]
    t_all = np.union1d(inside, t_seg)
    seg_of_step = np.searchsorted(t_seg, t_all[:-1], side="right") - 1
    first = np.searchsorted(seg_of_step, np.arange(len(t_seg) - 1), side="left")
    return t_all, seg_of_step, np.arange(len(t_all) - 1) - first[seg_of_step]


def build_grid(t_gyro_s, gyro_rad_s, t_mag_s, stride: int = 1) -> Grid:
    """Nodes on every `stride`-th segment boundary (`segment_starts`: magnetometer samples and gyro times)
    inside the gyro's span."""
    usable = usable_magnetometer(t_gyro_s, t_mag_s)
    holes = hole_spans_s(t_gyro_s)
    t_bound, idx_bound, on_sample = segment_starts(t_mag_s, usable, t_gyro_s)
    n_int = (len(t_bound) - 1) // stride
    t_seg = t_bound[: n_int * stride + 1]
    seg_idx = idx_bound[: n_int * stride + 1]
    L = int(step_layout(t_gyro_s, t_seg)[2].max()) + 1
    weight = on_sample[: n_int * stride].reshape(n_int, stride).astype(float)
    t_node = t_seg[::stride]
    linked = ~overlaps_a_hole(t_node[:-1], t_node[1:], holes)
    weight[~linked, 1:] = 0.0   # past a node, an interval over a hole cannot say where the device turned
    return Grid(t_node, seg_idx[:-1].reshape(n_int, stride), int(seg_idx[-1]), weight, linked, t_seg, L,
                t_gyro_s, gyro_rad_s, bool(on_sample[n_int * stride]))

def gyro_at_mag_midpoints(grid: Grid, t_gyro_s, gyro_rad_s, t_mag_s, tau0_s: float) -> np.ndarray:
    """Raw gyro at each used magnetometer stamp minus tau0/2: (N-1, stride, 3)."""
    if t_gyro_s is None:
        return np.zeros(grid.mag_index.shape + (3,))
    t = t_mag_s[grid.mag_index] - 0.5 * tau0_s
    return np.stack([np.interp(t, t_gyro_s, gyro_rad_s[:, i]) for i in range(3)], axis=-1)
