"""Sphinx configuration of the documentation site: the narrative pages and tutorials (MyST Markdown and
Jupyter notebooks, through myst-nb) and the API reference generated from the NumPy-style docstrings.

Build: ``sphinx-build -W --keep-going -n -b html docs <out>`` (``tests/test_docs.py`` does so, without
warnings). The tutorials are executed during the build; ``SPIRALBAYES_TUTORIAL_SIZE=full`` runs them at full
size (the default is a reduced size that keeps the build near a minute on 2 cores).
"""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
os.environ.setdefault("MPLBACKEND", "Agg")

project = "spiralbayes"
author = "spiralbayes developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "myst_nb"]
root_doc = "index"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
# Parameters, Returns and Attributes render as field lists whose types are text ("array, shape (n,)",
# "float [arcsec]"), not cross-references: the type fields are prose with units.
napoleon_use_param = False
napoleon_use_rtype = False
# Attributes like Parameters (a field list; the attribute itself is documented once, by autodoc)
napoleon_custom_sections = [("Attributes", "params_style")]
napoleon_use_keyword = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the docstrings state types with units; signatures stay readable
# each object is documented once, in the module that defines it (not again where a package re-exports it)
# (flags such as undoc-members and show-inheritance are off by leaving them out: a key set to False turns them on)
autodoc_default_options = {"members": True, "ignore-module-all": True}
# optional back ends imported lazily by the code: not needed to document it
autodoc_mock_imports = ["casatools", "casatasks", "casacore", "schwimmbad", "mpi4py", "dask_jobqueue"]

# MyST: ```{math}``` and $...$ in the pages; headings get anchors for links within a page
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
# the tutorials run at every build (a reduced size by default, see the module docstring); a failing cell fails it
nb_execution_mode = "force"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_show_tb = True
# progress-bar and library notices on stderr are not part of a tutorial's story
nb_output_stderr = "remove"

html_theme = "alabaster"
html_title = "spiralbayes"
exclude_patterns = ["_build", "**.ipynb_checkpoints", "jupyter_execute"]
nitpicky = True  # every cross-reference must resolve
# Classes of libraries whose own documentation is not linked (no intersphinx: the build runs offline), named by
# docstrings; each is listed, nothing else is ignored.
nitpick_ignore = [
    ("py:class", "distributed.LocalCluster"),
    ("py:class", "matplotlib.figure.Figure"),
]


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


def _napoleon_except_data(app, what, name, obj, options, lines):
    # Napoleon reads the first line of a constant's, attribute's or property's docstring as "type: description"; here
    # those docstrings are one or two sentences of prose (with colons), not typed fields.
    from sphinx.ext.napoleon import _process_docstring

    if what not in ("data", "attribute", "property"):
        _process_docstring(app, what, name, obj, options, lines)


def setup(app):
    from sphinx.ext.napoleon import _process_docstring

    listeners = app.events.listeners["autodoc-process-docstring"]
    listeners[:] = [entry for entry in listeners if entry.handler is not _process_docstring]
    app.connect("autodoc-process-docstring", _napoleon_except_data)
    app.connect("missing-reference", _resolve_re_exports)
