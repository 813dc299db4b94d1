"""The stages of one survey disc, as functions a Dask worker runs: load, frank, scan (in chunks), test 3,
detect, limits, posterior, table row.

Each stage writes what the single-disc command writes, in the disc's ``[output] dir``, and a
marker ``survey_stage_<stage>.json`` holding its resume key (a hash of the configuration sections
it depends on and of the data) and the files it wrote (:mod:`.files`). A stage whose marker
matches is skipped on a rerun; one whose key changed runs again and replaces its earlier outputs,
never a file the survey did not write. The scan is
split into template chunks: :func:`stage_scan_setup` builds the
:class:`~spiralbayes.inference.scan.engine.ScanContext` once (the
uv grids; workers fetch it once from the worker that built it), resumes from
``scan_checkpoint.h5`` and from the chunks already written to ``survey_parts/``, and every
:func:`stage_scan_chunk` computes and saves its templates' terms. :func:`stage_detect` assembles
them exactly as :func:`spiralbayes.inference.scan.scan` does, so a survey disc's ``scan.h5``
equals the single-disc scan's. Every stage's failure is raised as :class:`StageError` naming the
stage, in one line.
"""

from __future__ import annotations

import json
import logging
import shutil
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..._provenance import content_hash, data_hash
from ...config import describe_config
from ...exceptions import ResumeMismatchError, SpiralbayesError
from .files import begin, check_folder, claim, clear, done, mark, superseded, write_text

if TYPE_CHECKING:  # the stages import the inference modules when they run, on the worker
    from ...inference.scan.engine import ScanContext, TemplateTerms
    from ...inference.scan.run import ScanResult
    from ...visibilities import Visibilities

__all__ = ["StageError", "stage_alternatives", "stage_bank", "stage_detect", "stage_frank", "stage_limits",
           "stage_posterior", "stage_prepare", "stage_row", "stage_scan_chunk", "stage_scan_setup",
           "stage_templates"]

log = logging.getLogger(__name__)

SCAN_SECTIONS = ("data", "geometry", "frank", "templates", "grid", "scan", "alternatives")
SCAN_OUTPUTS = ("scan.h5", "verdict.json", "verdict.txt", "scan_checkpoint.h5", "config_used.toml",
                "alternatives.h5", "alternatives.txt")
"""Files of the scan stage that a rerun with other inputs replaces (checked to be the survey's own first)."""
LIMITS_OUTPUTS = ("limits.h5", "table3.md", "table3.ecsv", "table3.csv", "limits_summary.txt",
                  "config_used_limits.toml")
"""Files of the limits stage that a rerun with other inputs replaces."""


class StageError(SpiralbayesError, RuntimeError):
    """A survey stage failed; the message is one line: ``<stage>: <error type>: <what happened>``."""


def _staged(name: str):
    def wrap(func):
        def run(*args, **kwargs):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # DataWarnings go to the disc's log, not every worker's stderr
                    return func(*args, **kwargs)
            except StageError:
                raise
            except Exception as exc:  # every failure becomes one picklable line
                text = " ".join(str(exc.args[0] if isinstance(exc, KeyError) and exc.args else exc).split())
                raise StageError(f"{name}: {type(exc).__name__}: {text or 'no message'}") from None
        run.__name__ = run.__qualname__ = f"stage_{name}"
        run.__doc__ = func.__doc__
        run.__module__ = __name__
        return run
    return wrap


@dataclass
class Prepared:
    """The disc's data on a worker, with its content hash and the stage keys that depend on it."""

    vis: Visibilities
    data_key: str
    scan_key: str


@dataclass
class ScanSetup:
    """The scan of one disc ready to be split: context, the result being filled, what is left."""

    context: ScanContext | None  # None when the scan stage was already done
    result: ScanResult
    todo: list
    finished: bool
    key: str
    since: dict | None = None
    units: list = field(default_factory=list)  # the scan's work units (building-block groups or one template)


def _replaced(job, stage: str, names: list[str]) -> None:
    if names:
        log.info("disc %s: %s inputs changed; replacing the survey's earlier %s", job.name, stage, ", ".join(names))


def geometry_error_significant(alternatives) -> bool:
    """Whether test 3's geometry-error model beats the axisymmetric one by more than the Delta BIC threshold."""
    from ...inference.detection.verdict import DELTA_BIC_THRESHOLD

    return "geometry" in alternatives.fits and alternatives.delta_bic()["geometry"] > DELTA_BIC_THRESHOLD


# --- stages ----------------------------------------------------------------------------------------
@_staged("bank")
def stage_bank(bank: dict, path: str) -> str:
    """Build the survey's template bank (both hands of every listed template, in every listed
    morphology) at ``path``, once."""
    from ...templates import TemplateBank
    from ...templates.variants import variant_template

    file = Path(path)
    key = content_hash(bank)
    if done(file.parent, "bank", key, file.name) is not None:
        return str(file)
    claim(file.parent, [file.name])
    templates = []
    for h_p in bank["h_p"]:
        for tau0 in bank["tau0"]:
            for beta in bank["beta"]:
                for variant in bank["morphologies"]:
                    for mass in bank["mass"]:
                        right = variant_template(mass, tau0, beta, "R", variant, h_p=h_p,
                                                 wavelength=bank["wavelength"])
                        templates += [right, right.mirror()]
    TemplateBank(templates, provenance={"survey_bank": bank}).save(file)
    mark(file.parent, "bank", key, written=[file.name])
    return str(file)


@_staged("templates")
def stage_templates(templates_section: dict, bank_path: str | None = None) -> list:
    """The templates of a ``[templates]`` section (``bank_path`` only orders this after the bank)."""
    from ..inputs import load_templates

    return load_templates(templates_section)


@_staged("load")
def stage_prepare(job) -> Prepared:
    """Simulate the disc's data if missing and asked for, then load it as ``spiralbayes scan`` does."""
    from ..inputs import load_data

    check_folder(job.out_dir)
    path = Path(job.config["data"]["path"])
    if not path.exists() and job.simulate is not None:
        from .demo import simulate_disc

        simulate_disc(job, path)
    vis = load_data(job.config["data"], config=job.config)
    key = data_hash(vis.u, vis.v, vis.V, vis.weights)
    return Prepared(vis, key, job.key(*SCAN_SECTIONS, extra=key))


@_staged("frank")
def stage_frank(job, prep: Prepared):
    """The axisymmetric model: ``axisymmetric.h5`` when the frank stage finished, else a frank fit."""
    from ...axisymmetric import AxisymmetricModel
    from ..inputs import load_axisymmetric

    out = job.out_dir
    key = job.key("data", "geometry", "frank", extra=prep.data_key, bank=False)
    if done(out, "frank", key, "axisymmetric.h5") is not None:
        return AxisymmetricModel.load(out / "axisymmetric.h5")
    replaced = claim(out, ["axisymmetric.h5"])
    since = begin(out, "frank", key)
    axisym = load_axisymmetric(job.config, prep.vis, progress=False)
    axisym.save(out / "axisymmetric.h5")
    _replaced(job, "frank", replaced)
    mark(out, "frank", key, {"replaced": replaced} if replaced else None, since=since)
    return axisym


def _grid(config: dict, axisym):
    from ..scan_command import scan_settings

    settings = scan_settings(config)
    return settings.planet_radii(axisym), settings.n_phi_p


@_staged("scan")
def stage_scan_setup(job, prep: Prepared, axisym, templates) -> ScanSetup:
    """The scan's context and partly filled result (resumed from the checkpoint and saved chunks)."""
    from ...inference.scan.run import ScanResult, empty_result, resume_from_checkpoint, warn_beyond_rmax, resume_key
    from ...inference.scan.accuracy import check_terms
    from ...inference.scan.building_blocks import building_block_groups, check_pairs, describe_blocks, work_units
    from ...inference.scan.engine import ScanContext
    from ..scan_command import scan_settings

    out = job.out_dir
    if done(out, "scan", prep.scan_key, "scan.h5", "verdict.json") is not None:
        return ScanSetup(None, ScanResult.load(out / "scan.h5"), [], True, prep.scan_key)
    replaced = claim(out, SCAN_OUTPUTS)
    since = begin(out, "scan", prep.scan_key)
    s = job.config["scan"]
    r_p, n_phi_p = _grid(job.config, axisym)
    settings = scan_settings(job.config)
    warn_beyond_rmax(axisym, r_p)
    x_max = max(float(np.max(t.x)) for t in templates)
    context = ScanContext.build(prep.vis, axisym, axisym.geometry, r_p, n_phi_p, x_max=x_max, nthreads=s["nthreads"],
                                settings=settings)
    result = empty_result(context, templates, prep.vis, job.config["geometry"]["distance"])
    # the same work units as sb.scan, so that the survey's numbers are the single-disc scan's, bit for bit
    grouped = settings.building_blocks and settings.quadrature == "product"
    groups, plain = building_block_groups(templates) if grouped else ([], None)
    result.provenance["resume_key"] = rkey = resume_key(prep.vis, axisym, templates, context, describe_blocks(groups))
    checkpoint = out / "scan_checkpoint.h5"
    if s["checkpoint"] and checkpoint.exists():
        try:
            result = resume_from_checkpoint(checkpoint, result)
        except ResumeMismatchError:  # the inputs changed since the survey wrote it: scan again
            checkpoint.unlink()
    part_key = content_hash(rkey)
    for i in range(len(templates)):
        if not result.completed[i]:
            terms = _load_part(out, i, part_key)
            if terms is not None:
                _store_terms(result, i, terms)
    todo = [i for i in range(len(templates)) if not result.completed[i]]
    if todo and settings.quadrature == "product":
        context.algorithm_error = check_terms(context, templates[0])
        if groups:
            check_pairs(context, groups[0])
        result.provenance["power_check"] = context.algorithm_error
    _replaced(job, "scan", replaced)
    return ScanSetup(context, result, todo, False, part_key, since, work_units(templates, todo, groups, plain))


def _part_path(out: Path, index: int) -> Path:
    return Path(out) / "survey_parts" / f"scan_template_{index:03d}.npz"


def _load_part(out: Path, index: int, key: str):
    from ...inference.scan.engine import TemplateTerms

    path = _part_path(out, index)
    if not path.exists():
        return None
    try:
        with np.load(path) as f:
            if str(f["key"]) != key:
                return None
            return TemplateTerms(f["cross"], f["power"], f["cross_error"], f["power_error"])
    except (OSError, ValueError, KeyError):
        return None  # a damaged part is computed again


def _store_terms(result, index: int, terms) -> None:
    from ...inference.scan.run import store_template_terms

    store_template_terms(result, index, terms, None)


@_staged("scan")
def stage_scan_chunk(job, setup: ScanSetup, templates, indices) -> dict:
    """The terms of the work units whose first template is one of ``indices`` (a building-block group
    runs whole, in the chunk of its first member); each template's saved to ``survey_parts/``."""
    from ..._provenance import atomic_path
    from ...inference.scan.building_blocks import unit_rows
    from ...inference.scan.run import run_unit

    out: dict[int, TemplateTerms] = {}
    if setup.finished:
        return out
    if setup.context is None:
        raise RuntimeError(f"scan of {job.name}: the set-up of an unfinished scan has no context")
    chunk = set(indices)
    for unit in setup.units:
        if min(unit_rows(unit)) not in chunk:
            continue
        for i, terms in run_unit(setup.context, unit).items():
            path = _part_path(job.out_dir, i)
            with atomic_path(path) as tmp, open(tmp, "wb") as fh:
                np.savez(fh, key=setup.key, cross=terms[0], power=terms[1],
                         cross_error=np.asarray(getattr(terms, "cross_error", np.nan)),
                         power_error=np.asarray(getattr(terms, "power_error", np.nan)))
            out[i] = terms
    return out


def _alt_kwargs(config: dict) -> dict:
    from ...inference.detection.settings import AlternativesSettings
    from ...settings import from_config

    settings = from_config(AlternativesSettings, config["alternatives"], nthreads=config["scan"]["nthreads"])
    return {"settings": settings, "progress": False}


@_staged("alternatives")
def stage_alternatives(job, prep: Prepared, axisym, setup: ScanSetup):
    """Test 3's competing asymmetry models (None when switched off or the scan stage is done)."""
    from ...inference.detection.alternatives import fit_alternatives

    if setup.finished or not job.config["alternatives"]["fit"]:
        return None
    return fit_alternatives(prep.vis, axisym, axisym.geometry, **_alt_kwargs(job.config))


@_staged("detect")
def stage_detect(job, prep: Prepared, axisym, templates, setup: ScanSetup, alts, *chunks) -> dict:
    """Assemble the scan, decide (tests 1-3), write the scan's outputs as ``spiralbayes scan`` does."""
    if setup.finished:
        return json.loads((job.out_dir / "verdict.json").read_text())
    from ...inference.detection.follow_up import rescan_at_fitted_geometry
    from ...inference.detection.verdict import detect_with_planet_peak
    from ...inference.scan.accuracy import warn_if_inaccurate
    from ..outputs import write_scan_outputs
    from ..scan_command import scan_settings

    config, out = job.config, job.out_dir
    result = setup.result
    for chunk in chunks:
        for i, terms in chunk.items():
            _store_terms(result, i, terms)
    if not np.all(result.completed):
        raise RuntimeError(f"scan of {job.name} incomplete: templates {np.flatnonzero(~result.completed).tolist()}")
    s, a = config["scan"], config["alternatives"]
    if s["checkpoint"]:
        result.save(out / "scan_checkpoint.h5")
    warn_if_inaccurate(result)
    amplitude = "free" if s["amplitude"] == "free" else None
    detect_kwargs = {"alternative_threshold": a["threshold"], "mstar": config["limits"]["mstar"]}
    verdict = detect_with_planet_peak(result, prep.vis, axisym, templates, axisym.geometry, amplitude,
                                      alternatives=alts, **detect_kwargs)
    plots = config["output"]["plots"]
    write_scan_outputs(result, verdict, out, plots, amplitude, alternatives=alts, vis=prep.vis, axisymmetric=axisym,
                       templates=templates)
    axisym.save(out / "axisymmetric.h5")
    write_text(out / "config_used.toml", describe_config(config))
    info = {}
    if alts is not None and a["refit_geometry"] and geometry_error_significant(alts) and not verdict.detected:
        follow = rescan_at_fitted_geometry(prep.vis, axisym, templates, alts, settings=scan_settings(config),
                                           scan_result=result, progress=False, alternative_kwargs=_alt_kwargs(config),
                                           detect_kwargs=detect_kwargs)
        sub = out / "refit_geometry"
        write_scan_outputs(follow.scan, follow.verdict, sub, plots, amplitude, alternatives=follow.alternatives,
                           vis=prep.vis, axisymmetric=follow.axisymmetric, templates=templates)
        follow.axisymmetric.save(sub / "axisymmetric.h5")
        info["refit_detected"] = bool(follow.verdict.detected)
    mark(out, "scan", prep.scan_key, info, since=setup.since)
    shutil.rmtree(out / "survey_parts", ignore_errors=True)
    return verdict.to_dict()


@_staged("limits")
def stage_limits(job, prep: Prepared, axisym, templates, verdict: dict) -> str:
    """Exclusion limits and Table 3 of the disc, as ``spiralbayes limits`` writes them."""
    from ...inference.scan import ScanResult
    from ..limits import run_limits

    config, out = job.config, job.out_dir
    key = content_hash(prep.scan_key, config["limits"], config["output"])
    if done(out, "limits", key, "limits.h5", "table3.md") is None:
        replaced = claim(out, LIMITS_OUTPUTS)
        since = begin(out, "limits", key)
        result = ScanResult.load(out / "scan.h5")
        write_text(out / "config_used_limits.toml", describe_config(config))
        run_limits(prep.vis, axisym, templates, result, out, limits_config=config["limits"],
                   name=config["limits"]["name"], distance=config["geometry"]["distance"], progress=False,
                   plots=config["output"]["plots"], verdict=verdict)
        _replaced(job, "limits", replaced)
        mark(out, "limits", key, {"replaced": replaced} if replaced else None, since=since)
    return str(out / "limits.h5")


def wants_posterior(mode: str, verdict: dict) -> bool:
    """Whether the survey's posterior policy asks for this disc's posterior."""
    from .table import outcome

    # a handed compact peak beside a failed global one is followed up too (Verdict.candidate)
    return mode == "all" or (mode == "candidates" and (outcome(verdict) in ("detected", "candidate")
                                                       or verdict.get("candidate") is not None))


@_staged("posterior")
def stage_posterior(job, prep: Prepared, verdict: dict, mode: str, steps: int) -> dict | None:
    """The posterior (``spiralbayes sample``) of a disc the policy selects, with the candidate's template; a
    candidate compact source is sampled with the competing explanations (``[sample] alternatives``) unless
    the survey file names them."""
    from ...templates.asymmetry import ASYMMETRY_KINDS
    from ..sample_command import run_sample_config
    from .table import outcome

    if not wants_posterior(mode, verdict):
        return None
    config = {s: dict(v) for s, v in job.config.items()}
    sample = config["sample"]
    if not sample["n_steps"]:
        sample["n_steps"] = int(steps)
    best = verdict.get("candidate") or {"template": verdict.get("template")}
    if not sample["mcmc_templates"] and best.get("template"):
        sample["mcmc_templates"] = [best["template"]]
    if outcome(verdict) == "candidate" and not sample["alternatives"]:
        # a compact source that a planet and another model both explain: weigh them (posterior odds)
        sample["alternatives"] = list(ASYMMETRY_KINDS)
    out = job.out_dir
    key = content_hash(prep.scan_key, sample, config["priors"])
    info = done(out, "posterior", key, f"{sample['run_name']}_summary.json")
    if info is None:
        replaced = claim(out, [f"{sample['run_name']}_summary.json", f"{sample['run_name']}_posterior.h5"])
        if superseded(out, "posterior", key):  # chains of other inputs: sampled afresh, not resumed
            replaced += clear(out, "chains")
        since = begin(out, "posterior", key)
        post = run_sample_config(config, progress=False)
        info = {"p_planet": float(post.p_planet), "verdict": str(post.verdict),
                "model_probabilities": post.model_probabilities}
        _replaced(job, "posterior", replaced)
        mark(out, "posterior", key, {**info, "replaced": replaced} if replaced else info, since=since)
    return info


@_staged("row")
def stage_row(job, verdict: dict, limits_path: str, posterior: dict | None) -> dict:
    """The disc's survey-table row, read back from its files (so a resumed run gives the same row)."""
    from .table import disc_row

    return disc_row(job, json.loads((job.out_dir / "verdict.json").read_text()), limits_path, posterior)
