"""``spiralbayes survey``: the same search, verdict and limits over many discs, on dask.distributed.

:func:`run_survey` reads a survey file (:mod:`.config`), builds one task graph for all discs —
per disc load → frank → scan (split into template chunks) and test 3 in parallel → detect →
limits and, by the ``[survey] posterior`` policy, the posterior → table row (:mod:`.stages`) —
and runs it (:mod:`.engine`, on the engine of :mod:`spiralbayes.cluster`). Every disc's folder
``OUTPUT/discs/<name>/`` holds what ``spiralbayes scan`` and ``limits`` write for that disc
(:mod:`.files` records which files the survey wrote there); the survey writes
``survey_table.ecsv`` / ``.md`` (:mod:`.table`), ``figures/`` and ``survey_provenance.json``.
:mod:`.demo` writes the Taurus example.
"""

from .config import BANK_SCHEMA, DISC_KEYS, SURVEY_SCHEMA, DiscJob, SurveySpec, load_survey, parse_survey
from .run import SurveyFailedError, SurveyRun, run_survey, run_survey_demo

__all__ = ["BANK_SCHEMA", "DISC_KEYS", "SURVEY_SCHEMA", "DiscJob", "SurveyFailedError", "SurveyRun", "SurveySpec",
           "load_survey", "parse_survey", "run_survey", "run_survey_demo"]
