"""Text that leaves magyro is safe wherever it lands (issue 25): a terminal, a C comment, YAML, TOML, a params file.

A name or unit read from a file (session metadata, a calibration, a problem file) may hold terminal escapes
(ESC, C1 controls), NUL, DEL, line breaks or Unicode bidi overrides (the "Trojan Source" pattern). Every such
character is written as a visible escape (`\\x1b`, `\\u202e`) so it cannot act: `escaped(text)` for one line of
a terminal or a comment, `c_comment(text)` also keeps a C block comment closed, `ascii_escaped(text)` keeps
only printable ASCII. `unsafe_characters(text)` lists what would be escaped, for refusing a name outright.
"""
from __future__ import annotations

import math
import unicodedata

import numpy as np

# bidi controls (embeddings, overrides, isolates, marks): Unicode's own list of what reorders text
BIDI = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def is_unsafe(ch: str) -> bool:
    """True for a character that acts instead of showing: a control (C0, DEL, C1), a format character (bidi
    and other invisible ones), a line or paragraph separator, a surrogate or a private-use character."""
    return ch in BIDI or unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp")


def _escape(ch: str) -> str:
    code = ord(ch)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def unsafe_characters(text: str) -> list[str]:
    """The characters of `text` that `escaped` would escape, each as its escape (empty: the text is safe)."""
    return list(dict.fromkeys(_escape(ch) for ch in str(text) if is_unsafe(ch)))


def escaped(text, keep_lines: bool = False) -> str:
    """`text` with every control, bidi or invisible character written as a visible escape: safe on a terminal,
    in a comment, in a log line. Line breaks and tabs are escaped too (one line), unless `keep_lines`."""
    kept = "\n\t" if keep_lines else ""
    return "".join(_escape(ch) if is_unsafe(ch) and ch not in kept else ch for ch in str(text))


def ascii_escaped(text) -> str:
    """`escaped`, and every non-ASCII character as `\\uXXXX` too: plain printable ASCII."""
    return "".join(ch if " " <= ch <= "~" else _escape(ch) for ch in str(text))


def c_comment(text) -> str:
    """Text safe inside a C block comment on one line: printable ASCII only (no bidi for gcc's -Wbidi-chars),
    and neither `*/` (which would end it) nor `/*` (which -Wcomment warns about) can form."""
    out = ascii_escaped(text)
    while "*/" in out or "/*" in out:
        out = out.replace("*/", "* /").replace("/*", "/ *")
    return out


def toml_string(text) -> str:
    """A TOML basic string (quoted) holding `text` exactly: controls, DEL, bidi and non-ASCII escaped."""
    out = []
    for ch in str(text):
        if ch in '"\\':
            out.append("\\" + ch)
        elif " " <= ch <= "~":
            out.append(ch)
        else:
            code = ord(ch)
            out.append(f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return '"' + "".join(out) + '"'


MAX_NAME_CHARS = 100


def name_problem(name: str) -> str | None:
    """Why `name` cannot be one part of a file name (a problem name, a device id, a plan name), or None when it
    can: it must be 1 to 100 printable characters without a path separator, not '.' or '..', nor start with '.'
    (hidden, and the pattern of magyro's temporary files) or '-' (read as an option)."""
    name = str(name)
    if not name.strip():
        return "it is empty"
    if len(name) > MAX_NAME_CHARS:
        return f"it is longer than {MAX_NAME_CHARS} characters"
    bad = unsafe_characters(name)
    if bad:
        return f"it holds control or bidi characters ({', '.join(bad)})"
    if "/" in name or "\\" in name:
        return "it holds a path separator (/ or \\)"
    if name.startswith("."):
        return "it starts with '.'"
    if name.startswith("-"):
        return "it starts with '-'"
    return None


def file_name(name: str, what: str) -> str:
    """`name` when it can be one part of a file name (see `name_problem`); InputError naming `what` otherwise."""
    from magyro.errors import InputError

    why = name_problem(name)
    if why is not None:
        raise InputError(f"{what} '{escaped(str(name)[:MAX_NAME_CHARS])}' cannot name a file ({why}); use letters, "
                         "digits, '-' and '_'")
    return name


def significant(value: float, digits: int = 3) -> str:
    """`value` to `digits` significant digits, written out ("1600", "0.0146", "-0.5"): no exponent between
    1e-4 and 1e7 (":.3g" writes 1600 as "1.6e+03"), "-" for None and non-finite values."""
    if value is None or not math.isfinite(value):
        return "-"
    rounded = float(f"{value:.{digits}g}")
    if rounded == 0 or 1e-4 <= abs(rounded) < 1e7:
        return np.format_float_positional(rounded, trim="-")
    return f"{rounded:.{digits - 1}e}"


# how to add matplotlib, for every message that needs it: from PyPI, or from a clone (README's first command
# installs magyro from its clone, where 'magyro[plot]' would fetch another copy from PyPI)
PLOT_INSTALL = "pip install 'magyro[plot]', or pip install '.[plot]' in a clone of magyro"


ELLIPSIS = "..."


def shortened(text: str, width: int) -> str:
    """`text` on one line, whole when it fits in `width` characters, else cut at the last space that leaves room
    for ELLIPSIS (mid-word only when a single word is wider than `width`), never mid-word otherwise."""
    text = " ".join(str(text).split())
    if len(text) <= width:
        return text
    room = max(width - len(ELLIPSIS), 1)
    cut = text.rfind(" ", 0, room + 1)
    head = text[:cut] if cut > 0 else text[:room]
    return head.rstrip(" ,;:(") + ELLIPSIS
