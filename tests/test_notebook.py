"""docs/observability-notebook.ipynb: it runs without error, draws its figures, finds the theorem's ranks,
and is exactly what docs/make_observability_notebook.py makes (and stored without outputs).

The notebook is executed with nbclient on a python3 kernel of the running interpreter (ipykernel
installed in the same environment), in a temporary directory. `pytest -s` prints the time it took.
"""
from __future__ import annotations

import json
import os
import re
import sys
import time
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
NOTEBOOK = DOCS / "observability-notebook.ipynb"
GENERATOR = DOCS / "make_observability_notebook.py"
TIMEOUT_S = 300


def load_generator():
    from importlib.util import module_from_spec, spec_from_file_location

    spec = spec_from_file_location(GENERATOR.stem, GENERATOR)
    module = module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def stored_notebook() -> dict:
    return json.loads(NOTEBOOK.read_text(encoding="utf-8"))


def test_notebook_is_the_generators_output():
    pytest.importorskip("nbformat", reason="the notebook generator needs nbformat (pip install 'magyro[test]')")
    built = load_generator().build_notebook()
    stored = stored_notebook()
    assert [(c["cell_type"], "".join(c["source"])) for c in stored["cells"]] == \
        [(c["cell_type"], c["source"]) for c in built["cells"]], \
        "docs/observability-notebook.ipynb is stale: run python docs/make_observability_notebook.py"
    assert [c.get("id") for c in stored["cells"]] == [c["id"] for c in built["cells"]]
    assert stored["metadata"]["kernelspec"]["name"] == "python3"


def test_notebook_has_no_stored_outputs():
    for cell in stored_notebook()["cells"]:
        if cell["cell_type"] == "code":
            assert cell["outputs"] == [] and cell["execution_count"] is None, cell["id"]


def python3_kernel_of_this_interpreter(tmp_path: Path, monkeypatch) -> str:
    """The kernel name that runs `sys.executable`: "python3" when it resolves to this interpreter (ipykernel in
    this environment), otherwise a kernelspec written into tmp_path for it."""
    from jupyter_client.manager import KernelManager

    try:
        cmd = KernelManager(kernel_name="python3").format_kernel_cmd()
    except Exception:  # noqa: BLE001 - no python3 kernelspec at all: write our own below
        cmd = []
    if cmd and os.path.abspath(cmd[0]) == os.path.abspath(sys.executable):
        return "python3"
    name = "magyro-test-python3"
    spec_dir = tmp_path / "jupyter" / "kernels" / name
    spec_dir.mkdir(parents=True)
    (spec_dir / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": f"Python 3 ({sys.executable})", "language": "python"}), encoding="utf-8")
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter") + os.pathsep + os.environ.get("JUPYTER_PATH", ""))
    return name


def output_texts(nb) -> str:
    """Every text the executed notebook printed or displayed (stream text and text/plain)."""
    parts = []
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            if out.output_type == "stream":
                parts.append(out.text)
            elif out.output_type in ("execute_result", "display_data"):
                parts.append(out.get("data", {}).get("text/plain", ""))
    return "\n".join(parts)


def test_notebook_executes(tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat", reason="executing the notebook needs nbformat (pip install 'magyro[test]')")
    nbclient = pytest.importorskip("nbclient", reason="executing the notebook needs nbclient (pip install 'magyro[test]')")
    pytest.importorskip("ipykernel", reason="executing the notebook needs ipykernel (pip install 'magyro[test]')")
    pytest.importorskip("matplotlib", reason="the notebook's figures need matplotlib")

    kernel = python3_kernel_of_this_interpreter(tmp_path, monkeypatch)
    monkeypatch.setenv("MAGYRO_DATA", str(NOTEBOOK.resolve().parents[1] / "data"))   # the shipped sessions, wherever
    nb = nbformat.read(NOTEBOOK, as_version=4)                                        # magyro is installed
    client = nbclient.NotebookClient(nb, timeout=TIMEOUT_S, kernel_name=kernel,
                                     resources={"metadata": {"path": str(tmp_path)}})
    start = time.perf_counter()
    client.execute()
    seconds = time.perf_counter() - start
    print(f"\nexecuted {NOTEBOOK.name} in {seconds:.1f} s (kernel {kernel!r}, {sys.executable})")

    errors = [out for cell in nb.cells for out in cell.get("outputs", []) if out.output_type == "error"]
    assert not errors, [f"{e.ename}: {e.evalue}" for e in errors]
    images = [out for cell in nb.cells for out in cell.get("outputs", [])
              if out.output_type in ("display_data", "execute_result") and "image/png" in out.get("data", {})]
    assert len(images) >= 3, f"{len(images)} image/png outputs"
    text = output_texts(nb)
    # the theorem's ranks (docs/observability.md): still 2, one axis 6, two axes 9, three axes 12
    for name, rank in (("static", 2), ("axis-x", 6), ("two-axes", 9), ("three-axes", 12), ("paper-table1", 12)):
        assert re.search(rf"^{re.escape(name)}\s+rank {rank} of 12\b", text, flags=re.M), (name, rank)
