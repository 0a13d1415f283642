"""What `magyro watch` shows: a live panel on stderr (rich), plain lines, and the `--status` JSON lines.

- With an accelerometer in the stream, one more part: its poses held (seconds with gravity within 45 deg of
  each of +x -x +y -y +z -z), the rank of its 12 parameters and the poses still to hold, `magyro observe`'s
  accelerometer section on the data so far (`accelerometer_text`); without, every line is as it was.
- On a terminal (and without -q): a rich Live panel redrawn several times a second: the rank
  against the noise floor, the field-direction coverage, a table of the predicted one-sigma of
  each parameter group against its target, the instruction (the motion to make next) and ENOUGH
  once every target is met. Without rich, the plain lines below.
- Not a terminal, or -q: one plain line per second, or at once when the rank, the field
  source or "enough" changes (-q: nothing but the final summary).
- `StatusWriter`: every update as one JSON line (`Status.to_json_dict`: t_s, rank, coverage,
  predicted std per group, enough, ...), flushed as written.
"""
from __future__ import annotations

import json
import math
import sys
import time

from magyro.live.status import Status
from magyro.live.prediction import GROUP_LABELS, GROUPS
from magyro.text import significant

PLAIN_EVERY_S = 1.0
REFRESH_PER_SECOND = 8


def fmt(v: float | None) -> str:
    return significant(v)


def predicted_text(status: Status) -> str:
    p = status.predicted
    if p is None:
        return "predicting..." if status.predicting else "no prediction yet"
    return " ".join(f"{g.split('_')[0]} {fmt(p[g])}/{fmt(status.targets[g])}" for g in GROUPS)


def plain_line(status: Status, counts=None) -> str:
    skipped = f", {counts.skipped_text()}" if counts is not None and counts.skipped else ""
    head = (f"t {status.t_s:7.1f} s  rank {status.rank:2d}/12  coverage {100 * status.coverage:3.0f}%  "
            f"std {predicted_text(status)}")
    tail = status.instruction
    acc = "" if status.accelerometer is None else "  | " + accelerometer_text(status.accelerometer) + gravity_text(status)
    return f"magyro watch: {head}  | {tail}{acc}{skipped}"


def gravity_text(status: Status) -> str:
    """What gravity adds to the gyro: its rank with gravity beside the field (observe's part 2), or nothing yet."""
    r = status.rank_with_gravity
    return "" if r is None else f"  | gyro with gravity: rank {r}/12 (field alone {status.rank})"


def accelerometer_text(acc, advice: bool = False) -> str:
    """The accelerometer in one line: the rank of its 12 parameters, the poses held (s, weighted by stillness) and
    the poses to hold next (observe's rule, `gravity.missing_poses`); `advice`: observe's advice in full."""
    from magyro.observability.gravity import FACES, SPREAD_ENOUGH, body_direction, missing_poses

    poses = " ".join(f"{f} {acc.face_s[f]:.1f}" for f in FACES)
    missing = missing_poses(acc.face_s)
    if missing:
        nxt = "hold still with " + ", ".join(f"{f[1]} {'up' if f[0] == '+' else 'down'}" for f in missing)
    elif acc.spread < SPREAD_ENOUGH:
        nxt = f"turn its {body_direction(acc.spread_weakest)} axis up and down"
    else:
        nxt = "every pose held"
    text = f"accelerometer: rank {acc.rank}/12, poses (s) {poses}; {nxt}"
    if advice and acc.advice:
        text += " (" + " ".join(acc.advice) + ")"
    return text


class PlainDisplay:
    """One line per second, or at once on a change of rank, field source or "enough"."""

    def __init__(self, stream=None, every_s: float = PLAIN_EVERY_S, clock=time.monotonic):
        self.stream = stream or sys.stderr
        self.every_s = every_s
        self.clock = clock
        self._last = -math.inf
        self._key = None

    def show(self, status: Status, counts=None) -> None:
        key = (status.rank, status.rank_with_gravity, status.field_source, status.enough, status.predicted is None,
               status.instruction[:12],
               None if status.accelerometer is None else (status.accelerometer.rank, accelerometer_text(
                   status.accelerometer).split(";")[-1]))
        now = self.clock()
        if key != self._key or now - self._last >= self.every_s:
            print(plain_line(status, counts), file=self.stream, flush=True)
            self._key, self._last = key, now

    def close(self) -> None:
        pass


class QuietDisplay:
    def show(self, status: Status, counts=None) -> None:
        pass

    def close(self) -> None:
        pass


class RichDisplay:
    """A rich Live panel on stderr."""

    def __init__(self, stream=None, source: str = ""):
        from rich.console import Console
        from rich.live import Live

        self.source = source
        self.console = Console(file=stream or sys.stderr)
        self.live = Live(self._render(None, None), console=self.console, refresh_per_second=REFRESH_PER_SECOND,
                         transient=False)
        self.live.start()

    def show(self, status: Status, counts=None) -> None:
        self.live.update(self._render(status, counts))

    def _render(self, status: Status | None, counts):
        from rich.console import Group
        from rich.panel import Panel
        from rich.table import Table
        from rich.text import Text

        if status is None:
            return Panel(Text("waiting for samples..."), title=f"magyro watch {self.source}")
        head = Text()
        head.append(f"{status.t_s:.1f} s   ", style="bold")
        head.append(f"rank {status.rank}/12", style="bold green" if status.rank == 12 else "bold yellow")
        head.append(f" above the noise floor ({significant(status.noise_floor)}, x10)   ")
        head.append(f"coverage {100 * status.coverage:.0f}% ({status.cells_visited} cells)   ")
        head.append(f"field: {status.field_source}", style="dim")
        table = Table(box=None, pad_edge=False)
        for col in ("parameter group", "predicted 1-sigma (max)", "target", ""):
            table.add_column(col)
        p = status.predicted
        for g in GROUPS:
            label, unit = GROUP_LABELS[g]
            value = None if p is None else p[g]
            ok = value is not None and value <= status.targets[g]
            table.add_row(f"{label} ({unit})", fmt(value), fmt(status.targets[g]),
                          Text("ok", style="green") if ok else Text("-" if value is None else "above",
                                                                     style="dim" if value is None else "red"))
        when = ""
        if status.prediction is not None:
            when = f"prediction of the data up to {status.prediction.t_s:.1f} s (magyro observe, {status.prediction.seconds:.2f} s)"
        if status.predicting:
            when += ("; " if when else "") + "predicting..."
        parts = [head, table, Text(when, style="dim")]
        if status.enough:
            parts.append(Text(f"{status.instruction} (ENOUGH since {status.enough_at_s:.1f} s)",
                              style="bold white on green"))
        else:
            parts.append(Text("next: " + status.instruction, style="bold cyan"))
            if status.detail:
                parts.append(Text(status.detail, style="dim"))
        if status.accelerometer is not None:
            acc = status.accelerometer
            parts.append(Text(accelerometer_text(acc) + gravity_text(status),
                              style="bold green" if not acc.advice else "bold magenta"))
            if acc.advice:
                parts.append(Text(" ".join(acc.advice), style="dim"))
        if counts is not None:
            extra = f"{counts.gyro} gyro, {counts.mag} magnetometer" + (
                f", {counts.acc} accelerometer" if counts.acc else "") + " samples"
            if counts.skipped:
                extra += (f"; {counts.skipped_text()}"
                          + (f" (last bad: {counts.last_bad!r})" if counts.bad and counts.last_bad else ""))
            parts.append(Text(extra, style="dim"))
        return Panel(Group(*parts), title=f"magyro watch {self.source}")

    def close(self) -> None:
        self.live.stop()


def make_display(quiet: bool, stream=None, source: str = ""):
    """rich on a terminal, plain lines otherwise, nothing with -q."""
    stream = stream or sys.stderr
    if quiet:
        return QuietDisplay()
    if hasattr(stream, "isatty") and stream.isatty():
        try:
            return RichDisplay(stream, source)
        except ImportError:
            pass
    return PlainDisplay(stream)


class StatusWriter:
    """Every update as one JSON line in a file (flushed as written)."""

    def __init__(self, path):
        self.f = open(path, "w", encoding="utf-8")

    def write(self, status: Status) -> None:
        self.f.write(json.dumps(status.to_json_dict(), allow_nan=False, default=_plain) + "\n")
        self.f.flush()

    def close(self) -> None:
        self.f.close()


def _plain(x):
    try:
        return float(x)
    except (TypeError, ValueError):
        return str(x)
