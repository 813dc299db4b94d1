"""The documentation: the site builds (pages, tutorials, API reference), the pages cite tests that exist, name
modules that exist and tell no development history, and the tutorials use the public API."""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent


def cited_tests(page: Path) -> list[tuple[str, str | None]]:
    """``(file, test name or None)`` of each test cited as `tests/...py::name` or a bare `test_name`."""
    text = page.read_text()
    out, current = [], None
    for match in re.finditer(r"`(tests/[\w/]+\.py)(?:::(\w+))?`|`(test_\w+)`", text):
        if match.group(1):
            current = match.group(1)
            out.append((current, match.group(2)))
        else:
            out.append((current, match.group(3)))
    return out


def test_every_test_cited_by_the_conventions_page_exists():
    cited = cited_tests(ROOT / "docs" / "conventions.md")
    assert len(cited) >= 8
    for file, name in cited:
        path = ROOT / file
        assert path.exists(), f"docs/conventions.md cites {file}, which does not exist"
        if name:
            names = {n.name for n in ast.parse(path.read_text()).body if isinstance(n, ast.FunctionDef)}
            assert name in names, f"docs/conventions.md cites {file}::{name}, which does not exist"


DOCS = ROOT / "docs"
API = DOCS / "api"


def test_every_public_module_is_on_an_api_page():
    """Each module (no private part, validation harnesses aside) has an ``automodule`` on a stage page."""
    package = ROOT / "src" / "spiralbayes"
    documented = set(re.findall(r"^\.\. automodule:: ([\w.]+)", "\n".join(p.read_text() for p in API.glob("*.rst")),
                                re.M))
    modules = set()
    for path in package.rglob("*.py"):
        parts = path.relative_to(package).with_suffix("").parts
        if any(p.startswith("_") and p != "__init__" for p in parts) or parts[:2] == ("inference", "validation"):
            continue
        name = ".".join(["spiralbayes", *parts]).removesuffix(".__init__")
        if name != "spiralbayes.inference":
            modules.add(name)
    assert not modules - documented, f"modules on no page of docs/api: {sorted(modules - documented)}"
    assert not documented - modules - {"spiralbayes"}, f"pages name missing modules: {sorted(documented - modules)}"


def _build_site(tmp_path, size: str):
    import os
    import subprocess
    import sys

    import pytest

    pytest.importorskip("sphinx", reason="sphinx is not installed (pip install 'spiralbayes[test]')")
    pytest.importorskip("myst_nb", reason="myst-nb is not installed (pip install 'spiralbayes[test]')")
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT / "src"), "SPIRALBAYES_TUTORIAL_SIZE": size}
    out = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-q", "-b", "html", str(DOCS),
                          str(tmp_path / "html"), "-d", str(tmp_path / "doctrees")],
                         capture_output=True, text=True, env=env, timeout=1800)
    assert out.returncode == 0, "sphinx-build -W -n failed:\n" + out.stderr[-6000:]
    html = tmp_path / "html"
    pages = {p.stem for p in DOCS.glob("*.md")}
    missing = [name for name in pages if not (html / f"{name}.html").exists()]
    assert not missing, f"narrative pages not rendered: {missing}"
    assert (html / "api" / "posterior.html").exists()
    for notebook in (DOCS / "tutorials").glob("*.ipynb"):
        assert (html / "tutorials" / f"{notebook.stem}.html").exists(), f"tutorial {notebook.name} not rendered"


def test_documentation_site_builds_without_warnings(tmp_path):
    """The whole site (narrative pages, tutorials executed at the reduced size, API reference) with
    ``sphinx-build -W -n``: every page and docstring parses, every cross-reference resolves, every tutorial
    cell runs."""
    _build_site(tmp_path, "reduced")


@pytest.mark.slow
def test_documentation_site_builds_with_full_size_tutorials(tmp_path):
    """The same build with the tutorials at the size of a real analysis (SPIRALBAYES_TUTORIAL_SIZE=full)."""
    _build_site(tmp_path, "full")


def test_tutorials_use_the_public_api_only():
    """A tutorial's code imports ``spiralbayes as sb`` and reaches everything through ``sb.``; each runs at two
    sizes chosen by SPIRALBAYES_TUTORIAL_SIZE; each stored notebook has no outputs (the build makes them)."""
    import json

    notebooks = sorted((DOCS / "tutorials").glob("*.ipynb"))
    assert len(notebooks) >= 3
    for path in notebooks:
        cells = [c for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code"]
        code = "\n".join("".join(c["source"]) for c in cells)
        assert "import spiralbayes as sb" in code, path.name
        assert "SPIRALBAYES_TUTORIAL_SIZE" in code, path.name
        deep = re.findall(r"from spiralbayes[\w.]* import|import spiralbayes\.|(?<![\w.])spiralbayes\.\w+", code)
        assert not deep, f"{path.name} reaches past sb.: {deep}"
        assert not any(c.get("outputs") for c in cells), f"{path.name} is stored with outputs"


def test_the_site_configuration_ignores_no_role():
    """Nitpicky references are resolved, not silenced: no pattern ignores and no whole role is ignored."""
    conf = (DOCS / "conf.py").read_text()
    assert "nitpick_ignore_regex" not in conf
    assert "suppress_warnings" not in conf
    ignored = re.findall(r'\("py:\w+", "([^"]+)"\)', conf)
    assert all("*" not in target and "." in target for target in ignored), ignored


# Development history belongs in CHANGELOG.md: the pages, the README and the docstrings describe the package as it is.
HISTORY_MARKERS = re.compile(
    r"\bissues?\s+#?\d+"  # "issue 22", "issues 10/13"
    r"|\b(?:this|that|the\s+(?:first|second|third|fourth|fifth|sixth|previous|next|last))\s+session\b"
    r"|\b(?:first|second|third|fourth|fifth|sixth)\s+session's\b"
    r"|\bpreviously\b|\bformerly\b|\bno\s+longer\b|\buntil\s+now\b|\bwas\s+renamed\b|\bin\s+earlier\s+versions\b"
    r"|\bbefore\s+the\s+(?:fix|change|refit|merge)\b|\bafter\s+the\s+merge\b",
    re.I)


def _history_in(text: str) -> list[str]:
    return [m.group(0).replace("\n", " ") for m in HISTORY_MARKERS.finditer(text)]


def test_history_markers_are_found():
    """The patterns catch the ways a page tells history (the test below is not vacuous)."""
    for text in ("as issue 22 found", "the third\nsession's variants", "it no longer drags", "in this session",
                 "before the refit", "previously 0.9"):
        assert _history_in(text), text
    for text in ("the second run set (`batch = issue22`)", "the planet's session", "before the fit", "no longest"):
        assert not _history_in(text), text


def test_pages_readme_and_docstrings_tell_no_development_history():
    import ast

    found = []
    for page in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        if "_build" not in page.parts:
            found += [f"{page.relative_to(ROOT)}: {hit}" for hit in _history_in(page.read_text())]
    for path in sorted((ROOT / "src" / "spiralbayes").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                doc = ast.get_docstring(node) or ""
                found += [f"{path.relative_to(ROOT)}:{getattr(node, 'name', '')}: {hit}" for hit in _history_in(doc)]
    assert not found, "development history outside CHANGELOG.md (move it there):\n" + "\n".join(found)


# --- the API's docstrings ----------------------------------------------------------------------------------------
def _sections(doc: str) -> set[str]:
    return set(re.findall(r"^\s*([A-Z][A-Za-z ]+)\n\s*-{3,}\s*$", doc, re.M))


def test_every_public_name_has_a_numpy_docstring():
    """Every class of ``sb.__all__`` documents its Parameters or Attributes; every function its Parameters
    (when it takes any) and Returns."""
    import inspect

    import spiralbayes as sb

    missing = []
    for name in sb.__all__:
        obj = getattr(sb, name)
        doc = inspect.getdoc(obj) or ""
        if not doc:
            missing.append(f"{name}: no docstring")
        elif inspect.isclass(obj):
            if not _sections(doc) & {"Parameters", "Attributes"}:
                missing.append(f"{name}: no Parameters or Attributes section")
        elif inspect.isfunction(obj):
            wanted = (["Parameters"] if inspect.signature(obj).parameters else []) + ["Returns"]
            missing += [f"{name}: no {s} section" for s in wanted if s not in _sections(doc)]
    assert not missing, "\n".join(missing)


ENTRY_POINTS = ["simulate_observation", "fit_axisymmetric", "scan", "detect", "compute_limits", "sample_posterior"]
CHEAP_EXAMPLES = ["simulate_observation", "fit_axisymmetric"]


def _run_examples(names):
    import doctest

    import spiralbayes as sb

    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for name in names:
        for test in doctest.DocTestFinder(recurse=False).find(getattr(sb, name), name, globs={}):
            runner.run(test)
    return runner.summarize(verbose=False)


def test_main_entry_points_have_examples():
    import inspect

    import spiralbayes as sb

    assert not [n for n in ENTRY_POINTS if "Examples" not in _sections(inspect.getdoc(getattr(sb, n)))]


def test_cheap_examples_run(monkeypatch, tmp_path):
    """The examples of the data and profile entry points run as written (seconds)."""
    monkeypatch.chdir(tmp_path)
    result = _run_examples(CHEAP_EXAMPLES)
    assert result.attempted >= 4 and result.failed == 0, result


@pytest.mark.slow
def test_search_examples_run(monkeypatch, tmp_path):
    """The examples of scan, detect and compute_limits run as written (a frank fit and a scan each)."""
    monkeypatch.chdir(tmp_path)
    result = _run_examples(["scan", "detect", "compute_limits"])
    assert result.attempted >= 12 and result.failed == 0, result
