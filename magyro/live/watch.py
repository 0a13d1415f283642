"""The watch: live excitation feedback on a stream of samples, the session saved whatever stops it.

    from magyro.live.watch import watch
    result = watch("-", output="session.parquet", status="status.jsonl")   # reads standard input
    print(result.summary)

`watch` reads a source (`magyro.live.sources`: standard input, a serial port, a file being written),
feeds an `ExcitationMonitor` (`magyro.live.monitor`) several times a second, shows each status
(`magyro.live.display`) and writes it as a JSON line when asked; at the end of input, after
`idle` seconds without data, on Ctrl-C or SIGTERM, it saves what it received as a session file,
atomically. `magyro watch` (magyro.cli.live) is this function on the command line.
"""
from __future__ import annotations

import queue
import signal
import time
from dataclasses import dataclass

from magyro.text import significant

UPDATE_EVERY_S = 0.05      # the monitor takes in new samples at most this often (wall clock) ...
IDLE_UPDATE_S = 0.25       # ... and at least this often while the input waits (a prediction may come in)
DEFAULT_FILE_IDLE_S = 10.0


class Stop(Exception):
    """SIGTERM: stop like Ctrl-C does (save what was received)."""


@dataclass
class WatchResult:
    """What `watch` ends with: the summary line, whether the session was written, the last status."""

    summary: str
    saved: bool
    status: object = None


def watch(source: str, *, output=None, status=None, serial: bool = False, baud: int = 115200, idle=None,
          gyro_unit: str = "rad/s", mag_unit: str = "unknown", targets=None, refresh: float = 2.0, quiet: bool = False,
          predictor_mode: str = "process", stream=None) -> "WatchResult":
    """The watch itself; the session is saved, when `output`, whatever stops it (end of input, idle, Ctrl-C,
    SIGTERM). Raises InputError for an unusable source or output (before any work)."""
    from magyro.io import check_outputs
    from magyro.live.display import StatusWriter, make_display
    from magyro.live.monitor import ExcitationMonitor
    from magyro.live.prediction import Predictor
    from magyro.live.sources import END, LineParser, LineReader, resolve_source
    from magyro.targets import targets_from

    src = resolve_source(source, serial=serial, baud=baud)
    check_outputs([src.name] if src.kind == "file" else [], [output, status])   # before any work
    targets = targets_from(targets)
    parser = LineParser(gyro_unit)
    if idle is None and src.kind == "file":
        idle = DEFAULT_FILE_IDLE_S
    predictor = Predictor(predictor_mode, refresh_s=refresh, targets=targets)
    monitor = ExcitationMonitor(targets, predictor, mag_unit=mag_unit, source=f"magyro watch {source}")
    chunks = src.chunks()
    if src.kind == "serial":
        chunks = _opened_first(chunks)      # an unusable port fails here, before the display starts
    predictor.warm_up()
    reader = LineReader(chunks, parser).start()
    writer = StatusWriter(status) if status is not None else None
    display = make_display(quiet, stream, source)
    previous_term = _on_sigterm()
    reason = "end of input"
    last = None
    saved = False
    error = None
    try:
        try:
            reason, last = _loop(monitor, reader, display, writer, parser, idle, END)
        except (KeyboardInterrupt, Stop) as stop:
            reason = "interrupted (Ctrl-C)" if isinstance(stop, KeyboardInterrupt) else "stopped (SIGTERM)"
        except Exception as exc:  # noqa: BLE001 - its own error too: what was received is saved, then it is raised
            error, reason = exc, "stopped by an error"
        finally:
            _set_signal(signal.SIGTERM, signal.SIG_IGN)
            old_int = _set_signal(signal.SIGINT, signal.SIG_IGN)     # the save is not to be cut short
            try:
                _quietly(display.close, predictor.close)
                monitor.predictor = None
                reader.stop()
                _quietly(lambda: _drain(reader, monitor, END))
                saved = _save(monitor, output)        # first: nothing after it may lose the recording
                if error is None and (monitor.gyro.n or monitor.mag.n):
                    try:
                        last = monitor.update(final=True)
                    except Exception as exc:  # noqa: BLE001 - the session is saved; the error is reported
                        error, reason = exc, "stopped by an error"
            finally:
                _set_signal(signal.SIGINT, old_int)
        if error is not None:
            from magyro.errors import MagyroError

            if isinstance(error, MagyroError):
                raise error
            raise RuntimeError(f"{type(error).__name__}: {error}; "
                               + (f"what was received is saved in {output}" if saved else "nothing was saved")) from error
        if reason in ("end of input",) or reason.startswith("no new data"):
            try:
                last = _final_prediction(monitor, targets) or last
            except KeyboardInterrupt:     # Ctrl-C during the last prediction: the session is already saved
                pass
        if writer is not None and last is not None:
            writer.write(last)
    finally:
        _set_signal(signal.SIGTERM, previous_term)
        if writer is not None:
            writer.close()
    return WatchResult(summary(reason, monitor, last, parser.counts, saved, output), saved, last)


def _loop(monitor, reader, display, writer, parser, idle, END):
    last_data = last_update = time.monotonic()
    status = None
    pending = False
    while True:
        try:
            item = reader.batches.get(timeout=UPDATE_EVERY_S)
        except queue.Empty:
            item = ()
        if item is END:
            return "end of input", status
        if isinstance(item, BaseException):
            raise item
        if item:
            monitor.add(*item)
            pending = True
            last_data = time.monotonic()
        now = time.monotonic()
        if (pending and now - last_update >= UPDATE_EVERY_S) or now - last_update >= IDLE_UPDATE_S:
            status = monitor.update()
            display.show(status, parser.counts)
            if writer is not None:
                writer.write(status)
            last_update, pending = now, False
        if idle is not None and now - last_data > idle:
            return f"no new data for {idle:g} s", status


def _drain(reader, monitor, END) -> None:
    """Take in what the reader parsed but the loop had not yet taken (after a stop)."""
    while True:
        try:
            item = reader.batches.get_nowait()
        except queue.Empty:
            return
        if item is END or isinstance(item, BaseException):
            return
        monitor.add(*item)


def _quietly(*steps) -> None:
    """Run each cleanup step; one that fails does not stop the others (nor the save after them)."""
    for step in steps:
        try:
            step()
        except Exception:  # noqa: BLE001 - a cleanup failure must not lose the recording
            pass


def _opened_first(chunks):
    """Start a generator so that opening its source (a serial port) raises here, in the main thread."""
    first = next(chunks, None)

    def rest():
        if first is not None:
            yield first
        yield from chunks
    return rest()


def _on_sigterm():
    def handler(signum, frame):
        raise Stop()
    return _set_signal(signal.SIGTERM, handler)


def _set_signal(sig, handler):
    """signal.signal, the previous handler returned; off the main thread (watch() called from a thread) nothing."""
    try:
        return signal.signal(sig, handler)
    except ValueError:
        return signal.getsignal(sig)


def _save(monitor, output) -> bool:
    if output is None:
        return False
    session = monitor.session()
    if session is None:
        return False
    from magyro.io import write_session

    write_session(session, output)
    return True


def _final_prediction(monitor, targets):
    """When the input ended by itself: magyro observe's prediction on the whole recording, at once."""
    from magyro.live.prediction import meets, predict_session

    session = monitor.session()
    if session is None or monitor.status is None or monitor.status.rank < 12:
        return None
    if monitor.prediction is not None and monitor.prediction.t_s >= monitor.status.t_s:
        return None
    monitor.prediction = predict_session(session, monitor.status.t_s, None, targets)
    if monitor.enough_at_s is None and meets(monitor.prediction, targets):
        monitor.enough_at_s = monitor.prediction.t_s
    predictor, monitor.predictor = monitor.predictor, None
    try:
        return monitor.update()
    finally:
        monitor.predictor = predictor


def enough_summary(enough_at_s, status) -> str:
    """ENOUGH (when) and whether the recording ended with the rest ENOUGH asked for."""
    from magyro.live.monitor import END_REST_S

    if enough_at_s is None:
        return "not enough yet: " + status.instruction
    if status.still_s >= END_REST_S:
        return f"ENOUGH since {enough_at_s:.1f} s, ended after {status.still_s:.1f} s still"
    return (f"ENOUGH since {enough_at_s:.1f} s, but ended {status.still_s:.1f} s after the device was last turned "
            f"(put it down {END_REST_S:g} s before you stop: the end rest checks the bias)")


def summary(reason: str, monitor, status, counts, saved: bool, output) -> str:
    acc = f", {counts.acc} accelerometer" if counts.acc else ""
    parts = [f"magyro watch: {reason}; {counts.gyro} gyro, {counts.mag} magnetometer{acc} samples"]
    if counts.skipped:
        parts.append(counts.skipped_text() + (f" (last bad: {counts.last_bad!r})" if counts.bad and counts.last_bad
                                              else ""))
    if status is not None:
        parts.append(f"{status.t_s:.1f} s, rank {status.rank}/12, coverage {100 * status.coverage:.0f}%")
        p = status.predicted
        if p is not None:
            parts.append("predicted 1-sigma " + ", ".join(f"{g} {significant(v)} (target {significant(status.targets[g])})"
                                                          for g, v in p.items()))
        parts.append(enough_summary(monitor.enough_at_s, status))
        if status.accelerometer is not None:
            from magyro.live.display import accelerometer_text, gravity_text

            parts.append(accelerometer_text(status.accelerometer, advice=True) + gravity_text(status).replace("  |", ";"))
    if output is not None:
        parts.append(f"session written to {output}" if saved else "nothing to save (no gyro or no magnetometer sample)")
    return "; ".join(parts)
