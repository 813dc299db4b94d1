"""Running a survey's task graph: on ``dask.distributed`` (a LocalCluster or an existing scheduler) or serially.

The graph is a list of :class:`Task` in dependency order; an argument :class:`Ref` names an
earlier task whose result it stands for. On Dask every task is submitted at once with
``retries`` (a failed task, or one whose worker died, runs again), results stay on the workers
and move between them only where a task needs them (the ScanContext of a disc goes once to each
worker that scans a chunk of it), and the client only gathers the small table rows. A failure
propagates to the tasks that depend on it, never to other discs.

The serial engine runs every task with one BLAS thread, as a Dask worker does, so that both
give the same table to the last bit (frank's linear algebra differs in the last digit between
thread counts). The default cluster is a :class:`~distributed.LocalCluster` with one single-threaded worker
process per core; ``scheduler = "tcp://host:port"`` connects to a running one (dask-jobqueue,
dask-mpi or ``dask scheduler``; docs/survey.md) and fails in one line naming the address when it
cannot be reached within ``connect_timeout`` seconds, before any work is done.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
import uuid
from dataclasses import dataclass, field

from .._threads import blas_threads
from ..exceptions import InputError

__all__ = ["JOBQUEUE_KINDS", "Engine", "Ref", "SchedulerUnreachableError", "Task", "connect", "jobqueue_cluster",
           "open_engine"]

JOBQUEUE_KINDS = {"slurm": "SLURMCluster", "pbs": "PBSCluster"}
"""``[survey] scheduler`` values that build a dask-jobqueue cluster from the survey file's ``[cluster]`` table."""

log = logging.getLogger(__name__)


class SchedulerUnreachableError(InputError):
    """No Dask scheduler answered at the address given (``--scheduler`` / ``[survey] scheduler``)."""


@dataclass(frozen=True)
class Ref:
    """The result of the task named ``key``, as an argument of a later task."""

    key: str


@dataclass
class Task:
    key: str
    func: object
    args: tuple
    disc: str | None = None
    stage: str = ""


@dataclass
class Outcome:
    """What running a graph gave: results (or errors) of the tasks asked for, and the time per task [s]."""

    values: dict
    errors: dict
    seconds: dict = field(default_factory=dict)


def available_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def _quiet(level=logging.CRITICAL):
    names = ("distributed", "distributed.client", "distributed.comm", "distributed.core", "tornado")
    old = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(level)
    try:
        yield
    finally:
        for n, lvl in old.items():
            logging.getLogger(n).setLevel(lvl)


def connect(address: str, timeout: float = 10.0):
    """A ``distributed.Client`` of the scheduler at ``address``; one-line error naming it if unreachable."""
    from distributed import Client

    try:
        with _quiet():
            return Client(address, timeout=f"{float(timeout)}s")
    except Exception as exc:  # OSError/TimeoutError on no answer, ValueError on a malformed address
        reason = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise SchedulerUnreachableError(
            f"cannot reach the Dask scheduler at {address} within {float(timeout):g} s ({reason}): start it "
            "(e.g. 'dask scheduler'), check the address, or leave --scheduler / [survey] scheduler empty for a "
            "local cluster") from None


class Engine:
    """Runs a task graph on a Dask client, or serially when ``client`` is None."""

    def __init__(self, client=None, cluster=None, *, retries: int = 1, description: str = "serial"):
        self.client, self.cluster, self.retries, self.description = client, cluster, retries, description

    @property
    def dashboard(self) -> str | None:
        return getattr(self.client, "dashboard_link", None) if self.client is not None else None

    @property
    def n_workers(self) -> int:
        if self.client is None:
            return 1
        return len(self.client.scheduler_info().get("workers", {}))

    def close(self) -> None:
        with _quiet():
            if self.client is not None:
                self.client.close()
            if self.cluster is not None:
                self.cluster.close()

    def run(self, tasks: list[Task], wanted: list[str], *, progress: bool = False) -> Outcome:
        """Run ``tasks``; return the results of the ``wanted`` keys (errors as one-line strings)."""
        if self.client is None:
            return self._run_serial(tasks, wanted, progress)
        return self._run_dask(tasks, wanted, progress)

    def _run_serial(self, tasks, wanted, progress) -> Outcome:
        from tqdm.auto import tqdm

        results, errors, seconds = {}, {}, {}
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
        futures = {}
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
        seconds = {}
        for record in stream.data:
            key = str(record.get("key", ""))
            base = key.rsplit("-", 1)[0]
            for ss in record.get("startstops", ()):
                if ss.get("action") == "compute":
                    seconds[base] = seconds.get(base, 0.0) + ss["stop"] - ss["start"]
        for future in futures.values():
            future.release()
        return Outcome(values, errors, seconds)


def jobqueue_cluster(kind: str, options: dict | None = None):
    """A dask-jobqueue cluster (``kind`` "slurm" or "pbs") built from ``options`` (the ``[cluster]`` table).

    ``options`` are the cluster class's keyword arguments (``cores``, ``memory``, ``walltime``,
    ``queue``, ``account``, ``job_extra_directives``, ...); ``jobs`` (how many batch jobs to
    start) is taken out and left to the caller (:func:`open_engine` calls ``cluster.scale(jobs=...)``).
    Workers get one thread per process (``cores`` = ``processes``) unless ``processes`` is given.
    Needs ``pip install "spiralbayes[cluster]"`` (dask-jobqueue).
    """
    from ..exceptions import MissingDependencyError

    if kind not in JOBQUEUE_KINDS:
        raise InputError(f"cluster kind {kind!r}: use one of {', '.join(JOBQUEUE_KINDS)}")
    try:
        import dask_jobqueue
    except ImportError:
        raise MissingDependencyError(f"scheduler = {kind!r} needs dask-jobqueue: pip install "
                                     "'spiralbayes[cluster]'") from None
    kwargs = {k: v for k, v in (options or {}).items() if k != "jobs"}
    kwargs.setdefault("cores", 1)
    kwargs.setdefault("processes", kwargs["cores"])
    kwargs.setdefault("memory", "4GB")
    kwargs.setdefault("scheduler_options", {"dashboard_address": ":0"})
    return getattr(dask_jobqueue, JOBQUEUE_KINDS[kind])(**kwargs)


def open_engine(scheduler: str = "", *, n_workers: int = 0, connect_timeout: float = 10.0,
                retries: int = 1, cluster_options: dict | None = None) -> Engine:
    """The engine of a survey: ``"serial"``, a scheduler address, ``"slurm"``/``"pbs"`` (dask-jobqueue,
    from ``cluster_options``), or (empty) a LocalCluster sized to the machine."""
    if scheduler == "serial":
        return Engine(retries=retries)
    if scheduler in JOBQUEUE_KINDS:
        from distributed import Client

        cluster = jobqueue_cluster(scheduler, cluster_options)
        cluster.scale(jobs=int((cluster_options or {}).get("jobs", 1)))
        engine = Engine(Client(cluster), cluster, retries=retries, description=f"{JOBQUEUE_KINDS[scheduler]}")
    elif scheduler:
        client = connect(scheduler, connect_timeout)
        engine = Engine(client, retries=retries, description=f"scheduler {scheduler}")
    else:
        from distributed import Client, LocalCluster

        n = n_workers or available_cores()
        with _quiet(logging.ERROR):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                   silence_logs=logging.ERROR)
            client = Client(cluster)
        engine = Engine(client, cluster, retries=retries, description=f"LocalCluster({n} workers x 1 thread)")
    log.info("survey engine: %s; %d workers; Dask dashboard: %s", engine.description, engine.n_workers,
             engine.dashboard)
    return engine
