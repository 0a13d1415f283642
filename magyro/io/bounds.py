"""Bounds on a parsed tree of input (JSON, TOML): how deep it nests and how long its integers are (issue 25).

A file nested 50,000 deep or holding a 401-digit integer is refused naming the key path, before any reader
turns it into a recursion or an overflow error.
"""
from __future__ import annotations

MAX_DEPTH = 64          # magyro's own files nest at most 6 levels
MAX_INT_DIGITS = 40     # counts and seeds: a few digits; no quantity needs more than a float's range


def tree_problem(data, max_depth: int = MAX_DEPTH, max_int_digits: int = MAX_INT_DIGITS) -> str | None:
    """What is out of bounds in `data` (nested dicts and lists), with its key path; None when nothing is.
    Iterative, so a deep tree cannot exhaust Python's stack here."""
    stack = [(data, "", 0)]
    while stack:
        value, path, depth = stack.pop()
        if depth > max_depth:
            return f"{path or 'the top'} is nested deeper than {max_depth} levels"
        if isinstance(value, dict):
            stack.extend((v, f"{path}.{k}" if path else str(k), depth + 1) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, f"{path}[{i}]", depth + 1) for i, v in enumerate(value))
        elif isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10 ** max_int_digits:
            return f"{path or 'the top'} is an integer of more than {max_int_digits} digits"
    return None
