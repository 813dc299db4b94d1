"""Which intermediate files of an output folder a command may reuse: only those made from the same inputs.

``sample`` reuses ``OUTPUT/axisymmetric.h5`` and ``OUTPUT/scan.h5``, ``limits`` both as well. A
file is reused only when its provenance matches the present run: the data hash (u, v, V and
weights), the geometry the configuration asks for (unless it is fitted), frank's settings, the
templates' content hashes and the planet grid. Anything else is refused with the one-line fix
(:class:`~spiralbayes.exceptions.ResumeMismatchError` naming what differs) — never used silently.
Checkpoints and chain files carry their own resume keys (:func:`spiralbayes.inference.scan.resume_key`,
:class:`spiralbayes.inference.posterior.chains.ChainStore`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._provenance import content_hash, data_hash
from ..axisymmetric import AxisymmetricModel
from ..config import geometry_given
from ..axisymmetric.provenance import fitted_data_hash, same_data
from ..exceptions import ResumeMismatchError
from ..inference.scan import ScanResult
from ..templates.template import template_metadata

__all__ = ["axisymmetric_differences", "reusable_axisymmetric", "reusable_scan", "scan_differences"]

_FRANK_KEYS = ("Rmax", "alpha", "p0", "weights_smooth", "nonnegative")


def _close(a, b) -> bool:
    try:
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    except (TypeError, ValueError):
        return a == b


def axisymmetric_differences(model: AxisymmetricModel, vis, config: dict) -> list[str]:
    """What differs between a saved frank model and the run of ``config`` on ``vis`` (empty: reusable)."""
    diffs = []
    if same_data(model, vis) is False:
        diffs.append(f"the data (hash {fitted_data_hash(model)} -> {data_hash(vis.u, vis.v, vis.V, vis.weights)})")
    g = config["geometry"]
    if not g["fit"] and geometry_given(config):
        wanted = {"inc": g["inc"], "PA": g["PA"], "dRA": g["dRA"], "dDec": g["dDec"]}
        have = model.geometry.to_dict()
        changed = [f"{k}: {have.get(k)!r} -> {v!r}" for k, v in wanted.items() if not _close(have.get(k), v)]
        if changed:
            diffs.append(f"geometry ({', '.join(changed)})")
    hyper, f = model.hyperparameters or {}, config["frank"]
    changed = [f"{k}: {hyper.get(k)!r} -> {f[k]!r}" for k in _FRANK_KEYS if k in hyper and not _close(hyper[k], f[k])]
    if f["N"] and "N" in hyper and int(hyper["N"]) != int(f["N"]):
        changed.append(f"N: {hyper['N']!r} -> {f['N']!r}")
    if changed:
        diffs.append(f"frank settings ({', '.join(changed)})")
    return diffs


def reusable_axisymmetric(path, vis, config: dict) -> AxisymmetricModel:
    """``path``'s model when it was fitted to these data with these settings, else ResumeMismatchError."""
    model = AxisymmetricModel.load(path)
    diffs = axisymmetric_differences(model, vis, config)
    if diffs:
        raise ResumeMismatchError(
            f"{path} was fitted for other inputs — {'; '.join(diffs)}: run 'spiralbayes scan' with this "
            "configuration first (it refits frank), set [frank] model to the model to use, or use another "
            "[output] dir")
    return model


def scan_differences(result: ScanResult, vis, axisymmetric, templates=None, r_p=None, n_phi_p=None) -> list[str]:
    """What differs between a saved scan and the present data, model, templates and grid (empty: reusable)."""
    diffs = []
    key = result.provenance.get("resume_key") if isinstance(result.provenance, dict) else None
    key = key if isinstance(key, dict) else {}
    recorded = str(key.get("data") or result.provenance.get("data_hash") or "").rstrip("*")
    hashes = {data_hash(vis.u, vis.v, vis.V, vis.weights)}
    standard = vis.standardised()
    hashes.add(data_hash(standard.u, standard.v, standard.V, standard.weights))
    if recorded not in hashes:
        diffs.append("the data (u, v, V or weights)")
    if "forced_resume" in result.provenance:
        diffs.append("it was force-resumed from a checkpoint for other inputs")
    have, want = result.geometry.to_dict(), axisymmetric.geometry.to_dict()
    changed = [f"{k}: {have[k]!r} -> {want[k]!r}" for k in want if not _close(have.get(k), want[k])]
    if changed:
        diffs.append(f"geometry ({', '.join(changed)})")
    profile = key.get("axisymmetric_profile")
    if profile and hasattr(axisymmetric, "I"):
        now = content_hash(np.asarray(axisymmetric.r, float), np.asarray(axisymmetric.I, float),
                           float(getattr(axisymmetric, "Rmax", 0.0)))
        if now != profile:
            diffs.append("the axisymmetric model's profile")
    if templates is not None:
        names = [t["name"] for t in result.templates]
        if names != [t.name for t in templates]:
            diffs.append("the templates (names)")
        elif key.get("templates"):
            now_templates = [content_hash(np.asarray(t.x), np.asarray(t.phi), np.asarray(t.delta),
                                          template_metadata(t)) for t in templates]
            if now_templates != list(key["templates"]):
                diffs.append("the templates (content)")
    if r_p is not None and (result.r_p.shape != np.shape(r_p) or not np.allclose(result.r_p, r_p)):
        diffs.append("the planet radii")
    if n_phi_p is not None and result.phi_p.size != n_phi_p:
        diffs.append("the number of planet azimuths")
    if not np.all(result.completed):
        diffs.append("it is incomplete")
    return diffs


def reusable_scan(path, vis, axisymmetric, templates=None, r_p=None, n_phi_p=None) -> ScanResult:
    """``path``'s scan when it was computed for these inputs, else ResumeMismatchError naming what differs."""
    result = ScanResult.load(path)
    diffs = scan_differences(result, vis, axisymmetric, templates, r_p, n_phi_p)
    if diffs:
        raise ResumeMismatchError(
            f"{Path(path)} was computed for other inputs — {'; '.join(diffs)}: run 'spiralbayes scan' with this "
            "configuration first (it replaces it), or use another [output] dir")
    return result
