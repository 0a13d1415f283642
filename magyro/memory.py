"""Freed memory given back to the system before a phase that needs much of its own.

A long session's front end and problem set-up free many whole-session temporaries. glibc keeps the freed blocks in
its heap (resident, and scattered among live ones, so the heap's top cannot shrink) and Arrow's allocator keeps what
reading the Parquet file freed: at 360k samples 160 MB were resident but free when IPOPT started, and IPOPT's own
matrices came on top of them.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import sys
from functools import lru_cache


@lru_cache(maxsize=1)
def _malloc_trim():
    """glibc's malloc_trim, or None (another C library, another system)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        trim = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return trim


def give_back() -> None:
    """Return the free memory of Arrow's pool (when pyarrow is loaded) and of glibc's heap (every free page, not
    only the top's: malloc_trim(0)) to the system. A few milliseconds; nothing live moves."""
    arrow = sys.modules.get("pyarrow")
    if arrow is not None:
        arrow.default_memory_pool().release_unused()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
