"""Write results: figures and text atomically, and the files of a finished scan.

An output folder belongs to one dataset: :func:`check_output_folder` refuses to write a scan's
files over those of a scan of other data (another data hash in its ``scan.h5``) unless told.
"""

from __future__ import annotations

import logging
from pathlib import Path

from .._provenance import atomic_path, to_json
from ..axisymmetric import AxisymmetricModel
from ..exceptions import InputError, SpiralbayesError
from ..inference.detection.verdict import mirror_index
from ..inference.scan import ScanResult
from ..plotting.alternatives import plot_residual_comparison
from ..plotting.scan import plot_chi2_vs_rp, plot_heatmap_pair

__all__ = ["check_output_folder", "check_simulated_folder", "save_figure", "write_scan_outputs"]

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


def check_output_folder(out_dir, data_hash: str | None, overwrite: bool = False, *, filename: str = "scan.h5",
                        option: str = "[output] dir") -> None:
    """Refuse to write the results of ``data_hash``'s data where a run on other data left its results.

    Parameters
    ----------
    out_dir : path
        The output folder; a folder without ``filename`` is always accepted.
    data_hash : str or None
        The hash of the visibilities about to be used (``data_hash(u, v, V, weights)``, as
        recorded in a result's ``provenance["data_hash"]``); None accepts any folder.
    overwrite : bool
        Accept the folder whatever it holds (``--overwrite`` on the command line).
    filename : str
        The result that records the folder's data: ``scan.h5`` (a :class:`ScanResult`) or a frank
        model (an :class:`~spiralbayes.axisymmetric.AxisymmetricModel`, e.g. ``axisym_model.h5``).
    option : str
        How the user named the folder, for the message (``[output] dir``, ``--out``).

    Raises
    ------
    InputError
        Naming the folder, both data hashes and the fix.
    """
    previous = Path(out_dir) / filename
    if overwrite or data_hash is None or not previous.is_file():
        return
    load = ScanResult.load if filename == "scan.h5" else AxisymmetricModel.load
    try:
        provenance = load(previous).provenance
    except (SpiralbayesError, OSError) as exc:  # unreadable: nothing a rerun could lose; the writers check its kind
        log.debug("not comparing with %s: %s", previous, exc)
        return
    old = provenance.get("data_hash")
    # a scan of gain-corrected data records the data it was corrected from as well
    same = {h.rstrip("*") for h in (old, provenance.get("uncorrected_data_hash")) if h}
    if old and data_hash.rstrip("*") not in same:
        raise InputError(f"{previous.parent} holds the results of a run on other data ({filename}: data hash {old}; "
                         f"this run's data: {data_hash}): refusing to overwrite them; give another {option}, "
                         "or --overwrite (overwrite=True) to replace them")


def check_simulated_folder(out_dir, overwrite: bool = False, option: str = "--out") -> None:
    """Refuse a demo's output folder that holds a scan of data the package did not simulate.

    The demos write ``scan.h5``, ``verdict.json`` and ``axisymmetric.h5`` of simulated data: a
    folder whose ``scan.h5`` records another data source (the user's observation) is refused
    unless ``overwrite``; a demo's own earlier results are replaced.

    Raises
    ------
    InputError
        Naming the folder, the data source found and the fix.
    """
    previous = Path(out_dir) / "scan.h5"
    if overwrite or not previous.is_file():
        return
    try:
        data = ScanResult.load(previous).provenance.get("data") or {}
    except (SpiralbayesError, OSError) as exc:
        log.debug("not checking %s: %s", previous, exc)
        return
    source = data.get("source") if isinstance(data, dict) else None
    if source != SIMULATED_SOURCE:
        raise InputError(f"{option} {previous.parent} holds the scan of data the demo did not simulate (scan.h5 of "
                         f"{source or 'unrecorded data'}): refusing to overwrite it; give another {option}, or "
                         "--overwrite to replace it")


SIMULATED_SOURCE = "spiralbayes.simulate"
"""The ``source`` recorded in the provenance of simulated visibilities."""


def write_scan_outputs(result, verdict, out_dir: Path, plots: bool = True, amplitude=None, *, alternatives=None,
                       vis=None, axisymmetric=None, templates=None) -> list[Path]:
    """Save the scan, the verdict (JSON and text) and the heatmap PNGs; return the paths.

    With ``alternatives`` also ``alternatives.h5`` and ``alternatives.txt`` (the fits of test 3)
    and, when ``vis``, ``axisymmetric`` and ``templates`` are given and ``plots`` is on,
    ``residual_comparison.png`` (:func:`~spiralbayes.plotting.alternatives.plot_residual_comparison`).
    Callers that may meet another dataset's folder check it first (:func:`check_output_folder`).
    """
    out_dir = Path(out_dir)
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
