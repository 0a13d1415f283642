"""The figure of `magyro observe --plot`: field-direction coverage (and gravity's, with an accelerometer),
eigenvalue growth, signal to noise, rates.

Needs matplotlib, an optional extra (`pip install 'magyro[plot]'`); `require_matplotlib`
says so before any work is done.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from magyro.errors import InputError
from magyro.text import PLOT_INSTALL
from magyro.io import write_atomically
from magyro.observability.report import sphere_cell
from magyro.observability.gate import AXES, FLOOR_FACTOR
from magyro.observability.report import SPHERE_BANDS, SPHERE_SECTORS, ObservabilityReport, fmt


def require_matplotlib():
    """matplotlib's Figure, or InputError saying how to install it (call it before any work is done)."""
    try:
        import matplotlib  # noqa: F401
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError(f"--plot needs matplotlib, which is not installed: {PLOT_INSTALL}") from None
    return Figure


FIGURE_SIZE_IN = (10.0, 9.0)   # shown 924 px wide in `magyro report`, its smallest text (8.5 pt) is 10.9 px there
TEXT_PT = 8.5                   # the smallest text: legends and the text panel
TEXT_CHARACTERS = 140           # a line of the text panel, which spans the figure's width
GRAVITY_POINTS = 3000           # at most this many of gravity's directions drawn (with an accelerometer)


def plot_report(report: ObservabilityReport, path) -> None:
    """The figure: field-direction coverage, eigenvalue growth, signal to noise, rates per axis. Written atomically."""
    require_matplotlib()
    path = Path(path)
    file_format = path.suffix.lstrip(".").lower() or "png"
    fig = report_figure(report)
    write_atomically(path, lambda tmp: fig.savefig(tmp, format=file_format, dpi=100))


def report_figure(report: ObservabilityReport):
    """The matplotlib Figure of `plot_report` (not written): coverage, eigenvalue growth, signal to noise, rates."""
    Figure = require_matplotlib()
    fig = Figure(figsize=FIGURE_SIZE_IN, layout="constrained")
    grid = fig.add_gridspec(3, 2, height_ratios=[1.1, 1.0, 0.75])
    ax_sphere = fig.add_subplot(grid[0, 0])
    ax_eig = fig.add_subplot(grid[0, 1])
    ax_snr = fig.add_subplot(grid[1, 1], sharex=ax_eig)
    ax_rate = fig.add_subplot(grid[1, 0])
    ax_text = fig.add_subplot(grid[2, :])
    fig.suptitle(f"magyro observe: {Path(report.source).name or 'session'}: {report.verdict.upper()} "
                 f"(rank {report.rank} of 12, condition {fmt(report.condition)})", fontsize=11)
    c = report.coverage

    # field directions, Lambert cylindrical equal-area projection: the grid cells are equal rectangles
    u = report.field_directions
    lon = np.rad2deg(np.arctan2(u[:, 1], u[:, 0]))
    cells = np.zeros(SPHERE_BANDS * SPHERE_SECTORS)
    np.add.at(cells, sphere_cell(u), 1.0)
    visited = (cells > 0).reshape(SPHERE_BANDS, SPHERE_SECTORS).astype(float)
    ax_sphere.imshow(visited, origin="lower", extent=(-180, 180, -1, 1), aspect="auto", cmap="Greens",
                     vmin=0, vmax=2.5, interpolation="nearest")
    points = ax_sphere.scatter(lon, u[:, 2], s=1, c=report.t_mag_s, cmap="viridis")
    fig.colorbar(points, ax=ax_sphere, label="session time (s)", fraction=0.04, pad=0.01)
    for z in np.linspace(-1, 1, SPHERE_BANDS + 1):
        ax_sphere.axhline(z, color="0.8", lw=0.5)
    for x in np.linspace(-180, 180, SPHERE_SECTORS + 1):
        ax_sphere.axvline(x, color="0.8", lw=0.5)
    a = report.accelerometer
    if a is not None and a.gravity_directions is not None and len(a.gravity_directions):
        gu = a.gravity_directions[:: max(1, len(a.gravity_directions) // GRAVITY_POINTS)]
        ax_sphere.scatter(np.rad2deg(np.arctan2(gu[:, 1], gu[:, 0])), gu[:, 2], s=4, marker="x", color="tab:red",
                          lw=0.6, label=f"specific force (up), accelerometer, still: {100 * a.sphere_fraction:.0f}%")
        ax_sphere.legend(loc="lower right", fontsize=TEXT_PT)
    ax_sphere.set_xlim(-180, 180)
    ax_sphere.set_ylim(-1, 1)
    ax_sphere.set_xlabel("longitude of the field direction, magnetometer frame (deg)", fontsize=9)
    ax_sphere.set_ylabel("z of the unit field (= sin latitude)", fontsize=9)
    ax_sphere.set_title(f"field directions: {100 * c.sphere_fraction:.0f}% of the sphere "
                        f"({c.cells_visited}/{c.cells} equal-area cells)", fontsize=9.5)

    # eigenvalue growth of the cumulative integral, and each eigenvalue against its noise floor
    tl = report.timeline
    lam = plottable_on_log_axis(tl.eigenvalues)
    snr = tl.signal_to_noise
    snr = np.where(np.isfinite(snr) & (snr > 0), np.clip(snr, *SNR_SHOWN), np.nan)   # the first instants' floor is ~0
    for k in range(12):
        ax_eig.plot(tl.t_s, lam[:, k], lw=1, color=_palette(k))
        ax_snr.plot(tl.t_s, snr[:, k], lw=1, color=_palette(k))
    ax_snr.axhline(FLOOR_FACTOR, color="k", ls="--", lw=1.2, label=f"counted above {FLOOR_FACTOR:g} x noise")
    for ax in (ax_eig, ax_snr):
        for t_mark, label, style in ((report.full_rank_at_s, "full rank", "-"),
                                     (report.well_conditioned_at_s, "well conditioned", ":")):
            if t_mark is not None:
                ax.axvline(t_mark, color="tab:red", ls=style, lw=1, label=f"{label} at {t_mark:.1f} s")
        ax.set_yscale("log")
    ax_eig.set_ylabel("eigenvalues", fontsize=9)
    ax_eig.set_title("eigenvalue growth of the integral of M^T M", fontsize=9.5)
    if ax_eig.get_legend_handles_labels()[0]:
        ax_eig.legend(loc="lower right", fontsize=TEXT_PT)
    ax_snr.set_xlabel("session time (s)", fontsize=9)
    ax_snr.set_ylabel("eigenvalue / noise floor", fontsize=9)
    ax_snr.set_title("eigenvalue / its noise floor (in the rank above the line)", fontsize=9.5)
    ax_snr.legend(loc="lower right", fontsize=TEXT_PT)

    ax_text.axis("off")
    width = TEXT_CHARACTERS
    lines = [f"verdict: {report.verdict}", *_wrap(report.reason, width), ""]
    lines += ["weakest directions:"] + [f"  {w}" for d in report.weak_directions[:4] for w in _wrap(d, width - 2)]
    if report.advice:
        lines += ["", "advice:"] + [f"  {w}" for a in report.advice[:3] for w in _wrap(a, width - 2)]
    if report.accelerometer is not None:
        acc = report.accelerometer
        lines += ["", f"accelerometer: rank {acc.rank} of 12, gravity's spread {acc.spread:.2f}; the gyro with gravity "
                      f"rank {acc.gyro.rank if acc.gyro else '-'} of 12"]
        lines += [f"  {w}" for x in acc.advice[:2] for w in _wrap(x, width - 2)]
    ax_text.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", fontsize=TEXT_PT, transform=ax_text.transAxes)

    for i in range(3):
        ax_rate.plot(report.t_gyro_s, report.rates_deg_s[:, i], lw=0.7,
                     label=f"gyro {AXES[i]}: turned {c.angle_turned_deg[i]:.0f} deg, peak {c.peak_rate_deg_s[i]:.0f} deg/s")
    ax_rate.set_xlabel("session time (s)", fontsize=9)
    ax_rate.set_ylabel("rate (deg/s)", fontsize=9)
    ax_rate.set_title(f"rates per gyro axis ({c.rate_reference})", fontsize=9.5)
    ax_rate.legend(loc="upper right", fontsize=TEXT_PT)
    return fig


def _wrap(text: str, width: int) -> list[str]:
    import textwrap

    return textwrap.wrap(text, width) or [""]


def _palette(k: int):
    import matplotlib

    return matplotlib.colormaps["viridis"](k / 11.0)


SNR_SHOWN = (1e-3, 1e9)   # beyond either end a direction is plainly unexcited or plainly excited
LOG_AXIS_DECADES = 16   # what a double resolves below the largest value; smaller is a numerical zero


def plottable_on_log_axis(values: np.ndarray) -> np.ndarray:
    """The values with the ones a log axis cannot show (zero, negative, infinite, or numerically zero against the
    largest) as NaN: an unexcited direction's eigenvalue of 1e-300 asked for 300 decades and overflowed."""
    v = np.asarray(values, dtype=float)
    finite = np.isfinite(v) & (v > 0)
    if not finite.any():
        return np.full(v.shape, np.nan)
    floor = np.max(v[finite]) * 10.0 ** -LOG_AXIS_DECADES
    return np.where(finite & (v > floor), v, np.nan)
