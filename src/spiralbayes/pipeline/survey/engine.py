"""Running a survey's task graph: on ``dask.distributed`` (a LocalCluster or an existing scheduler) or serially.

The graph is a list of :class:`Task` in dependency order; an argument :class:`Ref` names an
earlier task whose result it stands for. On Dask every task is submitted at once with
``retries`` (a failed task, or one whose worker died, runs again), results stay on the workers
and move between them only where a task needs them (the ScanContext of a disc goes once to each
worker that scans a chunk of it), and the client only gathers the small table rows. A failure
propagates to the tasks that depend on it, never to other discs.

The serial engine runs every task with one BLAS thread, as a Dask worker does, so that both
give the same table to the last bit (frank's linear algebra differs in the last digit between
thread counts). The client comes from :func:`spiralbayes.cluster.open_scheduler` (the one place
that builds and closes clusters): by default a :class:`~distributed.LocalCluster` with one
single-threaded worker process per core; ``scheduler = "tcp://host:port"`` connects to a running
one (dask-jobqueue, dask-mpi or ``dask scheduler``; docs/survey.md) and fails in one line naming
the address when it cannot be reached within ``connect_timeout`` seconds, before any work is done.
"""

from __future__ import annotations

import logging
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..._threads import blas_threads
from ...cluster import describe_scheduler

__all__ = ["Engine", "Outcome", "Ref", "Task"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Ref:
    """The result of the task named ``key``, as an argument of a later task."""

    key: str


@dataclass
class Task:
    key: str
    func: Callable[..., Any]
    args: tuple
    disc: str | None = None
    stage: str = ""


@dataclass
class Outcome:
    """What running a graph gave: results (or errors) of the tasks asked for, and the time per task [s]."""

    values: dict
    errors: dict
    seconds: dict = field(default_factory=dict)


class Engine:
    """Runs a task graph on a Dask client (from :func:`spiralbayes.cluster.open_scheduler`), or serially
    when ``client`` is None."""

    def __init__(self, client=None, *, retries: int = 1):
        self.client, self.retries = client, retries
        self.description = describe_scheduler(client)

    @property
    def dashboard(self) -> str | None:
        return getattr(self.client, "dashboard_link", None) if self.client is not None else None

    @property
    def n_workers(self) -> int:
        if self.client is None:
            return 1
        return len(self.client.scheduler_info().get("workers", {}))

    def run(self, tasks: list[Task], wanted: list[str], *, progress: bool = False) -> Outcome:
        """Run ``tasks``; return the results of the ``wanted`` keys (errors as one-line strings)."""
        if self.client is None:
            return self._run_serial(tasks, wanted, progress)
        return self._run_dask(tasks, wanted, progress)

    def _run_serial(self, tasks, wanted, progress) -> Outcome:
        from tqdm.auto import tqdm

        results: dict[str, Any] = {}
        errors: dict[str, str] = {}
        seconds: dict[str, float] = {}
        for task in tqdm(tasks, desc="survey tasks", unit="task", disable=not progress):
            failed = [a.key for a in task.args if isinstance(a, Ref) and a.key in errors]
            if failed:
                errors[task.key] = errors[failed[0]]
                continue
            args = [results[a.key] if isinstance(a, Ref) else a for a in task.args]
            t0 = time.perf_counter()
            for attempt in range(self.retries + 1):
                try:
                    with blas_threads(1, all_pools=True):  # as a Dask worker: one BLAS thread, so the same bits
                        results[task.key] = task.func(*args)
                    break
                except Exception as exc:
                    if attempt == self.retries:
                        errors[task.key] = " ".join(str(exc).split()) or type(exc).__name__
                    else:
                        log.warning("%s failed (%s); retrying", task.key, exc)
            seconds[task.key] = time.perf_counter() - t0
        return Outcome({k: results[k] for k in wanted if k in results},
                       {k: errors[k] for k in wanted if k in errors}, seconds)

    def _run_dask(self, tasks, wanted, progress) -> Outcome:
        from distributed import as_completed, get_task_stream
        from tqdm.auto import tqdm

        token = uuid.uuid4().hex[:8]
        futures: dict[str, Any] = {}  # distributed.Future by task key
        with get_task_stream(self.client) as stream:
            for task in tasks:
                args = [futures[a.key] if isinstance(a, Ref) else a for a in task.args]
                futures[task.key] = self.client.submit(task.func, *args, key=f"{task.key}-{token}", pure=False,
                                                       retries=self.retries)
            with tqdm(total=len(futures), desc="survey tasks", unit="task", disable=not progress) as bar:
                for _ in as_completed(list(futures.values())):
                    bar.update()
            values, errors = {}, {}
            for key in wanted:
                future = futures[key]
                if future.status == "finished":
                    values[key] = future.result()
                else:
                    exc = future.exception()
                    errors[key] = " ".join(str(exc).split()) or type(exc).__name__
        seconds: dict[str, float] = {}
        for record in stream.data:
            key = str(record.get("key", ""))
            base = key.rsplit("-", 1)[0]
            for ss in record.get("startstops", ()):
                if ss.get("action") == "compute":
                    seconds[base] = seconds.get(base, 0.0) + ss["stop"] - ss["start"]
        for future in futures.values():
            future.release()
        return Outcome(values, errors, seconds)
