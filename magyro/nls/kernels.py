"""Compiled CasADi kernels: installed with magyro, or compiled once and cached on disk.

The per-interval kernels do not depend on the session's length, its rates or
the loss, only on the stride (grid.STRIDES), so installing magyro compiles the
usual strides' kernels into the package (setup.py, `install_kernels`) and a
first solve compiles nothing. Any other shape (a stride of the user's, a
moving hard iron, no time offset) has its C code generated once, compiled
with the machine's C compiler and kept in a cache folder keyed by a hash of the
code. Later runs load the shared library in milliseconds. Without a compiler
(or with MAGYRO_JIT=0) the interpreted kernel is used: same numbers, slower.

The kernels of one shape are compiled side by side (one compiler process each)
at -O2, the level measured fastest to evaluate: the three kernels mapped over the
30,000 intervals of a 360k-sample session took 1.42 s a pass at -O1, 1.22 s at
-O2 and 1.28 s at -O3 (best of 5 interleaved rounds on the 2-core machine; the
Gauss-Newton kernel 1.08 / 0.89 / 0.93 s), with outputs equal bit for bit;
compiling them side by side took 24.5 / 33.2 / 27.3 s under load, paid once
(at install for the installed shapes). -march=native was faster still (0.98 s)
but changes the rounding (FMA, 7e-12) and ties a library to the CPU it was built
on. On a terminal, a line on stderr says that it is compiling and why.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca

COMPILE_FLAGS = ["-O2", "-shared", "-fPIC"]
INSTALLED = Path(__file__).with_name("installed_kernels")   # filled when magyro is installed (setup.py)


def cache_dir() -> Path:
    root = os.environ.get("MAGYRO_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "magyro"
    )
    return Path(root)


def jit_enabled() -> bool:
    return os.environ.get("MAGYRO_JIT", "1") not in ("0", "false", "no") and find_compiler() is not None


def find_compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


def compile_kernels(fns: list[ca.Function], key: str) -> list[ca.Function]:
    """The kernels of one shape as compiled external functions (installed, cached, or compiled now, the
    compilers side by side), each the SX function itself where compiling is not possible.

    `key` must determine the kernels completely (their shape parameters); the library files are named by
    it, by the source of the modules that build kernels and by the CasADi version, so C code is generated
    only on a cache miss.
    """
    if not jit_enabled():
        return list(fns)
    libs = [existing_library(fn.name(), key) or library_path(fn.name(), key) for fn in fns]
    missing = [(fn, lib) for fn, lib in zip(fns, libs) if not lib.exists()]
    if missing:
        say_compiling(len(missing), key)
        build_libraries([(generate_c(fn), lib) for fn, lib in missing])
    return [ca.external(fn.name(), str(lib)) if lib.exists() else fn for fn, lib in zip(fns, libs)]


def say_compiling(count: int, key: str) -> None:
    """One line on stderr, on a terminal only (a log or a test sees nothing)."""
    if sys.stderr.isatty():
        print(f"magyro: compiling {count} solver kernels for this session's shape ({key}); once per machine "
              "and shape, some seconds", file=sys.stderr, flush=True)


def library_name(name: str, key: str) -> str:
    return f"{name}_{cache_digest(key)}.so"


def library_path(name: str, key: str) -> Path:
    """Where the kernel is cached when this machine compiles it."""
    return cache_dir() / library_name(name, key)


def existing_library(name: str, key: str) -> Path | None:
    """The kernel's shared library as installed with magyro, else as cached, else None."""
    for lib in (INSTALLED / library_name(name, key), library_path(name, key)):
        if lib.exists():
            return lib
    return None


def load_cached_kernel(name: str, key: str) -> ca.Function | None:
    """The compiled kernel `name` for `key` if it is in the cache (and compiling is on), else None."""
    if not jit_enabled():
        return None
    lib = existing_library(name, key)
    return ca.external(name, str(lib)) if lib is not None else None


def cache_digest(key: str) -> str:
    sources = b"".join(Path(__file__).with_name(m).read_bytes() for m in ("interval.py", "kernels.py"))
    text = key.encode() + sources + " ".join(COMPILE_FLAGS).encode() + ca.__version__.encode()
    return hashlib.sha256(text).hexdigest()[:20]


def generate_c(fn: ca.Function) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        c_name = f"{fn.name()}.c"
        cg = ca.CodeGenerator(c_name, {"with_header": False})
        cg.add(fn)
        cg.generate(tmp + os.sep)
        return Path(tmp, c_name).read_bytes()


def build_libraries(jobs: list[tuple[bytes, Path]]) -> list[bool]:
    """Compile each (C source, library) pair, the compilers side by side; each library is written atomically
    (renamed into place when whole). False for a library whose compiler failed."""
    if not jobs:
        return []
    jobs[0][1].parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=jobs[0][1].parent) as tmp:
        running = []
        for k, (source, lib) in enumerate(jobs):
            src, out = Path(tmp, f"kernel{k}.c"), Path(tmp, f"{k}_{lib.name}")
            src.write_bytes(source)
            process = subprocess.Popen([find_compiler(), *COMPILE_FLAGS, str(src), "-o", str(out), "-lm"],
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            running.append((process, out, lib))
        done = []
        for process, out, lib in running:
            ok = process.wait() == 0
            if ok:
                os.replace(out, lib)
            done.append(ok)
    return done
