"""Atomic output: a file is either whole or absent.

Every output is written to a temporary file in the target directory, flushed to disk,
then `os.replace`d onto the target. On any failure (an exception, Ctrl-C) the temporary
file is removed and the target is left as it was.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable


def write_text_atomically(path, text: str) -> None:
    """Write `text` (UTF-8) to `path` so that the file is either whole or absent."""
    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    write_atomically(Path(path), write)


def write_atomically(path: Path, write: Callable[[str], None]) -> None:
    """Call `write(tmp)` on a temp file next to `path`, then rename it onto `path`.

    On any failure the temp file is removed and `path` is left as it was.
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        write(tmp)
        _fsync_file(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _fsync_file(path: str) -> None:
    with open(path, "rb+") as f:
        os.fsync(f.fileno())


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
