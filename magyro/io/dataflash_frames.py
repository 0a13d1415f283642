"""The framing of a binary DataFlash log (ArduPilot .bin), checked before pymavlink decodes it.

A DataFlash log is a run of messages, each `0xA3 0x95 TYPE` then a body laid out by the FMT message that
defined TYPE earlier in the log. FMT is type 128 and 89 bytes long: header (3), Type (B), Length (B),
Name (4 bytes), Format (16 bytes), Columns (64 bytes, comma-separated names). Length counts the whole
message, header included.

pymavlink's DFReader is lenient by design: it skips bytes it cannot frame (printing to the terminal), drops
messages whose FMT lies about their length, and stops quietly at a cut. Calibrating from such a log would use
whatever survived without a word, so `check_framing` walks every message first and refuses (InputError,
one message naming the byte offset) a log that is garbled (a message that does not start with 0xA3 0x95, a
type no FMT defined), whose FMT lies (a Length other than the one its Format needs, a Length under 3, a
format character DataFlash does not have, a Columns list of another count than the Format, a type defined
twice differently). A log cut inside its last message (a logger powered off while writing) is normal: that
partial message is dropped and counted (`Framing.tail_bytes`).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

HEAD = b"\xa3\x95"
FMT_TYPE = 128
FMT_LENGTH = 89
FMT_BODY = struct.Struct("<BB4s16s64s")
MIN_LENGTH = 3   # the header alone


@dataclass(frozen=True)
class MessageFormat:
    type: int
    length: int        # whole message, header included (bytes)
    name: str
    format: str
    columns: tuple


@dataclass
class Framing:
    formats: dict = field(default_factory=dict)   # type -> MessageFormat
    counts: dict = field(default_factory=dict)    # message name -> how many whole messages
    tail_bytes: int = 0                           # bytes of a last message cut short (dropped)
    size_bytes: int = 0


def struct_size(fmt: str, format_to_struct: dict) -> int | None:
    """Bytes a body of DataFlash format `fmt` takes; None when `fmt` holds a character DataFlash has not."""
    try:
        return struct.calcsize("<" + "".join(format_to_struct[c][0] for c in fmt))
    except KeyError:
        return None


def check_framing(data: bytes, path, format_to_struct: dict) -> Framing:
    """Every message of `data` framed by the FMT messages before it (see the module docstring); InputError else."""
    from magyro.errors import InputError

    framing = Framing(size_bytes=len(data))
    formats = {FMT_TYPE: MessageFormat(FMT_TYPE, FMT_LENGTH, "FMT", "BBnNZ",
                                       ("Type", "Length", "Name", "Format", "Columns"))}
    counts: dict = {}
    offset, n = 0, len(data)
    while offset < n:
        if n - offset < 3:
            framing.tail_bytes = n - offset
            break
        if data[offset:offset + 2] != HEAD:
            raise InputError(f"{path}: garbled DataFlash log: no message starts at byte {offset} (it holds "
                             f"0x{data[offset]:02x} 0x{data[offset + 1]:02x}, not 0xa3 0x95){_after(counts)}; "
                             f"the file is damaged or not a DataFlash .bin")
        msg_type = data[offset + 2]
        fmt = formats.get(msg_type)
        if fmt is None:
            raise InputError(f"{path}: garbled DataFlash log: the message at byte {offset} has type {msg_type}, "
                             f"which no FMT message before it defines{_after(counts)}; the file is damaged")
        if n - offset < fmt.length:
            framing.tail_bytes = n - offset
            break
        if msg_type == FMT_TYPE:
            defined = _read_fmt(data, offset, path, format_to_struct)
            known = formats.get(defined.type)
            if known is not None and known != defined:
                raise InputError(f"{path}: the FMT message at byte {offset} defines type {defined.type} "
                                 f"({defined.name}, {defined.format}) again, differently from before "
                                 f"({known.name}, {known.format}); the log is damaged")
            formats[defined.type] = defined
        counts[fmt.name] = counts.get(fmt.name, 0) + 1
        offset += fmt.length
    framing.formats, framing.counts = formats, counts
    return framing


def _read_fmt(data: bytes, offset: int, path, format_to_struct: dict) -> MessageFormat:
    """The FMT message at `offset`, checked: its Length is what its Format needs, its columns one per field."""
    from magyro.errors import InputError

    msg_type, length, name, fmt, columns = FMT_BODY.unpack_from(data, offset + 3)
    try:
        name, fmt, columns = (_text(b) for b in (name, fmt, columns))
    except UnicodeDecodeError:
        raise InputError(f"{path}: the FMT message at byte {offset} holds names that are not text; "
                         f"the log is damaged") from None
    where = f"{path}: the FMT message at byte {offset} (type {msg_type}, {name or 'no name'})"
    if not name:
        raise InputError(f"{where} has no name; the log is damaged")
    if msg_type == FMT_TYPE and (length != FMT_LENGTH or fmt != "BBnNZ"):
        raise InputError(f"{where} redefines FMT itself as {length} bytes, format {fmt!r}; FMT is 89 bytes, "
                         f"BBnNZ; the log is damaged")
    if length < MIN_LENGTH:
        raise InputError(f"{where} says its messages are {length} bytes long, shorter than their 3-byte header; "
                         f"the FMT lies: the log is damaged or forged")
    body = struct_size(fmt, format_to_struct)
    if body is None:
        bad = sorted({c for c in fmt if c not in format_to_struct})
        raise InputError(f"{where} has format {fmt!r} with character(s) {', '.join(bad)} that DataFlash does not "
                         f"have; the log is damaged")
    if body + MIN_LENGTH != length:
        raise InputError(f"{where} says its messages are {length} bytes long, but its format {fmt!r} needs "
                         f"{body + MIN_LENGTH} (3 header bytes + {body}); the FMT lies: the log is damaged or "
                         f"forged")
    names = tuple(c for c in columns.split(",")) if columns else ()
    if len(names) != len(fmt):
        raise InputError(f"{where} names {len(names)} column(s) ({columns or 'none'}) for the {len(fmt)} fields of "
                         f"its format {fmt!r}; the log is damaged")
    return MessageFormat(msg_type, length, name, fmt, names)


def _text(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("ascii").strip()


def _after(counts: dict) -> str:
    n = sum(counts.values())
    return f", after {n} whole messages" if n else ""
