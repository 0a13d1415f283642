"""What long work is doing, for whoever shows it: `step("solving")` anywhere, `showing(...)` on the command line.

The library only names its steps (`step`); it prints nothing. A caller that wants to see them
installs a reporter for a block of work:

    with magyro.progress.reporting(print):                  # any callable taking the step's text
        magyro.calibrate(session)

`magyro solve`, `check`, `observe`, `report` and the importers use `showing()`, which on a
terminal keeps one live line on stderr (a spinner, the step, the seconds so far; rich when it is
installed, a plain line otherwise) and shows nothing when stderr is not a terminal or with -q; with
MAGYRO_PROGRESS=lines in the environment each step is its own line on stderr ("magyro step: ..."), for logs.
"""
from __future__ import annotations

import contextlib
import contextvars
import os
import sys
import time
from typing import Callable

LINES_VARIABLE = "MAGYRO_PROGRESS"   # =lines: each step as its own stderr line, terminal or not (logs, CI)
_reporter: contextvars.ContextVar[Callable[[str], None] | None] = contextvars.ContextVar("magyro_progress", default=None)


def step(text: str) -> None:
    """Say that the work now does `text` (a few words, e.g. "solving the least squares")."""
    reporter = _reporter.get()
    if reporter is not None:
        reporter(text)


@contextlib.contextmanager
def reporting(reporter: Callable[[str], None] | None):
    """Within the block, every `step` goes to `reporter` (None: nowhere)."""
    token = _reporter.set(reporter)
    try:
        yield
    finally:
        _reporter.reset(token)


@contextlib.contextmanager
def showing(enabled: bool = True, stream=None):
    """The steps of the block as one live line on `stream` (stderr), on a terminal only."""
    stream = stream or sys.stderr
    if enabled and os.environ.get(LINES_VARIABLE) == "lines":     # a log's view: every step its own line
        with reporting(lambda text: print(f"magyro step: {text}", file=stream, flush=True)):
            yield
        return
    if not (enabled and hasattr(stream, "isatty") and stream.isatty()):
        with reporting(None):
            yield
        return
    try:
        from rich.console import Console
        from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
    except ImportError:
        with reporting(_plain_line(stream)):
            yield
        stream.write("\r\033[K")
        return
    with Progress(SpinnerColumn(), TimeElapsedColumn(), TextColumn("{task.description}"),
                  console=Console(file=stream), transient=True) as live:
        task = live.add_task("magyro", total=None)
        with reporting(lambda text: live.update(task, description=text)):
            yield


def _plain_line(stream) -> Callable[[str], None]:
    start = time.perf_counter()

    def show(text: str) -> None:
        stream.write(f"\r\033[Kmagyro: {text} ({time.perf_counter() - start:.0f} s)")
        stream.flush()

    return show


LAST_WIDTH = 60   # the bar's last item: shortened at a word with "...", the whole text is printed in the log form


@contextlib.contextmanager
def counting(total: int, label: str = "runs", enabled: bool = True, stream=None):
    """Progress through `total` items (Monte Carlo runs, a batch's devices): yields `tick(done, text, alarm=False,
    total=None)` (`total` when it becomes known only later).

    On a terminal a rich bar on stderr with the last item's text (shortened at a word with "..." to LAST_WIDTH;
    an `alarm` item, a failure, is also printed whole as its own line); otherwise one line per item, "LABEL k/N
    text", the text whole, so a log keeps them. Disabled: yields None.
    """
    stream = stream or sys.stderr
    if not enabled:
        yield None
        return
    state = {"total": total}
    try:
        if not stream.isatty():
            raise ImportError
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
    except (ImportError, AttributeError, ValueError):
        def plain(done: int, text: str, alarm: bool = False, total: int | None = None) -> None:
            state["total"] = total or state["total"]
            print(f"{label[:-1] if label.endswith('s') else label} {done}/{state['total']} {text}", file=stream,
                  flush=True)

        yield plain
        return
    from magyro.text import shortened

    console = Console(file=stream)
    with Progress(TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("{task.fields[last]}"), console=console) as bar:
        task = bar.add_task(label, total=total or None, last="")

        def rich_tick(done: int, text: str, alarm: bool = False, total: int | None = None) -> None:
            state["total"] = total or state["total"]
            if alarm:
                console.print(f"{done}/{state['total']} {text}")
            bar.update(task, completed=done, total=state["total"] or None, last=shortened(text, LAST_WIDTH))

        yield rich_tick
