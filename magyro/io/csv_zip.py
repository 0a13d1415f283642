"""A zip's CSV members unpacked with bounded memory and disk, or one refusal naming the member and the cause.

`unpack_csv_members(archive, unpack_to, wanted)` checks every member it would read before
unpacking any (encrypted, a compression Python's zipfile cannot read such as Deflate64, a
declared size beyond the caps), then streams each one to disk in READ_CHUNK_BYTES pieces,
counting what it inflates: a member inflating beyond MAX_MEMBER_BYTES, or all beyond
MAX_TOTAL_BYTES, is refused when the cap is reached, whatever its header says (a zip bomb
never reaches memory), and so is a member whose data fail their CRC-32. Members are
written under `unpack_to` by index and file name (no path from the zip is followed) and
labelled ARCHIVE:MEMBER. The archive is only read.
"""
from __future__ import annotations

import zipfile
import zlib
from pathlib import Path
from typing import Callable

from magyro.errors import InputError, one_line

MAX_MEMBER_BYTES = 128 * 2**20     # one CSV inflated: 2 million rows of 65 bytes, 5 h of a phone's sensor at 100 Hz
MAX_TOTAL_BYTES = 160 * 2**20      # all CSVs read from one zip: 240 MiB of CSV peaked at 0.97 GiB resident; 160 keeps a margin
MAX_MEMBERS = 100_000              # entries in the zip's directory
READ_CHUNK_BYTES = 2**20
_READABLE = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate", zipfile.ZIP_BZIP2: "bzip2",
             zipfile.ZIP_LZMA: "LZMA"}
_KNOWN_METHODS = {9: "Deflate64", 10: "PKWARE implode", 6: "implode", 93: "Zstandard", 95: "xz", 96: "JPEG",
                  97: "WavPack", 98: "PPMd", 99: "AES encryption"}


def is_zip(path: Path) -> bool:
    try:
        return path.is_file() and zipfile.is_zipfile(path)
    except OSError:
        return False


def unpack_csv_members(archive: Path, unpack_to: Path,
                       wanted: Callable[[str], bool] = lambda name: True) -> list[tuple[Path, str]]:
    """(unpacked path, "ARCHIVE:MEMBER") of each CSV member outside meta/ and __MACOSX/ folders that `wanted(file name)`."""
    try:
        with zipfile.ZipFile(archive) as z:
            infos = z.infolist()
            if len(infos) > MAX_MEMBERS:
                raise InputError(f"{archive}: the zip lists {len(infos)} entries, more than the {MAX_MEMBERS} "
                                 f"an export holds; unzip it and give the CSV files")
            members = [i for i in sorted(infos, key=lambda i: i.filename) if _is_csv_member(i, wanted)]
            _check_readable(archive, members)
            budget = [MAX_TOTAL_BYTES]
            return [_unpacked(z, archive, info, unpack_to / f"{k}", budget) for k, info in enumerate(members)]
    except zipfile.BadZipFile as exc:
        raise InputError(f"{archive}: not a readable zip ({one_line(exc)}); export it again") from None


def _is_csv_member(info: zipfile.ZipInfo, wanted: Callable[[str], bool]) -> bool:
    parts = Path(info.filename).parts
    return (not info.is_dir() and bool(parts) and info.filename.lower().endswith(".csv")
            and "meta" not in parts[:-1] and parts[0] != "__MACOSX" and wanted(parts[-1]))


def _check_readable(archive: Path, members: list[zipfile.ZipInfo]) -> None:
    """Before anything is unpacked: no member encrypted, compressed in a way zipfile cannot read, or declared too big."""
    for info in members:
        where = f"{archive}: member {info.filename}"
        if info.flag_bits & 0x1 or info.compress_type == 99:
            raise InputError(f"{where} is encrypted; unzip it with its password and give the CSV files")
        if info.compress_type not in _READABLE:
            method = _KNOWN_METHODS.get(info.compress_type, f"method {info.compress_type}")
            raise InputError(f"{where} is compressed with {method}, which magyro cannot read (it reads "
                             f"{', '.join(_READABLE.values())}); unzip it with another tool and give the CSV files, "
                             f"or zip them again with ordinary deflate")
        if info.file_size > MAX_MEMBER_BYTES:
            raise InputError(f"{where} inflates to {_mib(info.file_size)}, beyond the {_mib(MAX_MEMBER_BYTES)} "
                             f"cap on one CSV member; unzip it and give the CSV files")
    total = sum(info.file_size for info in members)
    if total > MAX_TOTAL_BYTES:
        raise InputError(f"{archive}: its CSV members inflate to {_mib(total)}, beyond the {_mib(MAX_TOTAL_BYTES)} "
                         f"cap on one zip; unzip it and give the CSV files")


def _unpacked(z: zipfile.ZipFile, archive: Path, info: zipfile.ZipInfo, folder: Path,
              budget: list[int]) -> tuple[Path, str]:
    """The member streamed to folder/NAME, counting inflated bytes against the caps (the header may lie);
    `budget` holds the bytes all members may still inflate to."""
    where = f"{archive}: member {info.filename}"
    target = folder / _local_name(Path(info.filename).name)
    folder.mkdir(parents=True, exist_ok=True)
    written = 0
    try:
        with z.open(info) as src, open(target, "wb") as dst:
            while chunk := src.read(READ_CHUNK_BYTES):
                written += len(chunk)
                if written > MAX_MEMBER_BYTES:
                    raise InputError(f"{where} inflates beyond the {_mib(MAX_MEMBER_BYTES)} cap on one CSV member "
                                     f"(its header says {_mib(info.file_size)}); it is not an export")
                budget[0] -= len(chunk)
                if budget[0] < 0:
                    raise InputError(f"{archive}: its CSV members inflate beyond the {_mib(MAX_TOTAL_BYTES)} cap "
                                     f"on one zip; unzip it and give the CSV files")
                dst.write(chunk)
    except zipfile.BadZipFile as exc:
        cause = "its data fail their CRC-32 check" if "CRC" in str(exc) else one_line(exc)
        raise InputError(f"{where} is damaged ({cause}); the zip is corrupt: export or copy it again") from None
    except (zlib.error, EOFError) as exc:
        raise InputError(f"{where} is damaged (cannot be inflated: {one_line(exc)}); the zip is corrupt: "
                         f"export or copy it again") from None
    return target, f"{archive}:{info.filename}"


MAX_LOCAL_NAME_BYTES = 200


def _local_name(name: str) -> str:
    """The member's own file name to unpack it under (an app's files are recognised by it), or, when the file
    system could not hold it (too long, control characters), a plain one."""
    if name.isprintable() and len(name.encode("utf-8", "surrogateescape")) <= MAX_LOCAL_NAME_BYTES:
        return name
    return "member.csv"


def _mib(n_bytes: int) -> str:
    mib = n_bytes / 2**20
    return f"{mib:.0f} MiB" if mib >= 10 or mib == int(mib) else f"{mib:.3f} MiB"
