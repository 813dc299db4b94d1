"""The package's shape: imports flow one way (no circles, no upward imports) and modules stay small.

Every ``import`` of a spiralbayes module is read from the source (top level and inside functions,
relative and absolute), so a lazy import cannot hide a circle. Layers, lowest first — a module may
import its own layer and the ones below it, never one above:

0. base: ``exceptions``, ``units``, ``_version``, ``_provenance``, ``_hdf5``, ``_casa``
1. data: ``geometry``, ``layout``, ``visibilities``, ``fourier``, ``io``
2. models: ``axisymmetric``, ``templates``, ``quadrature``, ``model``
3. synthetic data: ``simulate``
4. inference: ``inference``
5. outputs: ``plotting``, ``baselines``
6. runners: ``pipeline``, ``config``, ``cli`` and the package's ``__init__``
"""

import ast
from pathlib import Path

import spiralbayes

PACKAGE = Path(spiralbayes.__file__).parent
LAYERS = {
    "exceptions": 0, "units": 0, "_version": 0, "_provenance": 0, "_hdf5": 0, "_casa": 0,
    "geometry": 1, "layout": 1, "visibilities": 1, "fourier": 1, "io": 1,
    "axisymmetric": 2, "templates": 2, "model": 2, "asymmetries": 2, "quadrature": 2,
    "simulate": 3,
    "inference": 4,
    "plotting": 5, "baselines": 5,
    "pipeline": 6, "config": 6, "cli": 6, "": 6,
}
MAX_LINES = 500
LONG_MODULE_MARKER = "Why this module is long:"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(["spiralbayes", *parts])


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imported_modules(name: str, path: Path, known: set[str]) -> set[str]:
    """spiralbayes modules imported anywhere in ``path`` (a ``from pkg import sub`` counts ``pkg.sub``)."""
    is_package = path.name == "__init__.py"
    here = name.split(".") if is_package else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "spiralbayes"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "spiralbayes":
                continue
            subs = {f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in known}
            found |= subs or {target}
    return {m for m in found if m in known and m != name}


def import_graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imported_modules(name, path, known) for name, path in mods.items()}


def layer(name: str) -> int:
    top = name.split(".")[1] if "." in name else ""
    assert top in LAYERS, f"module {name} has no layer: add its top-level name to LAYERS in this test"
    return LAYERS[top]


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def package_parents(name: str) -> set[str]:
    parts = name.split(".")
    return {".".join(parts[:k]) for k in range(1, len(parts))}


def test_the_graph_sees_lazy_and_relative_imports():
    graph = import_graph()
    assert "spiralbayes.inference.scan.engine" in graph["spiralbayes.inference.scan.run"]
    assert "spiralbayes.io.measurement_set" in graph["spiralbayes.io"]
    assert "spiralbayes.pipeline" in graph["spiralbayes.cli"]  # imported inside functions


def test_no_import_circles():
    graph = import_graph()
    # a package's __init__ importing its own submodules is not a circle with them
    pruned = {m: {d for d in deps if d not in package_parents(m)} for m, deps in graph.items()}
    cycle = find_cycle(pruned)
    assert cycle is None, "import circle: " + " -> ".join(cycle)


def test_no_upward_imports():
    graph = import_graph()
    upward = [f"{m} (layer {layer(m)}) imports {d} (layer {layer(d)})"
              for m, deps in graph.items() for d in deps if layer(d) > layer(m)]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_modules_are_small_or_say_why():
    long = []
    for name, path in modules().items():
        text = path.read_text()
        n = text.count("\n")
        docstring = ast.get_docstring(ast.parse(text)) or ""
        if n > MAX_LINES and LONG_MODULE_MARKER not in docstring:
            long.append(f"{name}: {n} lines")
    assert not long, f"modules over {MAX_LINES} lines without '{LONG_MODULE_MARKER}' in their docstring: {long}"


def test_public_api_is_importable_and_complete():
    for name in spiralbayes.__all__:
        assert hasattr(spiralbayes, name), name
    for name in ("scan", "detect", "sample_posterior", "fit_axisymmetric", "load_visibilities", "simulate_observation"):
        assert callable(getattr(spiralbayes, name))
