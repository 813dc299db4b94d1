"""Running a survey: the task graph of every disc, its engine, the table, figures and provenance.

A disc that fails (after ``retries``) is a row with its error; a rerun skips every stage whose
resume key is unchanged, so a survey killed at any point and run again ends with the same table,
byte for byte. The table is written also when discs failed; :attr:`SurveyRun.exit_code` is then
1 and :meth:`SurveyRun.check` raises :class:`SurveyFailedError`.
"""

from __future__ import annotations

import logging
import math
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..._provenance import content_hash, provenance_record, to_json
from ...cluster import open_scheduler
from ...exceptions import SpiralbayesError
from .config import SurveySpec, load_survey
from .engine import Engine, Ref, Task
from .files import write_text
from .stages import (
    stage_alternatives,
    stage_bank,
    stage_detect,
    stage_frank,
    stage_limits,
    stage_posterior,
    stage_prepare,
    stage_row,
    stage_scan_chunk,
    stage_scan_setup,
    stage_templates,
)
from .table import failed_row, survey_table, write_figures, write_table

__all__ = ["SurveyFailedError", "SurveyRun", "run_survey", "run_survey_demo"]

log = logging.getLogger(__name__)


class SurveyFailedError(SpiralbayesError, RuntimeError):
    """Some discs of a survey failed (their errors are in the table, which was written)."""


@dataclass
class SurveyRun:
    """What :func:`run_survey` produced: the table (astropy), the rows, files, engine and timings."""

    table: object
    rows: list
    files: list
    engine: str
    timings: dict = field(default_factory=dict)
    spec: SurveySpec | None = None

    @property
    def failed(self) -> list[str]:
        """Names of the discs that failed."""
        return [r["disc"] for r in self.rows if r.get("status") != "ok"]

    @property
    def exit_code(self) -> int:
        """0 when every disc finished, 1 when any failed (``spiralbayes survey``'s exit status)."""
        return 1 if self.failed else 0

    def check(self) -> SurveyRun:
        """Raise :class:`SurveyFailedError` (one line naming the failed discs) when any disc failed; else self."""
        if self.failed:
            table = next((str(f) for f in self.files if str(f).endswith(".md")), "the survey table")
            raise SurveyFailedError(f"{len(self.failed)} of {len(self.rows)} discs failed "
                                    f"({', '.join(self.failed)}): their errors are in {table}")
        return self


def _count(templates: list) -> int:
    return len(templates)


def _template_tasks(spec: SurveySpec) -> tuple[list[Task], dict[str, str]]:
    tasks: list[Task] = []
    keys: dict[str, str] = {}  # disc folder name -> key of its templates task
    bank_ref = None
    if spec.bank is not None:
        tasks.append(Task("bank", stage_bank, (spec.bank, str(spec.out_dir / "bank.h5")), stage="bank"))
        bank_ref = Ref("bank")
    for job in spec.discs:
        section = job.config["templates"]
        key = "templates_" + content_hash(section)
        if key not in keys.values():
            tasks.append(Task(key, stage_templates, (section, bank_ref), stage="templates"))
            tasks.append(Task(key + "_n", _count, (Ref(key),), stage="templates"))
        keys[job.slug] = key
    return tasks, keys


def _disc_tasks(job, templates_key: str, n_templates: int, settings: dict) -> list[Task]:
    s = job.slug
    tpl = Ref(templates_key)
    chunk = settings["chunk_templates"]
    tasks = [Task(f"{s}_load", stage_prepare, (job,), s, "load"),
             Task(f"{s}_frank", stage_frank, (job, Ref(f"{s}_load")), s, "frank"),
             Task(f"{s}_scan_setup", stage_scan_setup, (job, Ref(f"{s}_load"), Ref(f"{s}_frank"), tpl), s, "scan")]
    chunks = []
    for k in range(math.ceil(n_templates / chunk)):
        indices = list(range(k * chunk, min(n_templates, (k + 1) * chunk)))
        tasks.append(Task(f"{s}_scan_chunk{k}", stage_scan_chunk, (job, Ref(f"{s}_scan_setup"), tpl, indices), s,
                          "scan"))
        chunks.append(Ref(f"{s}_scan_chunk{k}"))
    common = (Ref(f"{s}_load"), Ref(f"{s}_frank"))
    tasks += [
        Task(f"{s}_alternatives", stage_alternatives, (job, *common, Ref(f"{s}_scan_setup")), s, "alternatives"),
        Task(f"{s}_detect", stage_detect, (job, *common, tpl, Ref(f"{s}_scan_setup"), Ref(f"{s}_alternatives"),
                                           *chunks), s, "detect"),
        Task(f"{s}_limits", stage_limits, (job, *common, tpl, Ref(f"{s}_detect")), s, "limits"),
        Task(f"{s}_posterior", stage_posterior, (job, Ref(f"{s}_load"), Ref(f"{s}_detect"), settings["posterior"],
                                                 settings["posterior_steps"]), s, "posterior"),
        Task(f"{s}_row", stage_row, (job, Ref(f"{s}_detect"), Ref(f"{s}_limits"), Ref(f"{s}_posterior")), s, "row"),
    ]
    return tasks


def _per_disc_seconds(spec: SurveySpec, seconds: dict) -> dict:
    out = {}
    for job in spec.discs:
        stages: dict[str, float] = {}
        for key, t in seconds.items():
            if key.startswith(job.slug + "_"):
                stage = key[len(job.slug) + 1:].rstrip("0123456789")
                stages[stage] = stages.get(stage, 0.0) + t
        out[job.name] = {"stages_s": stages, "total_s": sum(stages.values())}
    return out


def run_survey(survey, *, scheduler: str | None = None, n_workers: int | None = None, progress: bool = True,
               output: str | None = None) -> SurveyRun:
    """Run a survey file (or a parsed :class:`SurveySpec`) and write its table, figures and provenance.

    Parameters
    ----------
    survey : path or SurveySpec
        The survey file (:mod:`spiralbayes.pipeline.survey.config`).
    scheduler : str or distributed.Client, optional
        Overrides ``[survey] scheduler``: ``"local"`` (a LocalCluster; also ``""``, the default),
        ``"serial"``, ``"slurm"``/``"pbs"`` (dask-jobqueue from ``[cluster]``), ``tcp://host:port``
        or a client of the caller's (left open); :func:`spiralbayes.cluster.open_scheduler`.
    n_workers : int, optional
        Overrides ``[survey] n_workers`` (LocalCluster only).
    progress : bool
        A progress bar over the survey's tasks.
    output : str, optional
        Overrides ``[survey] output`` (relative to the survey file).

    Returns
    -------
    SurveyRun
        Also when discs failed (their rows hold the error): see :attr:`SurveyRun.exit_code`.
    """
    given = scheduler if scheduler is not None and not isinstance(scheduler, str) else None
    if given is not None:
        scheduler = None
    spec = survey if isinstance(survey, SurveySpec) else load_survey(
        survey, scheduler=scheduler, n_workers=n_workers, output=output)
    if isinstance(survey, SurveySpec) and scheduler is not None:
        spec.settings["scheduler"] = scheduler
    settings = spec.settings
    out = spec.out_dir
    t0 = time.perf_counter()
    with open_scheduler(given if given is not None else settings["scheduler"], n_workers=settings["n_workers"] or None,
                        connect_timeout=settings["connect_timeout"], cluster_options=spec.cluster,
                        default="local") as client:
        engine = Engine(client, retries=settings["retries"])
        t_engine = time.perf_counter() - t0
        log.info("survey engine: %s; %d workers; Dask dashboard: %s", engine.description, engine.n_workers,
                 engine.dashboard)
        out.mkdir(parents=True, exist_ok=True)
        first, tkeys = _template_tasks(spec)
        counted = engine.run(first, [k + "_n" for k in set(tkeys.values())], progress=False)
        tasks, wanted = list(first), []
        for job in spec.discs:
            n = counted.values.get(tkeys[job.slug] + "_n")
            if n is None:
                continue
            tasks += _disc_tasks(job, tkeys[job.slug], n, settings)
            wanted.append(f"{job.slug}_row")
        t1 = time.perf_counter()
        outcome = engine.run(tasks, wanted, progress=progress)
        t_graph = time.perf_counter() - t1
        description, n_workers_used, dashboard = engine.description, engine.n_workers, engine.dashboard
    rows = []
    for job in spec.discs:
        key = f"{job.slug}_row"
        if key in outcome.values:
            rows.append(outcome.values[key])
        else:
            error = outcome.errors.get(key) or counted.errors.get(tkeys[job.slug] + "_n", "templates: not loaded")
            log.error("disc %s failed: %s", job.name, error)
            rows.append(failed_row(job.name, error))
    table = survey_table(rows, name=settings["name"])
    files = write_table(table, out)
    if settings["figures"]:
        files += write_figures(spec.discs, rows, out)
    timings = {"engine_start_s": t_engine, "graph_s": t_graph, "total_s": time.perf_counter() - t0,
               "discs": _per_disc_seconds(spec, outcome.seconds)}
    record = provenance_record(
        survey={"name": settings["name"], "file": spec.source, "hash": spec.text_hash, "settings": settings,
                "bank": spec.bank},
        engine={"description": description, "n_workers": n_workers_used, "dashboard": dashboard,
                "python": platform.python_version()},
        discs=[{"name": j.name, "folder": str(j.out_dir), "config_hash": content_hash(j.config),
                "status": r.get("status"), "error": r.get("error", "")} for j, r in zip(spec.discs, rows)],
        timings=timings)
    files.append(write_text(out / "survey_provenance.json", to_json(record, indent=2)))
    n_failed = sum(r.get("status") != "ok" for r in rows)
    log.info("survey %s: %d discs, %d failed, %.1f s (%s)", settings["name"], len(rows), n_failed,
             timings["total_s"], description)
    return SurveyRun(table, rows, files, description, timings, spec)


def run_survey_demo(out_dir="spiralbayes-survey-demo", *, scheduler: str | None = None,
                    n_workers: int | None = None, progress: bool = True) -> SurveyRun:
    """``spiralbayes survey --demo``: the Taurus example survey (six synthetic discs) in ``out_dir``.

    Writes ``out_dir/taurus_survey.toml`` (the text of ``examples/taurus_survey.toml``), simulates
    the six observations into ``out_dir/taurus-data/`` and runs the survey into ``out_dir/taurus-survey/``.
    """
    from .demo import taurus_survey_toml

    out_dir = Path(out_dir)
    path = write_text(out_dir / "taurus_survey.toml", taurus_survey_toml())
    return run_survey(path, scheduler=scheduler, n_workers=n_workers, progress=progress)
