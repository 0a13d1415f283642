"""Where `magyro watch` reads its lines from, and how a line becomes samples.

A line is CSV, `t,gx,gy,gz,mx,my,mz`: time in seconds, the gyro (rad/s, or deg/s with
`--gyro-unit deg/s`), the magnetometer in any unit. Sensors sampled apart may come on lines
of their own, the other sensor's fields left empty: `t,gx,gy,gz,,,` and `t,,,,mx,my,mz`
(`t,gx,gy,gz` alone is a gyro line too). An accelerometer (m/s^2, the session format's
`ax ay az`) comes as three more fields, `t,gx,gy,gz,mx,my,mz,ax,ay,az`, or on lines of its
own, `t,,,,,,,ax,ay,az`; a stream without them is read as it always was. A header line, a line that is not numbers, a
sample with NaN/inf or a value beyond any sensor's range (MAX_ABS_VALUE), a line longer than
MAX_LINE_BYTES, or a sample whose time does not increase for its sensor is skipped and
counted (`LineCounts`), never fatal.

Sources (each an iterator of byte chunks, read by `LineReader` in a thread of its own so
that the display keeps moving while the input waits):

- standard input (`-`): until end of input;
- a serial port (`/dev/tty*`, `COM*`, or any path with `--serial`), at `--baud`, with pyserial
  (imported only then; missing, it is an InputError that says how to install it);
- a file still being written: followed like `tail -f`; `magyro watch` stops once it has
  not grown for `--idle` seconds.
"""
from __future__ import annotations

import math
import os
import queue
import re
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from magyro.errors import InputError

CHUNK_BYTES = 65536
FOLLOW_POLL_S = 0.05
SERIAL_TIMEOUT_S = 0.2
DEFAULT_BAUD = 115200
SERIAL_NAME = re.compile(r"^(/dev/tty|/dev/cu\.|/dev/serial/)|^COM\d+$", re.IGNORECASE)
GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
MAX_LINE_BYTES = 4096       # a sample line is under 200 bytes: a longer one is skipped as bad, never buffered whole
MAX_ABS_VALUE = 1e9         # a gyro (rad/s) or magnetometer reading beyond this is not a reading: skipped as bad
MAX_ABS_TIME_S = 1e12       # a time stamp beyond this (seconds; Unix time is 1.7e9) is not one: skipped as bad


# --------------------------------------------------------------------------- lines to samples


@dataclass
class LineCounts:
    """What the parser made of the lines so far (shown by the display)."""

    lines: int = 0            # non-empty lines
    gyro: int = 0             # gyro samples kept
    mag: int = 0              # magnetometer samples kept
    acc: int = 0              # accelerometer samples kept
    header: int = 0           # a first line that is not numbers
    bad: int = 0              # lines that are not `t,gx,gy,gz,mx,my,mz[,ax,ay,az]` (or a part of it)
    out_of_order: int = 0     # samples whose time does not increase for their sensor
    last_bad: str = field(default="", repr=False)

    @property
    def skipped(self) -> int:
        """What was left out that a user should hear of: bad lines and out-of-order samples (a header is expected)."""
        return self.bad + self.out_of_order

    def skipped_text(self) -> str:
        """"skipped 2 bad lines and 1 out-of-order sample" naming only what was skipped; "" when nothing was."""
        parts = [f"{n} {what}{'' if n == 1 else 's'}" for n, what in ((self.bad, "bad line"),
                                                                     (self.out_of_order, "out-of-order sample")) if n]
        return "skipped " + " and ".join(parts) if parts else ""

    def to_dict(self) -> dict:
        out = {"lines": self.lines, "gyro": self.gyro, "mag": self.mag, "header": self.header, "bad": self.bad,
               "out_of_order": self.out_of_order}
        if self.acc:
            out["acc"] = self.acc
        return out


class LineParser:
    """Bytes in, (gyro rows, magnetometer rows, accelerometer rows) out; rows are (t, x, y, z) tuples, gyro in
    rad/s, accelerometer in m/s^2 (no rows without `ax ay az` fields)."""

    def __init__(self, gyro_unit: str = "rad/s"):
        if gyro_unit not in GYRO_UNITS:
            raise InputError(f"--gyro-unit {gyro_unit!r}: give rad/s or deg/s")
        self.gyro_scale = GYRO_UNITS[gyro_unit]
        self.counts = LineCounts()
        self._tail: list[bytes] = []     # the pieces of a line not yet ended (joined once, when it ends)
        self._tail_bytes = 0
        self._dropping = False           # inside a line longer than MAX_LINE_BYTES: skipped up to its newline
        self._last_t = [-math.inf, -math.inf, -math.inf]

    def feed(self, data: bytes) -> tuple[list, list, list]:
        """Parse the complete lines in `data` (a partial last line waits for the rest). Linear in the input: a
        line's pieces are kept apart until it ends, and a line longer than MAX_LINE_BYTES is dropped as it grows."""
        lines = data.split(b"\n")
        last = lines.pop()
        complete = []
        if lines:   # the line waiting in the tail ends here
            first = lines.pop(0)
            if not self._dropping:
                complete.append(b"".join(self._tail) + first)
            self._tail, self._tail_bytes, self._dropping = [], 0, False
            complete += lines
        rows = self.parse_lines(complete)
        self._keep(last)
        return rows

    def _keep(self, piece: bytes) -> None:
        if self._dropping or not piece:
            return
        self._tail.append(piece)
        self._tail_bytes += len(piece)
        if self._tail_bytes > MAX_LINE_BYTES:
            self._tail, self._tail_bytes, self._dropping = [], 0, True
            self._too_long()

    def _too_long(self) -> None:
        self.counts.lines += 1
        self.counts.bad += 1
        self.counts.last_bad = f"a line longer than {MAX_LINE_BYTES} bytes"

    def finish(self) -> tuple[list, list, list]:
        """The last line, when the input ended without a newline."""
        tail = b"".join(self._tail)
        self._tail, self._tail_bytes, self._dropping = [], 0, False
        return self.parse_lines([tail]) if tail.strip() else ([], [], [])

    def parse_lines(self, lines) -> tuple[list, list, list]:
        gyro, mag, acc = [], [], []
        c = self.counts
        for raw in lines:
            if len(raw) > MAX_LINE_BYTES:
                self._too_long()
                continue
            line = raw.strip()
            if not line:
                continue
            c.lines += 1
            parts = line.split(b",")
            try:
                values = [float(p) if p.strip() else None for p in parts]
            except ValueError:
                self._bad(line, header=c.lines == 1)
                continue
            if len(values) == 4:
                values += [None, None, None]
            if len(values) not in (7, 10) or values[0] is None:
                self._bad(line)
                continue
            t = values[0]
            g, m, a = values[1:4], values[4:7], values[7:10]     # a: [] without accelerometer fields
            has_g, has_m, has_a = _complete(g), _complete(m), bool(a) and _complete(a)
            if (not has_g and any(v is not None for v in g)) or (not has_m and any(v is not None for v in m)) \
                    or (not has_a and any(v is not None for v in a)) \
                    or not (has_g or has_m or has_a) or not all(math.isfinite(v) for v in values if v is not None) \
                    or abs(t) > MAX_ABS_TIME_S or any(abs(v) > MAX_ABS_VALUE for v in values[1:] if v is not None):
                self._bad(line)
                continue
            if has_g:
                if t > self._last_t[0]:
                    s = self.gyro_scale
                    gyro.append((t, g[0] * s, g[1] * s, g[2] * s))
                    self._last_t[0] = t
                    c.gyro += 1
                else:
                    c.out_of_order += 1
            if has_m:
                if t > self._last_t[1]:
                    mag.append((t, m[0], m[1], m[2]))
                    self._last_t[1] = t
                    c.mag += 1
                else:
                    c.out_of_order += 1
            if has_a:
                if t > self._last_t[2]:
                    acc.append((t, a[0], a[1], a[2]))
                    self._last_t[2] = t
                    c.acc += 1
                else:
                    c.out_of_order += 1
        return gyro, mag, acc

    def _bad(self, line: bytes, header: bool = False) -> None:
        if header:
            self.counts.header += 1
        else:
            self.counts.bad += 1
            self.counts.last_bad = line[:80].decode("utf-8", "replace")


def _complete(xyz) -> bool:
    return all(v is not None for v in xyz)


# --------------------------------------------------------------------------- sources


def stdin_chunks() -> Iterator[bytes]:
    """Standard input, chunk by chunk as it arrives, until end of input."""
    fd = sys.stdin.fileno()
    while True:
        data = os.read(fd, CHUNK_BYTES)
        if not data:
            return
        yield data


def follow_chunks(path: Path, poll_s: float = FOLLOW_POLL_S) -> Iterator[bytes]:
    """A file from its start, then what is appended to it, like `tail -f` (never ends by itself:
    the caller stops after its idle time). While the file does not grow it yields b"" every `poll_s`."""
    with open(path, "rb") as f:
        while True:
            data = f.read(CHUNK_BYTES)
            yield data
            if not data:
                time.sleep(poll_s)


def serial_chunks(port: str, baud: int = DEFAULT_BAUD) -> Iterator[bytes]:
    """A serial port's bytes as they arrive (pyserial)."""
    ser = open_serial(port, baud)
    try:
        while True:
            yield ser.read(max(1, ser.in_waiting))    # b"" after SERIAL_TIMEOUT_S without bytes: a heartbeat
    finally:
        ser.close()


def open_serial(port: str, baud: int):
    try:
        import serial  # pyserial
    except ImportError:
        raise InputError(f"reading the serial port {port} needs pyserial, which is not installed: "
                         "pip install pyserial") from None
    try:
        return serial.Serial(port, baudrate=baud, timeout=SERIAL_TIMEOUT_S)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise InputError(f"cannot open the serial port {port} at {baud} baud: {exc}") from None


def is_serial_name(source: str) -> bool:
    return bool(SERIAL_NAME.search(source))


@dataclass(frozen=True)
class Source:
    kind: str            # "stdin" | "serial" | "file"
    name: str            # as the user gave it
    baud: int = DEFAULT_BAUD

    def chunks(self) -> Iterator[bytes]:
        if self.kind == "stdin":
            return stdin_chunks()
        if self.kind == "serial":
            return serial_chunks(self.name, self.baud)
        return follow_chunks(Path(self.name))


def resolve_source(source: str, serial: bool = False, baud: int = DEFAULT_BAUD) -> Source:
    """`-` standard input; a serial device (by its name, or any path with `serial`); else a file to follow."""
    if source == "-":
        if serial:
            raise InputError("--serial with SOURCE '-': give the serial device's path (e.g. /dev/ttyUSB0)")
        return Source("stdin", "-")
    if serial or is_serial_name(source):
        return Source("serial", source, baud)
    path = Path(source)
    if not path.exists():
        raise InputError(f"{source}: no such file (SOURCE is '-' for standard input, a serial device such as "
                         "/dev/ttyUSB0 or COM3, or a file being written)")
    if path.is_dir():
        raise InputError(f"{source}: is a folder; give the file being written")
    return Source("file", source)


# --------------------------------------------------------------------------- the reader thread

END = None   # what the queue carries after the last batch


class LineReader:
    """Reads a source in a daemon thread and puts (gyro rows, magnetometer rows, accelerometer rows) batches on
    `batches`;
    after the input ends, END (None); an error in the source arrives as the exception itself."""

    def __init__(self, chunks: Iterator[bytes], parser: LineParser):
        self.chunks = chunks
        self.parser = parser
        self.batches: queue.Queue = queue.Queue()
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._run, name="magyro-watch-reader", daemon=True)

    def start(self) -> "LineReader":
        self.thread.start()
        return self

    def stop(self) -> None:
        """Ask the thread to end (at its source's next chunk or heartbeat; a blocked standard input keeps it,
        a daemon thread, until the process ends)."""
        self.stopped.set()

    def _run(self) -> None:
        try:
            for data in self.chunks:
                if self.stopped.is_set():
                    return
                if not data:
                    continue
                gyro, mag, acc = self.parser.feed(data)
                if gyro or mag or acc:
                    self.batches.put((gyro, mag, acc))
            gyro, mag, acc = self.parser.finish()
            if gyro or mag or acc:
                self.batches.put((gyro, mag, acc))
            self.batches.put(END)
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread
            self.batches.put(exc)
