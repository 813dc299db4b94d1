"""Sphinx configuration of the API reference: pages generated from the NumPy-style docstrings.

Build: ``sphinx-build -W -b html docs/api <out>`` (``tests/test_docs.py`` does so, without warnings).
"""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))
os.environ.setdefault("MPLBACKEND", "Agg")

project = "spiralbayes"
author = "spiralbayes developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # dataclass fields: a field list, not a second description of each attribute
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the docstrings state types with units; signatures stay readable
# each object is documented once, in the module that defines it (not again where a package re-exports it)
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False,
                           "ignore-module-all": True}
# optional back ends imported lazily by the code: not needed to document it
autodoc_mock_imports = ["casatools", "casatasks", "casacore", "schwimmbad", "mpi4py", "dask_jobqueue"]


html_theme = "alabaster"
exclude_patterns = ["_build"]
# "array, shape (n, m)" in a type field makes Sphinx look up "shape" and "n" as names, which several
# classes define: ambiguous lookups of type words are not errors in the docstrings
suppress_warnings = ["ref.python"]
nitpicky = True  # every :func:, :meth:, :mod:, :data:, :attr: reference must resolve
# type fields ("float", "array_like", "Visibilities") and Raises sections are prose, not references
nitpick_ignore_regex = [("py:class", r".*"), ("py:obj", r".*"), ("py:exc", r".*")]


def _canonical_name(dotted: str) -> str | None:
    """``module.qualname`` of the object a dotted name reaches (a re-export resolves to its home)."""
    import importlib

    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        try:
            for attr in parts[k:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if parts[k:] and module and qualname:
            return f"{module}.{qualname}"
        return None
    return None


def _resolve_re_exports(app, env, node, contnode):
    # Docstrings cite the public paths (spiralbayes.inference.scan.scan, or a name imported into
    # the current module); autodoc documents each object once, under the module that defines it.
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    module = node.get("py:module")
    for candidate in ([f"{module}.{target}"] if module else []) + [target]:
        canonical = _canonical_name(candidate)
        if canonical and canonical != candidate:
            return env.get_domain("py").resolve_xref(env, node["refdoc"], app.builder, node["reftype"], canonical,
                                                     node, contnode)
    return None


def setup(app):
    app.connect("missing-reference", _resolve_re_exports)
