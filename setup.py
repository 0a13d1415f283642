"""Everything is declared in pyproject.toml; this file only adds one build step: compiling magyro's
solver kernels into the package being installed (magyro/nls/installed.py), so that the first solve
on a machine compiles nothing. Without a C compiler, or if it fails, the install goes on and the
first solve compiles (or interprets) the kernels instead."""
import shutil
import sys
import time
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution


class BuildWithKernels(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):   # an editable install compiles on first use, into the cache
            return
        target = Path(self.build_lib) / "magyro" / "nls" / "installed_kernels"
        shutil.rmtree(target, ignore_errors=True)   # a reused build folder keeps earlier builds' kernels: ship today's only
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        try:
            from magyro.nls.installed import install_kernels

            start_s = time.perf_counter()
            built = install_kernels(target)
            print(f"magyro: compiled {len(built)} solver kernels into the package in "   # benchmarks/bench_cold_start.py reads it
                  f"{time.perf_counter() - start_s:.1f} s", file=sys.stderr)
        except Exception as error:  # never fail the install over a speed-up
            print(f"magyro: solver kernels not compiled at install ({error}); the first solve compiles them",
                  file=sys.stderr)
        finally:
            sys.path.pop(0)


class PlatformSpecific(Distribution):
    def has_ext_modules(self):   # the wheel holds compiled libraries: it is not pure Python
        return True


setup(cmdclass={"build_py": BuildWithKernels}, distclass=PlatformSpecific)
