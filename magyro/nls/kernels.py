"""Compiled CasADi kernels, cached on disk.

The per-interval kernels do not depend on the session's length, only on the
grid's shape (stride, sub-steps), so their C code is generated once, compiled
with the machine's C compiler and kept in a cache folder keyed by a hash of the
code. Later runs load the shared library in milliseconds. Without a compiler
(or with MAGYRO_JIT=0) the interpreted kernel is used: same numbers, slower.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

COMPILE_FLAGS = ["-O2", "-shared", "-fPIC"]


def cache_dir() -> Path:
    root = os.environ.get("MAGYRO_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "magyro"
    )
    return Path(root)


def jit_enabled() -> bool:
    return os.environ.get("MAGYRO_JIT", "1") not in ("0", "false", "no") and find_compiler() is not None


def find_compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


def compile_kernel(fn: ca.Function, key: str) -> ca.Function:
    """`fn` as a compiled external function (cached), or `fn` itself when compiling is not possible.

    `key` must determine the kernel completely (its shape parameters); the
    cache file is named by it, by the source of the modules that build kernels
    and by the CasADi version, so C code is generated only on a cache miss.
    """
    if not jit_enabled():
        return fn
    lib = library_path(fn.name(), key)
    if not lib.exists() and not build_library(generate_c(fn), lib):
        return fn
    return ca.external(fn.name(), str(lib))


def library_path(name: str, key: str) -> Path:
    return cache_dir() / f"{name}_{cache_digest(key)}.so"


def load_cached_kernel(name: str, key: str) -> ca.Function | None:
    """The compiled kernel `name` for `key` if it is in the cache (and compiling is on), else None."""
    if not jit_enabled():
        return None
    lib = library_path(name, key)
    return ca.external(name, str(lib)) if lib.exists() else None


def cache_digest(key: str) -> str:
    sources = b"".join(Path(__file__).with_name(m).read_bytes() for m in ("problem.py", "kernels.py"))
    text = key.encode() + sources + " ".join(COMPILE_FLAGS).encode() + ca.__version__.encode()
    return hashlib.sha256(text).hexdigest()[:20]


def generate_c(fn: ca.Function) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        c_name = f"{fn.name()}.c"
        cg = ca.CodeGenerator(c_name, {"with_header": False})
        cg.add(fn)
        cg.generate(tmp + os.sep)
        return Path(tmp, c_name).read_bytes()


def build_library(source: bytes, lib: Path) -> bool:
    """Compile C source into `lib` atomically; False when the compiler fails."""
    lib.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=lib.parent) as tmp:
        src = Path(tmp, "kernel.c")
        src.write_bytes(source)
        out = Path(tmp, lib.name)
        done = subprocess.run(
            [find_compiler(), *COMPILE_FLAGS, str(src), "-o", str(out), "-lm"],
            capture_output=True,
        )
        if done.returncode != 0:
            return False
        os.replace(out, lib)
    return True
