"""Public names of a package, imported from their modules on first use.

The solve path must import neither pandas nor scipy (each costs 0.2-0.4 s on
every run), so a package's `__init__` names what it offers without importing
it: `__getattr__, __dir__ = lazy_exports(__name__, {"name": "module", ...})`.
"""
from __future__ import annotations

import importlib


def lazy_exports(package: str, exports: dict[str, str]):
    """(__getattr__, __dir__) for `package`, whose name `n` is `exports[n]`'s attribute `n`.

    A module path without a dot is taken inside the package. The value is kept
    in the package's namespace, so each name is looked up once.
    """
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name: str):
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module if "." in module else f"{package}.{module}"), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
