"""The client's compiled kernels for Dask workers: a worker plugin (imported only with `--scheduler`).

Registered by `magyro.executor.DaskCluster` when it connects: every worker that joins
writes the client's cached kernel libraries into its own kernel cache (a library
already there is left alone), so a worker on another machine compiles nothing the
client already has, once when it joins rather than with every task.
"""
from __future__ import annotations

import os
from pathlib import Path

from distributed.diagnostics.plugin import WorkerPlugin

KERNEL_SHIPPING_LIMIT_BYTES = 64 * 2**20   # the client's cache beyond this is not shipped (workers compile)


class KernelCache(WorkerPlugin):
    """A Dask worker plugin carrying the client's compiled kernels: written into each worker's kernel cache when
    it joins (a library already there is left alone), so a worker on another machine compiles nothing the
    client already has."""

    name = "magyro-kernels"

    def __init__(self, libraries: dict[str, bytes]):
        self.libraries = libraries

    @classmethod
    def from_local_cache(cls) -> "KernelCache":
        from magyro.nls.kernels import cache_dir

        libraries, total = {}, 0
        for lib in sorted(Path(cache_dir()).glob("*.so"), key=lambda p: -p.stat().st_mtime):
            size = lib.stat().st_size
            if total + size > KERNEL_SHIPPING_LIMIT_BYTES:
                break
            libraries[lib.name] = lib.read_bytes()
            total += size
        return cls(libraries)

    def setup(self, worker=None) -> None:
        from magyro.nls.kernels import cache_dir

        folder = Path(cache_dir())
        folder.mkdir(parents=True, exist_ok=True)
        for name, data in self.libraries.items():
            target = folder / name
            if target.exists():
                continue
            tmp = folder / f".{name}.{os.getpid()}.tmp"
            tmp.write_bytes(data)
            os.replace(tmp, target)

    def teardown(self, worker=None) -> None:
        return None
