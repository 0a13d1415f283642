"""The shape of the package (issue 24, "a house with no circles"): no import cycle among magyro's modules,
and no module over 450 lines.

The imports are read from the source with ast, every `import` and `from ... import` statement wherever it
stands (inside functions and `if TYPE_CHECKING:` blocks too), so a cycle hidden in a function-level import
counts. `from magyro.x import y` is an edge to the module magyro.x.y when that is a module, else to magyro.x;
the parent packages that Python loads on the way are not edges (a package's __init__ importing its own
submodules is how packages work, not a cycle).
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1] / "magyro"
MAX_LINES = 450


def module_files() -> dict[str, Path]:
    """Every magyro module by its dotted name."""
    modules = {}
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def imported_modules(name: str, path: Path, known: set[str]) -> set[str]:
    """The magyro modules that module `name` (source at `path`) imports, anywhere in its body."""
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module
            for alias in node.names:
                submodule = f"{source}.{alias.name}"
                found.add(submodule if submodule in known else source)
    return {m for m in found if m in known and m != name}


def import_graph() -> dict[str, set[str]]:
    modules = module_files()
    known = set(modules)
    return {name: imported_modules(name, path, known) for name, path in modules.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module (each one a circle of imports)."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def test_the_walker_sees_function_level_and_relative_imports(tmp_path):
    """The walker itself: a cycle through an import inside a function, and a relative import, are found."""
    pkg = tmp_path / "magyro" / "sub"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from magyro.sub.b import g\n    return g\n")
    (pkg / "b.py").write_text("from . import c\n")
    (pkg / "c.py").write_text("from .a import f\n")
    known = {"magyro.sub", "magyro.sub.a", "magyro.sub.b", "magyro.sub.c"}
    graph = {name: imported_modules(name, pkg / (name.split(".")[-1] + ".py"), known) for name in sorted(known - {"magyro.sub"})}
    graph["magyro.sub"] = set()
    assert graph["magyro.sub.a"] == {"magyro.sub.b"}
    assert graph["magyro.sub.b"] == {"magyro.sub.c"}
    assert graph["magyro.sub.c"] == {"magyro.sub.a"}
    assert strongly_connected(graph) == [["magyro.sub.a", "magyro.sub.b", "magyro.sub.c"]]


def test_no_import_cycle_among_magyro_modules():
    graph = import_graph()
    assert len(graph) > 50                      # the walk found the package
    circles = strongly_connected(graph)
    described = ["; ".join(f"{a} -> {b}" for a in circle for b in sorted(graph[a]) if b in circle) for circle in circles]
    assert not circles, "import cycles:\n" + "\n".join(described)


def test_no_module_over_450_lines():
    counts = {name: len(path.read_text(encoding="utf-8").splitlines()) for name, path in module_files().items()}
    too_long = {name: n for name, n in sorted(counts.items()) if n > MAX_LINES}
    assert not too_long, f"modules over {MAX_LINES} lines (split each by meaning): {too_long}"
