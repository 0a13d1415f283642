"""The repository's scripts (docs/make_*.py, benchmarks/) loaded as modules by the tests that check them."""
from __future__ import annotations

import importlib.util
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"


def load_script(path: Path):
    """A script of the repository (not part of the package) as a module."""
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
