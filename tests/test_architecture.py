"""The package's shape: imports flow one way (no circles, no upward imports) and modules stay small.

Every ``import`` of a spiralbayes module is read from the source (top level and inside functions,
relative and absolute), so a lazy import cannot hide a circle. Layers, lowest first — a module may
import its own layer and the ones below it, never one above:

0. base: ``exceptions``, ``units``, ``settings``, ``_compat``, ``_version``, ``_provenance``, ``_hdf5``, ``results``,
   ``_casa``, ``_threads``
1. data: ``geometry``, ``layout``, ``visibilities``, ``averaging``, ``fourier``, ``io``
2. models: ``axisymmetric``, ``templates``, ``quadrature``, ``model``
3. synthetic data: ``simulate``
4. inference: ``inference``
5. outputs: ``plotting``, ``image_plane``
6. runners: ``pipeline``, ``config``, ``cli`` and the package's ``__init__``

Inside ``inference`` the modules live in stage subpackages, each a layer of its own (lowest first:
``scan``; ``detection`` and ``posterior``; ``limits``; ``validation``), with no module loose beside
them. ``validation`` holds calibration harnesses and reference paths that only tests and
benchmarks import. A private name (``_x``) is never imported from another subpackage: a helper
shared that widely is public.
"""

import ast
from pathlib import Path

import pytest

import spiralbayes

PACKAGE = Path(spiralbayes.__file__).parent
LAYERS = {
    "exceptions": 0, "units": 0, "_version": 0, "_provenance": 0, "_hdf5": 0, "results": 0, "_casa": 0,
    "_threads": 0, "settings": 0, "_compat": 0, "cluster": 0,
    "geometry": 1, "layout": 1, "visibilities": 1, "averaging": 1, "fourier": 1, "io": 1,
    "axisymmetric": 2, "templates": 2, "model": 2, "alternatives": 2, "quadrature": 2, "calibration": 2,
    "simulate": 3,
    "inference": 4,
    "plotting": 5, "image_plane": 5,
    "pipeline": 6, "config": 6, "cli": 6, "": 6,
}
INFERENCE = PACKAGE / "inference"
STAGES = {"scan": 0, "detection": 1, "posterior": 1, "limits": 2, "validation": 3}
VALIDATION = "spiralbayes.inference.validation"
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
    # grouped by stage: every public name in exactly one stage list
    stages = ("DATA", "MODELS", "SEARCH", "DETECTION", "LIMITS", "POSTERIOR", "PLOTTING", "SURVEY")
    grouped = [name for stage in stages for name in getattr(spiralbayes, stage)]
    assert len(grouped) == len(set(grouped)), "a public name is listed under two stages"
    assert sorted(grouped + ["__version__", "exceptions"]) == sorted(spiralbayes.__all__)


def stage(name: str) -> str | None:
    parts = name.split(".")
    return parts[2] if len(parts) > 2 and parts[1] == "inference" else None


def test_inference_is_split_by_stage():
    loose = sorted(p.name for p in INFERENCE.glob("*.py") if p.name != "__init__.py")
    assert not loose, f"modules loose in inference/ (move each into one of {sorted(STAGES)}): {loose}"
    folders = sorted(p.name for p in INFERENCE.iterdir() if p.is_dir() and p.name != "__pycache__")
    assert folders == sorted(STAGES), f"inference/ holds {folders}; expected the stages {sorted(STAGES)}"
    for name in STAGES:
        assert (INFERENCE / name / "__init__.py").exists(), f"inference/{name}/ has no __init__.py"


def test_stages_import_only_down():
    graph = import_graph()
    bad = [f"{m} imports {d}" for m, deps in graph.items() if stage(m) for d in deps
           if stage(d) and stage(d) != stage(m) and STAGES[stage(d)] >= STAGES[stage(m)]]
    assert not bad, "inference stages importing sideways or up:\n" + "\n".join(bad)


def test_runtime_code_never_imports_validation():
    graph = import_graph()
    bad = [f"{m} imports {d}" for m, deps in graph.items() if not m.startswith(VALIDATION)
           for d in deps if d.startswith(VALIDATION)]
    assert not bad, "runtime code importing inference.validation:\n" + "\n".join(bad)


def private_imports() -> list[str]:
    """``importer: name from module`` for every private name imported from another package's module."""
    mods = modules()
    known = set(mods)
    out = []
    for name, path in mods.items():
        is_package = path.name == "__init__.py"
        here = name.split(".") if is_package else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                target = ".".join(here[: len(here) - node.level + 1] + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target not in known:
                continue
            target_package = target if mods[target].name == "__init__.py" else target.rsplit(".", 1)[0]
            for alias in node.names:
                private = alias.name.startswith("_") and not alias.name.startswith("__")
                if private and target_package != ".".join(here):
                    out.append(f"{name}: {alias.name} from {target}")
    return out


def test_no_private_name_is_imported_across_subpackages():
    bad = private_imports()
    assert not bad, "private names imported from another subpackage (make them public):\n" + "\n".join(bad)


def test_subpackages_re_export_their_modules_public_names():
    import importlib
    import types

    for name in STAGES:
        package = importlib.import_module(f"spiralbayes.inference.{name}")
        expected = set()
        for path in sorted((INFERENCE / name).glob("*.py")):
            if path.name == "__init__.py":
                continue
            module = importlib.import_module(f"spiralbayes.inference.{name}.{path.stem}")
            expected |= set(module.__all__)
            # a re-exported function must not hide a submodule of the same name
            assert getattr(package, path.stem) is module, f"spiralbayes.inference.{name}.{path.stem} is not the module"
        assert set(package.__all__) == expected, \
            f"inference/{name}/__init__ re-exports {set(package.__all__) ^ expected} wrongly"
        for public in package.__all__:
            assert getattr(package, public) is not None
    inference = importlib.import_module("spiralbayes.inference")
    for name in ("scan", "detection", "limits", "posterior"):
        assert isinstance(getattr(inference, name), types.ModuleType), \
            f"spiralbayes.inference.{name} is not the subpackage"
        for public in getattr(inference, name).__all__:
            if public != "scan":
                assert getattr(inference, public) is getattr(getattr(inference, name), public), public
    assert not hasattr(inference, "validation") or "validation" not in inference.__all__


def test_angles_are_wrapped_by_the_one_helper():
    """``units.wrap_angle`` is the only wrap of radians: no ``% TWO_PI``, ``% (2 * np.pi)`` or ``angle(exp(1j x))``."""
    import re

    pattern = re.compile(r"%=?\s*\(?\s*(TWO_PI|2(\.0)?\s*\*\s*(np|math)\.pi)|np\.angle\(np\.exp\(")
    found = [f"{name}:{i}: {line.strip()}" for name, path in modules().items() if name != "spiralbayes.units"
             for i, line in enumerate(path.read_text().split("\n"), 1) if pattern.search(line)]
    assert not found, "hand-written angle wraps (use spiralbayes.units.wrap_angle):\n" + "\n".join(found)


# HDF5 is opened and written in these modules only: the result helper, and the file formats that
# are not results (visibility files, the kill-safe chain files emcee's HDFBackend also reads, the
# template bank with its per-template groups, the frank model). Every result class is saved and
# loaded by spiralbayes._hdf5.save_dataclass / load_dataclass through spiralbayes.results.ResultMixin.
HDF5_WRITERS = {"spiralbayes._hdf5", "spiralbayes.io.hdf5", "spiralbayes.inference.posterior.chains",
                "spiralbayes.templates.bank", "spiralbayes.templates.template", "spiralbayes.axisymmetric.model"}
HDF5_CALLS = {"File", "write_file", "open_file", "checked_dataset", "create_dataset", "create_group",
              "save_dataclass", "load_dataclass"}


def hdf5_calls(path: Path) -> list[str]:
    """``name (line)`` of every call of an HDF5-writing or -opening function in ``path``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in HDF5_CALLS:
                found.append(f"{name} (line {node.lineno})")
    return found


def own_save_load(path: Path) -> list[str]:
    """Classes in ``path`` that define ``save`` or ``load`` themselves."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ClassDef):
            methods = {n.name for n in node.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
            if methods & {"save", "load"}:
                found.append(f"{node.name} (line {node.lineno})")
    return found


def test_one_hdf5_helper_for_results():
    offenders = []
    for name, path in modules().items():
        if name in HDF5_WRITERS or name == "spiralbayes.results":
            continue
        calls, classes = hdf5_calls(path), own_save_load(path)
        if calls:
            offenders.append(f"{name} calls {', '.join(calls)}")
        if classes:
            offenders.append(f"{name} defines save/load in {', '.join(classes)}")
    assert not offenders, ("hand-written HDF5 save/load outside spiralbayes._hdf5 (use spiralbayes.results."
                           "ResultMixin):\n" + "\n".join(offenders))


def test_the_hdf5_rule_can_fail(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import h5py\nclass R:\n    def save(self, path):\n        with h5py.File(path, 'w') as f:\n"
                      "            f.create_dataset('x', data=[1])\n")
    assert hdf5_calls(sample) == ["File (line 4)", "create_dataset (line 5)"]
    assert own_save_load(sample) == ["R (line 2)"]


def test_threads_are_limited_by_the_one_helper():
    """``spiralbayes._threads.blas_threads`` is the only module that imports threadpoolctl."""
    found = []
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "threadpoolctl"
                    or isinstance(node, ast.Import)
                    and any(a.name.split(".")[0] == "threadpoolctl" for a in node.names)):
                found.append(name)
    assert set(found) <= {"spiralbayes._threads"}, \
        f"threadpoolctl imported outside spiralbayes._threads: {sorted(set(found))}"
    assert found, "spiralbayes._threads no longer imports threadpoolctl"


def test_docstrings_hold_no_change_history():
    """Change history ("issue 9", "version 1") lives in CHANGELOG.md, not in docstrings."""
    import re

    pattern = re.compile(r"\bissue #?\d+|\bversion[- ]1\b", re.I)
    found = []
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                doc = ast.get_docstring(node) or ""
                found += [f"{name}.{getattr(node, 'name', '')}: {m.group(0)}" for m in pattern.finditer(doc)]
    assert not found, "change history in docstrings (move it to CHANGELOG.md):\n" + "\n".join(found)


# --- one settings pattern, each default written once ------------------------------------------------
STAGE_FUNCTIONS = ["fit_axisymmetric", "scan", "detect", "fit_alternatives", "rescan_at_fitted_geometry",
                   "compute_limits", "completeness", "sample_posterior", "forecast"]
"""Public stage functions (``spiralbayes.<name>``) that take ``settings=`` plus the few arguments a notebook changes."""


@pytest.mark.parametrize("name", STAGE_FUNCTIONS)
def test_every_stage_function_takes_settings(name):
    import inspect

    function = getattr(spiralbayes, name)
    parameters = inspect.signature(function).parameters
    assert "settings" in parameters and parameters["settings"].kind is inspect.Parameter.KEYWORD_ONLY, name
    assert parameters["settings"].default is None, f"{name}: settings=None must mean the settings class's defaults"


def _is_number_literal(node) -> bool:
    if isinstance(node, ast.UnaryOp):
        return _is_number_literal(node.operand)
    if isinstance(node, ast.Constant):
        return isinstance(node.value, (int, float)) and not isinstance(node.value, bool)
    if isinstance(node, (ast.Tuple, ast.List)):
        return bool(node.elts) and all(_is_number_literal(e) for e in node.elts)
    return False


def named_defaults(tree: ast.Module):
    """``(name, value node)`` of every function default, dataclass field default (also inside ``option()``/
    ``field()``), module constant and dict entry with a string key in ``tree``."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            a = node.args
            positional = a.posonlyargs + a.args
            yield from ((arg.arg, d) for arg, d in zip(positional[len(positional) - len(a.defaults):], a.defaults))
            yield from ((arg.arg, d) for arg, d in zip(a.kwonlyargs, a.kw_defaults) if d is not None)
        elif isinstance(node, ast.ClassDef):
            for st in node.body:
                if isinstance(st, ast.AnnAssign) and isinstance(st.target, ast.Name) and st.value is not None:
                    value = st.value
                    if isinstance(value, ast.Call) and getattr(value.func, "id", "") in ("option", "field") \
                            and value.args:
                        value = value.args[0]
                    yield st.target.id, value
        elif isinstance(node, ast.Dict):
            yield from ((k.value, v) for k, v in zip(node.keys, node.values)
                        if isinstance(k, ast.Constant) and isinstance(k.value, str))
    for st in tree.body:
        if isinstance(st, ast.Assign):
            yield from ((t.id, st.value) for t in st.targets if isinstance(t, ast.Name))
        elif isinstance(st, ast.AnnAssign) and isinstance(st.target, ast.Name) and st.value is not None:
            yield st.target.id, st.value


def literal_defaults(pattern: str, allowed=()) -> list[str]:
    """``module: name = literal`` for every number literal given to a name matching ``pattern`` outside the
    settings modules (``spiralbayes/settings.py`` and every ``<stage>/settings.py``)."""
    import re

    regex = re.compile(pattern, re.I)
    found = []
    for name, path in modules().items():
        if path.name == "settings.py":
            continue
        found += [f"{name}: {key} = {ast.unparse(value)} (line {value.lineno})"
                  for key, value in named_defaults(ast.parse(path.read_text()))
                  if regex.fullmatch(key) and _is_number_literal(value) and (name, key) not in allowed]
    return found


CLEAN_THRESHOLDS = {("spiralbayes.image_plane", "threshold"), ("spiralbayes.image_plane", "threshold_sigma")}
"""CLEAN's stopping thresholds (image-plane comparison), not the verdict's or Table 3's."""


def test_distance_mstar_and_thresholds_are_written_once():
    """The default distance, stellar mass and detection / Table 3 thresholds are literals only in the settings
    modules (``spiralbayes.settings.DEFAULT_DISTANCE_PC``, ``DEFAULT_MSTAR_MSUN``, ``DetectionSettings``,
    ``limits.settings.TABLE3_THRESHOLDS``); everywhere else names them."""
    found = literal_defaults(r"\w*(distance|mstar)\w*|\w*threshold\w*", CLEAN_THRESHOLDS)
    assert not found, "default literals outside the settings modules (import the settings' constant):\n" + \
        "\n".join(found)


def test_the_literal_rule_can_fail(tmp_path):
    tree = ast.parse("X_DISTANCE = 140.0\ndef f(mstar=0.8, n=3): pass\nclass S:\n    thresholds: tuple = "
                     "option((3.0, 1.0), 'doc')\nD = {'distance': -1}\n")
    found = {k: ast.unparse(v) for k, v in named_defaults(tree)}
    assert {k: found[k] for k in ("X_DISTANCE", "mstar", "thresholds", "distance")} == \
        {"X_DISTANCE": "140.0", "mstar": "0.8", "thresholds": "(3.0, 1.0)", "distance": "-1"}


def test_scan_grid_defaults_are_written_once():
    found = literal_defaults(r"n_r_p|n_phi_p|r_p_min|r_p_max")
    assert not found, "scan grid literals outside the settings modules:\n" + "\n".join(found)


def test_only_the_compat_module_imports_tomllib():
    found = []
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found += [name for a in node.names if a.name.split(".")[0] in ("tomllib", "tomli")]
            elif isinstance(node, ast.ImportFrom) and not node.level and \
                    (node.module or "").split(".")[0] in ("tomllib", "tomli"):
                found.append(name)
    assert set(found) == {"spiralbayes._compat"}, f"tomllib imported outside spiralbayes._compat: {sorted(set(found))}"


CLUSTER_CLASSES = ("Client", "LocalCluster", "SLURMCluster", "PBSCluster")


def test_one_cluster_builder():
    """Dask clients and clusters are made in ``spiralbayes.cluster`` only (``open_scheduler``)."""
    if "spiralbayes.cluster" not in modules():
        pytest.skip("spiralbayes.cluster (the one cluster builder) does not exist yet")
    found = []
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                called = node.func.id if isinstance(node.func, ast.Name) else getattr(node.func, "attr", "")
                if called in CLUSTER_CLASSES:
                    found.append(f"{name}: {called}(...) (line {node.lineno})")
    assert all(f.startswith("spiralbayes.cluster:") for f in found), \
        "Dask clients/clusters made outside spiralbayes.cluster:\n" + "\n".join(found)
