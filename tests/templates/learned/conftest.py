"""The training runs and the learned model, read and fitted once per test process."""

from __future__ import annotations

import pytest

from spiralbayes.templates.learned import LearnedTemplateModel, TrainingRun, read_training_runs

from .common import FILES


@pytest.fixture(scope="session")
def runs() -> list[TrainingRun]:
    return read_training_runs(FILES)


@pytest.fixture(scope="session")
def model(runs) -> LearnedTemplateModel:
    return LearnedTemplateModel.fit(runs, restarts=0)
