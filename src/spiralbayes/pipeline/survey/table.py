"""The survey's outputs: one row per disc (the paper's Table 3 columns and the verdict), the table as ECSV and
Markdown, the figure set.

Columns (``COLUMNS``): ``disc``; ``R_eff95_arcsec`` and ``R_eff95_au`` (radius holding 95 %
of the frank profile's flux); for each mass threshold M of ``[limits] thresholds`` (the paper's
3 and 1 M_th) ``excluded_geMMth`` (orbital radii where planets of at least M thermal masses are
ruled out at ``[limits] cl`` by every template family of the disc, with the Jupiter masses M
corresponds to at the ends, as :func:`~spiralbayes.inference.limits.table3.format_range` writes
them in ``table3``); ``verdict`` (detected / candidate / not detected); ``best_candidate``;
``delta_bic`` (of the best spiral against the axisymmetric model); ``test1`` ... ``test3``;
``test3_alternative``; ``family`` (the template families the limits assume); ``morphologies``
(the template variants they cover); ``price_of_robustness`` (M_lim over the morphologies / M_lim
of the compromise wake); ``p_planet`` (the posterior's P(planet | data), when run); ``status``
(ok / failed) and ``error`` (the failed stage's one-line error). The table holds no timings, so a
resumed survey writes the same bytes as an uninterrupted one. It is written by the writer of
``spiralbayes limits``' Table 3 (:func:`~spiralbayes.inference.limits.table3.write_table`).
"""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import numpy as np

from ..._provenance import atomic_path
from ...inference.limits.robust import morphologies
from ...inference.limits.table3 import families_text, format_ranges, price_text
from ...inference.limits.table3 import write_table as write_ecsv_and_markdown
from ..outputs import save_figure

__all__ = ["disc_row", "failed_row", "survey_table", "write_figures", "write_table"]

log = logging.getLogger(__name__)


def _pass(flag) -> str:
    return "not run" if flag is None else ("pass" if flag else "fail")


def _where(v: dict, c: dict | None) -> str:
    d = v.get("distance")
    source = v.get("compact_source")
    if source and source.get("origin") == "arc" and not v.get("detected"):
        r = f"{source['r'] * d:.0f} au" if d else f"{source['r']:.3f} arcsec"
        return f"compact source (arc/vortex fit) at {r}, {source['phi_deg']:.0f} deg"
    src = c if c is not None else v
    r = f"{src['r_p'] * d:.0f} au" if d else f"{src['r_p']:.3f} arcsec"
    return f"{src['template']} at {r}, {src['phi_p_deg']:.0f} deg"


def outcome(verdict: dict) -> str:
    """"detected", "candidate" or "not detected" of a ``verdict.json`` (its ``outcome``; files written
    without one: detected or not)."""
    if verdict.get("outcome"):
        return str(verdict["outcome"])
    return "detected" if verdict["detected"] else "not detected"


def disc_row(job, verdict: dict, limits_path: str, posterior: dict | None) -> dict:
    """One table row from the disc's ``verdict.json``, ``limits.h5`` and ``axisymmetric.h5``."""
    from ...axisymmetric import AxisymmetricModel
    from ...inference.limits import ExclusionLimits

    out = Path(job.out_dir)
    axisym = AxisymmetricModel.load(out / "axisymmetric.h5")
    limits = ExclusionLimits.load(limits_path)
    distance = job.config["geometry"]["distance"]
    r_eff = float(axisym.R_eff(0.95))
    row = {"disc": job.name, "R_eff95_arcsec": round(r_eff, 4), "R_eff95_au": round(r_eff * distance, 1)}
    for mass in job.config["limits"]["thresholds"]:
        row[f"excluded_ge{mass:g}Mth"] = format_ranges(limits, limits.excluded_ranges(None, mass), mass)
    candidate = verdict.get("candidate")
    source = verdict.get("compact_source") or {}
    row.update({
        "verdict": outcome(verdict),
        "best_candidate": _where(verdict, candidate),
        "delta_bic": float(verdict["delta_bic"]),
        "test1": _pass(verdict.get("test1_passed")), "test2": _pass(verdict.get("test2_passed")),
        "test3": _pass(verdict.get("test3_passed")),
        "test3_alternative": verdict.get("best_alternative_label") or "",
        "explained_by": " or ".join(source.get("explained_by") or []),
        "source_flux_mJy": float("nan") if source.get("flux_mJy") is None else float(source["flux_mJy"]),
        "family": families_text(limits),
        "morphologies": ", ".join(morphologies(limits)),
        "price_of_robustness": price_text(limits),
        "p_planet": float("nan") if posterior is None else float(posterior["p_planet"]),
        "p_arc": _odds(posterior, "arc/vortex"), "p_ring": _odds(posterior, "eccentric ring"),
        "status": "ok", "error": "",
    })
    return row


def _odds(posterior: dict | None, hypothesis: str) -> float:
    odds = (posterior or {}).get("model_probabilities") or {}
    return float(odds.get(hypothesis, float("nan")))


def failed_row(name: str, error: str) -> dict:
    """The row of a disc that failed (after its retries): its one-line error, nothing else."""
    return {"disc": name, "status": "failed", "error": " ".join(str(error).split())}


COLUMNS = ("disc", "R_eff95_arcsec", "R_eff95_au")
TAIL = ("verdict", "best_candidate", "delta_bic", "test1", "test2", "test3", "test3_alternative", "explained_by",
        "source_flux_mJy", "family",
        "morphologies", "price_of_robustness", "p_planet", "p_arc", "p_ring", "status", "error")
UNITS = {"R_eff95_arcsec": "arcsec", "R_eff95_au": "AU", "source_flux_mJy": "mJy"}


def survey_table(rows: list[dict], *, name: str = "survey"):
    """An astropy Table of the rows (discs in survey order; missing values: NaN or '')."""
    from astropy.table import Table

    middle = []
    for row in rows:
        middle += [k for k in row if k.startswith("excluded_") and k not in middle]
    names = [*COLUMNS, *middle, *TAIL]
    columns = {}
    for key in names:
        values = [row.get(key) for row in rows]
        numeric = key in ("R_eff95_arcsec", "R_eff95_au", "delta_bic", "source_flux_mJy", "p_planet", "p_arc",
                          "p_ring")
        columns[key] = np.array([np.nan if v is None else v for v in values], float) if numeric else \
            np.array(["" if v is None else str(v) for v in values], dtype=str)
    table = Table(columns, names=names, meta={"survey": name})
    for key, unit in UNITS.items():
        table[key].unit = unit
    return table


def write_table(table, out_dir: Path) -> list[Path]:
    """``survey_table.ecsv`` and ``survey_table.md`` in ``out_dir``, written atomically."""
    return write_ecsv_and_markdown(table, Path(out_dir) / "survey_table")


def _tile(paths: list[tuple[str, Path]], title: str):
    from matplotlib.figure import Figure
    from matplotlib.image import imread

    n = len(paths)
    cols = min(2, n)
    rows = int(np.ceil(n / cols))
    fig = Figure(figsize=(7.0 * cols, 2.9 * rows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, (label, path) in zip(axes, paths):
        ax.imshow(imread(path))
        ax.set_title(label, fontsize=10)
    for ax in axes:
        ax.set_axis_off()
    fig.suptitle(title, fontsize=11)
    return fig


def write_figures(jobs, rows: list[dict], out_dir: Path) -> list[Path]:
    """``figures/limits_grid.png`` (each disc's mass-radius plot) and the candidates' heatmap pairs."""
    fig_dir = Path(out_dir) / "figures"
    files = []
    panels = []
    for job, row in zip(jobs, rows):
        if row.get("status") != "ok":
            continue
        found = sorted(Path(job.out_dir).glob("mass_radius_*.png"))
        panels += [(job.name, p) for p in found[:1]]
        if row.get("verdict") in ("detected", "candidate"):
            template = row["best_candidate"].split(" at ")[0]
            stem = template[:-2] + "_R" if template.endswith(("_R", "_L")) else template
            for heat in Path(job.out_dir).glob(f"heatmap_{stem}.png"):
                target = fig_dir / "heatmaps" / f"{job.slug}_{heat.name}"
                with atomic_path(target) as tmp:
                    shutil.copyfile(heat, tmp)
                files.append(target)
    if panels:
        files.insert(0, save_figure(_tile(panels, "Mass-radius exclusion limits (95 %), one panel per disc"),
                                    fig_dir / "limits_grid.png", dpi=110))
    return files
