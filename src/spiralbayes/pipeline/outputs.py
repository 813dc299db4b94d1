"""Write results: figures and text atomically, and the files of a finished scan."""

from __future__ import annotations

import logging
from pathlib import Path

from .._provenance import atomic_path, to_json
from ..inference.detection.verdict import mirror_index
from ..plotting.alternatives import plot_residual_comparison
from ..plotting.scan import plot_chi2_vs_rp, plot_heatmap_pair

__all__ = ["save_figure", "write_scan_outputs"]

log = logging.getLogger(__name__)


def save_figure(fig, path, dpi: int = 120, **kwargs) -> Path:
    """Write a Figure through a temporary file (format from the suffix, default PNG; no pyplot state)."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi, **kwargs)
    return path


_save_figure = save_figure


def _write_text(path: Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def write_scan_outputs(result, verdict, out_dir: Path, plots: bool = True, amplitude=None, *, alternatives=None,
                       vis=None, axisymmetric=None, templates=None) -> list[Path]:
    """Save the scan, the verdict (JSON and text) and the heatmap PNGs; return the paths.

    With ``alternatives`` also ``alternatives.h5`` and ``alternatives.txt`` (the fits of test 3)
    and, when ``vis``, ``axisymmetric`` and ``templates`` are given and ``plots`` is on,
    ``residual_comparison.png`` (:func:`~spiralbayes.plotting.alternatives.plot_residual_comparison`).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [result.save(out_dir / "scan.h5")]
    files.append(_write_text(out_dir / "verdict.json", to_json(verdict.to_dict(), indent=2)))
    files.append(_write_text(out_dir / "verdict.txt", verdict.summary() + "\n"))
    if alternatives is not None:
        files.append(alternatives.save(out_dir / "alternatives.h5"))
        files.append(_write_text(out_dir / "alternatives.txt", alternatives.table() + "\n"))
    if not plots:
        return files
    done = set()
    for t, meta in enumerate(result.templates):
        j = mirror_index(result, t)
        if meta.get("hand") != "R" or j is None or t in done:
            continue
        done.update({t, j})
        fig = plot_heatmap_pair(result, t, j, amplitude=amplitude)
        files.append(_save_figure(fig, out_dir / f"heatmap_{meta['name']}.png"))
    files.append(_save_figure(plot_chi2_vs_rp(result, amplitude=amplitude), out_dir / "chi2_vs_rp.png"))
    if alternatives is not None and None not in (vis, axisymmetric, templates):
        fig = plot_residual_comparison(vis, axisymmetric, result, alternatives, templates, amplitude=amplitude)
        files.append(_save_figure(fig, out_dir / "residual_comparison.png"))
    return files
