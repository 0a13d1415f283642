"""The report's own figures (the recording's clocks, the calibration with its std, the residuals over time, the
split-half check) and the embedding of any matplotlib Figure in the page (`embedded`: a PNG at twice the width
the page shows it at, `magyro.report.embed`).

Every figure is a `matplotlib.figure.Figure` made without pyplot (no global state, nothing to close). Every
figure is shown FIGURE_WIDTH_PX wide; its text is at least 8 pt, which at that width is over 10 CSS pixels for
a figure up to 10 in wide.
"""
from __future__ import annotations

import numpy as np

from magyro.errors import InputError
from magyro.text import PLOT_INSTALL
from magyro.report.embed import EmbeddedFigure, embed_png

RAW, CALIBRATED, SPLIT = "#c0392b", "#1f5fa8", "#e08a1e"   # the page's colours for raw, calibrated, split-half
GOOD, FAIR, POOR = "#2e7d32", "#b26a00", "#b3261e"
PAGE_MAX_WIDTH_PX = 980                                   # the page's main column (magyro.report.html.CSS) ...
PAGE_PADDING_PX = 28                                      # ... and its padding on either side
FIGURE_WIDTH_PX = PAGE_MAX_WIDTH_PX - 2 * PAGE_PADDING_PX  # the width every figure is shown at


def new_figure(width_in: float, height_in: float):
    """An empty Figure with the report's style; InputError when matplotlib is absent."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError(f"magyro report needs matplotlib for its figures, which is not installed: {PLOT_INSTALL}") from None
    return Figure(figsize=(width_in, height_in), layout="constrained")


def style(ax) -> None:
    ax.grid(alpha=0.25, lw=0.6)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.tick_params(labelsize=8)


def embedded(fig) -> EmbeddedFigure:
    """The figure as the page embeds it: a PNG data URI at twice FIGURE_WIDTH_PX, shown FIGURE_WIDTH_PX wide."""
    return embed_png(fig, FIGURE_WIDTH_PX)


# --------------------------------------------------------------------------- 1. the recording's clocks


def recording_figure(raw, repaired, check):
    """Sample intervals of each sensor over time, as stamped and as kept after the repairs; the gap threshold,
    the gyro holes and the findings that are local in time marked."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    from magyro.front.findings import GAP_PERIODS

    fig = new_figure(9.5, 4.4)
    axes = fig.subplots(2, 1, sharex=True)
    sensors = (("gyro", raw.t_gyro_s, repaired.t_gyro_s), ("magnetometer", raw.t_mag_s, repaired.t_mag_s))
    span = raw.t_gyro_s[-1] - raw.t_gyro_s[0] if len(raw.t_gyro_s) > 1 else 1.0
    for ax, (name, t_raw, t_rep) in zip(axes, sensors):
        style(ax)
        for t, label, color, size in ((t_rep, "kept after the repairs", CALIBRATED, 9.0), (t_raw, "as stamped", "0.3", 1.5)):
            if len(t) < 2:
                continue
            dt_ms = 1e3 * np.diff(t)
            ok = dt_ms > 0
            ax.scatter(t[1:][ok], dt_ms[ok], s=size, color=color, label=label, rasterized=True, linewidths=0)
            if (~ok).any():
                ax.scatter(t[1:][~ok], np.full((~ok).sum(), 1e-3), marker="v", s=14, color=POOR,
                           label="out of order or repeated stamp")
        stats = check.sensors.get(name)
        if stats is not None and np.isfinite(stats.period_s) and stats.period_s > 0:
            ax.axhline(1e3 * GAP_PERIODS * stats.period_s, color=POOR, ls="--", lw=0.9,
                       label=f"gap: over {GAP_PERIODS:g} periods")
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        low, high = ax.get_ylim()
        ax.set_ylim(low / 1.5, high * 2.5)   # room for the legend above the gap line
        ax.set_ylabel(f"{name}\ninterval (ms)", fontsize=9)
        for finding in check.findings:
            if finding.sensor not in (name, "both"):
                continue
            color = POOR if finding.severity == "error" else FAIR if finding.severity == "warning" else "0.6"
            for a, b in finding.where_s:
                if b - a < 0.5 * span:   # a finding over the whole record marks nothing
                    ax.axvspan(a, max(b, a + 2e-3 * span), color=color, alpha=0.2, lw=0)
        if name == "gyro":
            for a, b in check.gyro_holes_s:
                ax.axvspan(a, b, color=POOR, alpha=0.3, lw=0)
        ax.legend(fontsize=8, loc="upper right", markerscale=2, ncols=3, frameon=False)
    axes[-1].set_xlabel("session time (s)", fontsize=9)
    return fig


# --------------------------------------------------------------------------- 3. the calibration and its std


def calibration_figure(rows):
    """Each gyro parameter with its one-sigma (and half the split-half difference when known), in four groups by unit.

    `rows`: the report's parameter rows (group, label, value, std, split_std, rest)."""
    groups = [("scale", "scale factor off 1 (ppm)"), ("nonorth", "non-orthogonality (deg)"),
              ("bias", "bias (deg/s)"), ("misalignment", "misalignment (deg)")]
    fig = new_figure(9.5, 3.2)
    axes = fig.subplots(1, 4)
    for ax, (group, title) in zip(axes, groups):
        style(ax)
        mine = [r for r in rows if r.group == group]
        x = np.arange(len(mine))
        values = np.array([r.value for r in mine])
        split = np.array([np.nan if r.split_std is None else r.split_std for r in mine])
        if np.isfinite(split).any():
            ax.errorbar(x + 0.12, values, yerr=np.nan_to_num(split), fmt="none", ecolor=SPLIT, elinewidth=1.2,
                        capsize=3, label="± half the split-half difference")
        ax.errorbar(x, values, yerr=[r.std for r in mine], fmt="o", color=CALIBRATED, ms=4, elinewidth=2,
                    capsize=3, label="estimate ± 1σ")
        rest = [(i, r.rest) for i, r in enumerate(mine) if r.rest is not None]
        if rest:
            ax.scatter([i - 0.15 for i, _ in rest], [v for _, v in rest], marker="x", color="0.2", s=22,
                       label="from the rests", zorder=3)
        ax.axhline(0, color="0.3", lw=0.8)
        ax.set_xticks(x, [r.axis for r in mine], fontsize=8)
        ax.set_xlim(-0.6, len(mine) - 0.4)
        ax.set_title(title, fontsize=9)
    handles = {}
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, h)
    fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    return fig


# --------------------------------------------------------------------------- 4. the residuals over time


def residual_figure(windows, field, max_field_change: float, field_window_s: float):
    """Top: the turning misfit of each window (eq. 13), raw and calibrated gyro.
    Bottom: the calibrated field magnitude |R (y - h)| - 1 in percent, each sample and over `field_window_s`,
    with the limit the fit check uses."""
    fig = new_figure(9.5, 4.8)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[1.2, 1])
    style(ax1)
    style(ax2)
    for name, color in (("raw", RAW), ("calibrated", CALIBRATED)):
        t, r = windows.t_s[name], windows.misfit_deg[name]
        ax1.plot(t, r, color=color, lw=1.1, marker="o", ms=2.2,
                 label=f"{name} gyro: RMS {windows.rms_deg[name]:.2f} deg")
    ax1.set_ylim(bottom=0)
    ax1.set_ylabel(f"misfit per {windows.window_s:g} s\nwindow (deg)", fontsize=9)
    ax1.legend(fontsize=8, loc="upper right", frameon=False, ncols=2)
    ax1.set_title(f"eq. (13) over {windows.window_s:g} s windows: the field's turning the gyro predicts minus the "
                  "turning measured", fontsize=9)
    percent = 100 * (field.magnitude - 1.0)
    ax2.plot(field.t_s, percent, color="0.7", lw=0.5, rasterized=True, label="each sample")
    centre, mean = window_means(field.t_s, percent, field_window_s)
    ax2.plot(centre, mean, color=CALIBRATED, lw=1.3, label=f"{field_window_s:g} s mean (judged)")
    limit = 100 * max_field_change
    ax2.axhspan(-limit, limit, color=GOOD, alpha=0.06, lw=0)
    for y in (-limit, limit):
        ax2.axhline(y, color=POOR, ls="--", lw=0.9)
    top = max(1.3 * limit, 1.05 * float(np.nanmax(np.abs(percent))) if percent.size else limit)
    ax2.set_ylim(-top, top)
    ax2.set_ylabel("|R (y − h)| − 1 (%)", fontsize=9)
    ax2.set_xlabel("session time (s)", fontsize=9)
    ax2.legend(fontsize=8, loc="lower right", frameon=False, ncols=2)
    ax2.text(0.005, 0.97, f"limit ±{limit:g} % (a magnet or iron near the path)", transform=ax2.transAxes,
             fontsize=8, va="top", color=POOR)
    return fig


def window_means(t: np.ndarray, values: np.ndarray, window_s: float):
    """Mean of `values` over consecutive windows of `window_s`: (window centres, means)."""
    if len(t) == 0:
        return t, values
    k = np.floor((t - t[0]) / window_s).astype(int)
    n = np.bincount(k)
    has = n > 0
    return np.bincount(k, weights=t)[has] / n[has], np.bincount(k, weights=values)[has] / n[has]


# --------------------------------------------------------------------------- 5. the split-half check


def split_figure(check, labels: dict):
    """Each gyro parameter's half-difference over its std (z), against the warning limits."""
    names = list(check.parameters)
    z = np.array([check.parameters[n]["z"] for n in names], dtype=float)
    fig = new_figure(9.5, 3.4)
    ax = fig.subplots()
    style(ax)
    colors = [POOR if abs(v) > check.max_half_z else FAIR if abs(v) > check.max_rms_z else CALIBRATED for v in z]
    ax.bar(np.arange(len(z)), z, color=colors, width=0.65)
    for y in (-check.max_half_z, check.max_half_z):
        ax.axhline(y, color=POOR, ls="--", lw=0.9)
    ax.axhline(0, color="0.3", lw=0.8)
    ax.set_xticks(np.arange(len(z)), [labels.get(n, n) for n in names], rotation=35, ha="right", fontsize=8)
    ax.set_ylabel("first half - second half\nover its std (z)", fontsize=9)
    ax.set_title(f"RMS z {check.rms_z:.2f} (warning above {check.max_rms_z:g}); one |z| above "
                 f"{check.max_half_z:g} (dashed) is a warning", fontsize=9)
    return fig
