"""Atomic output: a file is either whole or absent, and checked before any work.

`check_outputs(inputs, outputs)` runs at the start of every command that writes: an
output that is one of the inputs (or another output) or that cannot be written is
refused (InputError, exit 2) before a second is spent on the work, with a message that
names the paths and the cause.

Every output is written to a temporary file in the target directory, flushed to disk,
then `os.replace`d onto the target. On any failure (an exception, Ctrl-C) the temporary
file is removed and the target is left as it was; an OSError names the target, never
the temporary file.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable, Iterable

from magyro.errors import InputError, one_line


# --------------------------------------------------------------------------- before any work


def check_outputs(inputs: Iterable, outputs: Iterable) -> None:
    """Refuse, before any work, outputs that would destroy an input or cannot be written.

    `inputs` and `outputs` are paths (str or os.PathLike); None (an option not given)
    and other objects (a Calibration passed instead of its file) are skipped, and so
    are inputs that do not exist (a shipped problem's name; a missing file is the
    job's own exit 2). Raises InputError (exit 2) when an output is the same file as
    an input (same resolved path, or `os.path.samefile`: a symlink or hard link), when
    two outputs are the same file, or when an output cannot be written (a folder, not a
    regular file, its folder missing or not writable).
    """
    ins: dict = {}
    for p in inputs:
        if isinstance(p, (str, os.PathLike)) and os.path.exists(p):
            ins.update(dict.fromkeys(file_identities(Path(p)), Path(p)))
    checked: dict = {}
    for out in (Path(p) for p in outputs if isinstance(p, (str, os.PathLike))):   # linear: a fleet writes thousands
        keys = file_identities(out)
        inp = next((ins[k] for k in keys if k in ins), None)
        if inp is not None:
            raise InputError(
                f"the output {out} is the input {inp} (the same file); writing it would destroy the "
                f"input, which magyro never changes: choose another output path")
        other = next((checked[k] for k in keys if k in checked), None)
        if other is not None:
            raise InputError(
                f"two outputs are the same file: {other} and {out}; give each output its own path")
        check_writable(out)
        checked.update(dict.fromkeys(keys, out))


def confined(folder, name: str) -> Path:
    """folder/name, checked to stay inside `folder` once resolved (no '..', no absolute name, no symlinked way
    out); InputError naming the name otherwise. Every name read from input that becomes a path goes through here."""
    from magyro.text import escaped

    folder, name = Path(folder), str(name)
    path = folder / name
    if ("\0" in name or name in ("", ".", "..") or Path(name).is_absolute() or path.name != name
            or _resolved(path.parent) != _resolved(folder)):
        raise InputError(f"the name '{escaped(name[:100])}' would write outside {folder} (it holds a path or is "
                         "not a file name); nothing written")
    return path


def file_identities(p: Path) -> tuple:
    """What names one file, for lookups: its resolved path, and its device and inode when it exists (a symlink
    or a hard link is the file it points to). Two paths name the same file exactly when they share one."""
    keys = (("path", _resolved(p)),)
    try:
        if os.path.exists(p):
            st = os.stat(p)
            keys += (("inode", st.st_dev, st.st_ino),)
    except OSError:
        pass
    return keys


def _resolved(p: Path) -> Path:
    try:
        return p.resolve(strict=False)
    except (OSError, RuntimeError):  # a symlink loop
        return Path(os.path.abspath(p))


def check_writable(path: Path) -> None:
    """InputError unless `write_atomically(path, ...)` can create its temp file and replace `path`."""
    path = Path(path)
    where = f"cannot write the output {path}"
    try:
        _check_writable(path, where)
    except OSError as exc:  # e.g. a folder on the way that may not be searched
        raise InputError(f"{where}: {exc.strerror or one_line(exc)}; choose another path") from None


def _check_writable(path: Path, where: str) -> None:
    if path.is_dir():
        raise InputError(f"{where}: it is a folder; give a file name, e.g. {path / 'out.json'}")
    if path.exists() and not path.is_file():
        raise InputError(f"{where}: it exists and is not a regular file; give the path of a file (or leave the option out)")
    folder = path.parent
    if not folder.exists():
        raise InputError(f"{where}: its folder {folder} does not exist; create it first, or choose another path")
    if not folder.is_dir():
        raise InputError(f"{where}: {folder} is not a folder; choose another path")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{where}: its folder {folder} is not writable (no permission); "
                         f"choose another folder or change its permissions")
    try:  # what os.access cannot see: a read-only file system, root on /sys, quotas
        fd, probe = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".check")
    except OSError as exc:
        raise InputError(f"{where}: no file can be created in its folder {folder} "
                         f"({exc.strerror or one_line(exc)}); choose another folder") from None
    os.close(fd)
    os.unlink(probe)


# --------------------------------------------------------------------------- writing


def write_text_atomically(path, text: str) -> None:
    """Write `text` (UTF-8) to `path` so that the file is either whole or absent."""
    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    write_atomically(Path(path), write)


def write_atomically(path: Path, write: Callable[[str], None]) -> None:
    """Call `write(tmp)` on a temp file next to `path`, then rename it onto `path`.

    On any failure the temp file is removed and `path` is left as it was; an OSError
    (disk full, permission) is raised again naming `path`, not the temp file.
    """
    path = Path(path)
    remove_stale_temps(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise _naming_target(exc, path, None) from None
    os.close(fd)
    try:
        write(tmp)
        _fsync_file(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _naming_target(exc, path, tmp) from None
        raise


STALE_TEMP_S = 15 * 60   # a temp file of ours untouched this long belongs to a run that was killed
_swept: set = set()      # folders already swept by this process (a batch writes thousands of files into one)


def remove_stale_temps(path: Path, older_than_s: float = STALE_TEMP_S) -> int:
    """Remove the temp files killed runs left in `path`'s folder (`.NAME.XXXXXXXX.tmp` / `.check`, magyro's own
    pattern, untouched for `older_than_s`; a write in progress keeps its file fresh), once per folder and process.
    The number removed."""
    import re
    import time

    pattern = re.compile(r"^\..+\.[a-z0-9_]{8}\.(tmp|check)$")   # tempfile.mkstemp's names
    removed = 0
    folder = os.path.abspath(path.parent)
    if folder in _swept:
        return 0
    _swept.add(folder)
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    now = time.time()
    for entry in entries:
        try:
            if pattern.match(entry.name) and entry.is_file(follow_symlinks=False) \
                    and now - entry.stat(follow_symlinks=False).st_mtime > older_than_s:
                os.unlink(entry.path)
                removed += 1
        except OSError:
            pass
    return removed


def _naming_target(exc: OSError, path: Path, tmp: str | None) -> OSError:
    """`exc` as an OSError of the same kind whose file is the target `path` (the temp file never shows)."""
    if exc.errno is not None and exc.strerror:
        return OSError(exc.errno, exc.strerror, str(path))  # OSError(errno, ...) picks the subclass
    text = one_line(exc, None)
    if tmp:
        text = text.replace(tmp, str(path)).replace(Path(tmp).name, path.name)
    return OSError(f"{path}: {text}")


def _fsync_file(path: str) -> None:
    with open(path, "rb+") as f:
        os.fsync(f.fileno())


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
