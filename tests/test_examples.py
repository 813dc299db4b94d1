"""The notebook walk-through in examples/ runs from top to bottom (so that it cannot rot).

Slow group: the documentation's tutorials, executed by the default run's docs build, take the same
API path (simulate, frank, scan, verdict, posterior) at reduced size; this one runs at full size.
"""

from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).parent.parent / "examples" / "walkthrough.ipynb"


@pytest.mark.slow
@pytest.mark.notebook
def test_walkthrough_notebook_runs(tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("SPIRALBAYES_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(notebook, timeout=900, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = "".join(o.get("text", "") for c in notebook.cells if c.cell_type == "code" for o in c.get("outputs", []))
    assert "planet-driven spiral is detected" in outputs
    assert "P(right-handed)" in outputs
