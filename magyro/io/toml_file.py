"""TOML files read in one place (problem files, acceptance limits), refused with one plain message."""
from __future__ import annotations

from pathlib import Path

from magyro.errors import InputError, one_line

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


def read_toml(path, what: str | None = None) -> dict:
    """The TOML file at `path` as a dict; InputError naming `what` (default: the path) when it is not valid
    TOML or cannot be read."""
    path = Path(path)
    what = what or str(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{what}: not valid TOML ({one_line(exc, limit=None)})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{what}: cannot read ({one_line(exc, limit=None)})") from None


def parse_toml(text: str) -> dict:
    """TOML text as a dict (tomllib, or tomli on Python 3.10)."""
    return tomllib.loads(text)
