"""The one Dask engine: where every ``dask.distributed`` client and cluster of spiralbayes is made and closed.

The scan (``scan(scheduler=...)``, ``[scan] scheduler``) and the survey (``[survey] scheduler``,
``spiralbayes survey --scheduler``) name their engine with one value:

``"serial"``
    No Dask: the caller runs in this process.
``"local"``
    A :class:`~distributed.LocalCluster` on this machine: ``n_workers`` worker processes (default:
    one per core the process may use, :func:`available_cores`) of ``threads_per_worker`` threads.
``"slurm"`` / ``"pbs"``
    A dask-jobqueue cluster built from ``cluster_options`` (the survey file's ``[cluster]`` table).
``"tcp://host:port"`` (any scheduler address)
    A running scheduler (``dask scheduler``, dask-mpi, a jobqueue cluster started by hand); a
    one-line :class:`SchedulerUnreachableError` naming the address when none answers in
    ``connect_timeout`` seconds.
a ``distributed.Client``
    Used as it is and left open: it belongs to the caller.
``None`` or ``""``
    The stage's own default (``default=``): serial for the scan, local for the survey.

:func:`open_scheduler` is a context manager: whatever it started (client, LocalCluster and its
worker processes, batch jobs) is closed when the block ends, also on an error. Dashboards are
served on a free port (``":0"``) and their address logged at INFO.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator

from .exceptions import InputError, MissingDependencyError

__all__ = ["JOBQUEUE_KINDS", "SchedulerUnreachableError", "available_cores", "check_scheduler", "connect",
           "describe_scheduler", "jobqueue_cluster", "open_scheduler", "quiet_dask"]

log = logging.getLogger(__name__)

JOBQUEUE_KINDS = {"slurm": "SLURMCluster", "pbs": "PBSCluster"}
"""Scheduler values that build a dask-jobqueue cluster (the class of ``dask_jobqueue`` each one uses)."""

NAMED = ("serial", "local", *JOBQUEUE_KINDS)
"""Scheduler values that are names rather than addresses."""


class SchedulerUnreachableError(InputError):
    """No Dask scheduler answered at the address given (``--scheduler`` / ``[survey] scheduler``)."""


def available_cores() -> int:
    """Cores this process may use: CPU affinity and cgroup (container, SLURM allocation) limits respected."""
    from dask.system import cpu_count

    return int(cpu_count())


@contextlib.contextmanager
def quiet_dask(level: int = logging.CRITICAL) -> Iterator[None]:
    """Raise the level of Dask's and tornado's loggers for the block (start-up and shutdown chatter)."""
    names = ("distributed", "distributed.client", "distributed.comm", "distributed.core", "tornado")
    old = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(level)
    try:
        yield
    finally:
        for n, lvl in old.items():
            logging.getLogger(n).setLevel(lvl)


def check_scheduler(scheduler, option: str = "scheduler") -> None:
    """Raise InputError (naming ``option``) unless ``scheduler`` is a value :func:`open_scheduler` accepts."""
    if scheduler is None or scheduler == "" or not isinstance(scheduler, str):
        return
    if scheduler in NAMED or "://" in scheduler or ":" in scheduler:
        return
    raise InputError(f"{option} = {scheduler!r} is not a Dask engine: use 'serial', 'local', 'slurm', 'pbs' or "
                     "a scheduler address such as tcp://host:8786")


def connect(address: str, timeout: float = 10.0):
    """A ``distributed.Client`` of the scheduler at ``address``; one-line error naming it if unreachable."""
    from distributed import Client

    try:
        with quiet_dask():
            return Client(address, timeout=f"{float(timeout)}s")
    except Exception as exc:  # OSError/TimeoutError on no answer, ValueError on a malformed address
        reason = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise SchedulerUnreachableError(
            f"cannot reach the Dask scheduler at {address} within {float(timeout):g} s ({reason}): start it "
            "(e.g. 'dask scheduler'), check the address, or use --scheduler local for a cluster on this "
            "machine") from None


def jobqueue_cluster(kind: str, options: dict | None = None, *, dashboard: bool = True):
    """A dask-jobqueue cluster (``kind`` "slurm" or "pbs") built from ``options`` (the ``[cluster]`` table).

    ``options`` are the cluster class's keyword arguments (``cores``, ``memory``, ``walltime``,
    ``queue``, ``account``, ``job_extra_directives``, ...); ``jobs`` (how many batch jobs to
    start) is taken out and left to the caller (:func:`open_scheduler` calls ``cluster.scale(jobs=...)``).
    Workers get one thread per process (``cores`` = ``processes``) unless ``processes`` is given.
    Needs ``pip install "spiralbayes[cluster]"`` (dask-jobqueue).
    """
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
    kwargs.setdefault("scheduler_options", {"dashboard_address": ":0" if dashboard else None})
    return getattr(dask_jobqueue, JOBQUEUE_KINDS[kind])(**kwargs)


def _local_cluster(n_workers: int | None, threads_per_worker: int, dashboard: bool):
    from distributed import LocalCluster

    n = int(n_workers) if n_workers else available_cores()
    with quiet_dask(logging.ERROR):
        return LocalCluster(n_workers=n, threads_per_worker=int(threads_per_worker), processes=True,
                            dashboard_address=":0" if dashboard else None, silence_logs=logging.ERROR)


def describe_scheduler(client) -> str:
    """One line naming the engine behind ``client``: ``"serial"``, ``"LocalCluster(2 workers x 1 thread)"``, ..."""
    if client is None:
        return "serial"
    cluster = getattr(client, "cluster", None)
    if cluster is None:
        return f"scheduler {client.scheduler.address}"
    name = type(cluster).__name__
    if name == "LocalCluster":
        n, threads = len(cluster.workers), (sorted(set(client.nthreads().values())) or [0])[0]
        return f"LocalCluster({n} worker{'s' if n != 1 else ''} x {threads} thread{'s' if threads != 1 else ''})"
    return name


@contextlib.contextmanager
def open_scheduler(scheduler, *, n_workers: int | None = None, threads_per_worker: int = 1,
                   dashboard: bool = True, cluster_options: dict | None = None, connect_timeout: float = 10.0,
                   default: str = "serial"):
    """A ``distributed.Client`` for ``scheduler`` (None for ``"serial"``), closed with its cluster on exit.

    Parameters
    ----------
    scheduler : str, distributed.Client or None
        ``"serial"``, ``"local"``, ``"slurm"``, ``"pbs"``, a scheduler address or a client (see
        the module docstring); None or ``""``: ``default``.
    n_workers : int, optional
        LocalCluster worker processes (None or 0: :func:`available_cores`).
    threads_per_worker : int
        Threads of each LocalCluster worker.
    dashboard : bool
        Serve the Dask dashboard (on a free port; its address is logged at INFO).
    cluster_options : dict, optional
        dask-jobqueue keyword arguments for ``"slurm"`` / ``"pbs"`` (``jobs``: batch jobs to start).
    connect_timeout : float
        Seconds to wait for a scheduler at an address.
    default : str
        What None or ``""`` means for the calling stage (``"serial"`` or ``"local"``).

    Yields
    ------
    distributed.Client or None
        None for a serial run. A client passed in is yielded as it is and never closed; a client
        made here is closed on exit together with the cluster (and its worker processes) it started.
    """
    if scheduler is None or (isinstance(scheduler, str) and not scheduler.strip()):
        scheduler = default
    if not isinstance(scheduler, str):  # a Client of the caller's: theirs to close
        yield scheduler
        return
    scheduler = scheduler.strip()
    check_scheduler(scheduler)
    if scheduler == "serial":
        yield None
        return
    try:
        from distributed import Client
    except ImportError:
        raise MissingDependencyError(f"scheduler = {scheduler!r} needs dask.distributed: pip install "
                                     "'dask[distributed]', or use scheduler = 'serial'") from None

    cluster = client = None
    try:
        if scheduler == "local":
            cluster = _local_cluster(n_workers, threads_per_worker, dashboard)
        elif scheduler in JOBQUEUE_KINDS:
            cluster = jobqueue_cluster(scheduler, cluster_options, dashboard=dashboard)
            cluster.scale(jobs=int((cluster_options or {}).get("jobs", 1)))
        if cluster is not None:
            with quiet_dask(logging.ERROR):
                client = Client(cluster)
        else:
            client = connect(scheduler, connect_timeout)
        log.info("Dask engine: %s; dashboard: %s", describe_scheduler(client),
                 getattr(client, "dashboard_link", None) if dashboard else "off")
        yield client
    finally:
        with quiet_dask():
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
