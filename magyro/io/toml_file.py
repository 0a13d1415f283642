"""TOML files read in one place (problem files, acceptance limits), refused with one plain message."""
from __future__ import annotations

from pathlib import Path

from magyro.errors import InputError, one_line
from magyro.io.bounds import MAX_DEPTH, tree_problem

MAX_TOML_BYTES = 4 * 2 ** 20   # a problem or limits file is a few kB

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
        if path.stat().st_size > MAX_TOML_BYTES:
            raise InputError(f"{what}: larger than a TOML file magyro reads can be ({MAX_TOML_BYTES // 2 ** 20} MiB)")
        text = path.read_text(encoding="utf-8")
    except PermissionError:
        raise InputError(f"{what}: cannot be read: permission denied (unreadable input)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{what}: cannot read ({one_line(exc, limit=None)})") from None
    return parse_toml(text, what)


def parse_toml(text: str, what: str = "the TOML text") -> dict:
    """TOML text as a dict (tomllib, or tomli on Python 3.10), bounded in depth and integer length
    (`magyro.io.bounds`); InputError naming `what` and the key path otherwise."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{what}: not valid TOML ({one_line(exc, limit=None)})") from None
    except RecursionError:
        raise InputError(f"{what}: not usable TOML (nested too deep; at most {MAX_DEPTH} levels)") from None
    except ValueError as exc:    # e.g. Python's own limit on an integer's digits
        raise InputError(f"{what}: not usable TOML ({one_line(exc)})") from None
    problem = tree_problem(data)
    if problem is not None:
        raise InputError(f"{what}: not usable TOML ({problem})")
    return data
