"""The one Dask engine (spiralbayes.cluster): what it starts it closes, worker processes included; a client
passed in stays the caller's; values it refuses name the option."""

import os
import time

import numpy as np
import psutil
import pytest

from spiralbayes.cluster import available_cores, check_scheduler, describe_scheduler, open_scheduler
from spiralbayes.exceptions import InputError


def _children() -> set[int]:
    return {p.pid for p in psutil.Process().children(recursive=True) if p.is_running()
            and p.status() != psutil.STATUS_ZOMBIE}


def _worker_pids(client) -> set[int]:
    return set(client.run(os.getpid).values())


def _wait_until_gone(pids: set[int], seconds: float = 10.0) -> set[int]:
    deadline = time.monotonic() + seconds
    alive = set(pids)
    while alive and time.monotonic() < deadline:
        alive = {pid for pid in alive if psutil.pid_exists(pid)
                 and psutil.Process(pid).status() != psutil.STATUS_ZOMBIE}
        time.sleep(0.2)
    return alive


def test_available_cores_is_dasks_cgroup_aware_count():
    from dask.system import cpu_count

    assert available_cores() == cpu_count() >= 1


def test_serial_yields_no_client_and_empty_means_the_default():
    with open_scheduler("serial") as client:
        assert client is None
    with open_scheduler(None, default="serial") as client:
        assert client is None
    with open_scheduler("", default="serial") as client:
        assert describe_scheduler(client) == "serial"


@pytest.mark.parametrize("bad", ["locl", "dask", "slrum"])
def test_unknown_engine_names_the_option(bad):
    with pytest.raises(InputError, match=rf"\[scan\] scheduler = '{bad}' is not a Dask engine: use 'serial', 'local'"):
        check_scheduler(bad, "[scan] scheduler")
    with pytest.raises(InputError, match="is not a Dask engine"), open_scheduler(bad):
        pass


def test_local_cluster_workers_end_with_the_block():
    before = _children()
    with open_scheduler("local", n_workers=2, dashboard=False) as client:
        assert describe_scheduler(client) == "LocalCluster(2 workers x 1 thread)"
        assert client.submit(sum, [1, 2, 3]).result() == 6
        started = _worker_pids(client)
        assert len(started) == 2 and started <= _children() - before
    assert client.status == "closed"
    assert _wait_until_gone(started) == set()


def test_scan_on_local_leaves_no_worker_and_a_given_client_open(monkeypatch, planet_observation, planet_templates):
    from dask.distributed import Client, LocalCluster

    from spiralbayes.inference.scan.run import scan
    from tests._support.helpers import GEOMETRY

    vis, axisym = planet_observation
    kwargs = dict(r_p=np.linspace(0.1, 0.5, 3), n_phi_p=10, progress=False)
    serial = scan(vis, axisym, planet_templates[:2], GEOMETRY, **kwargs)
    seen = set()
    real = Client.scatter

    def scatter(self, *args, **kw):  # note the pids of the workers the scan started
        seen.update(_worker_pids(self))
        return real(self, *args, **kw)

    monkeypatch.setattr(Client, "scatter", scatter)
    local = scan(vis, axisym, planet_templates[:2], GEOMETRY, client="local", **kwargs)
    assert len(seen) == available_cores()
    assert _wait_until_gone(seen) == set()  # the LocalCluster's workers went with the scan
    monkeypatch.undo()
    np.testing.assert_array_equal(local.dchi2, serial.dchi2)

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        given = scan(vis, axisym, planet_templates[:2], GEOMETRY, client=client, **kwargs)
        assert client.status == "running"  # the caller's client is the caller's to close
        assert client.submit(sum, [1, 2]).result() == 3
    np.testing.assert_array_equal(given.dchi2, serial.dchi2)


def test_one_cluster_builder():
    """Only spiralbayes.cluster makes Dask clients and clusters (so each is closed by the one context manager)."""
    import re
    from pathlib import Path

    import spiralbayes

    package = Path(spiralbayes.__file__).parent
    pattern = re.compile(r"\b(LocalCluster|Client|SLURMCluster|PBSCluster)\(|dask_jobqueue")
    found = [f"{p.relative_to(package)}:{i}" for p in sorted(package.rglob("*.py")) if p.name != "cluster.py"
             for i, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]
    assert not found, f"Dask clients or clusters made outside spiralbayes/cluster.py: {found}"
    assert pattern.search((package / "cluster.py").read_text())


def test_survey_engine_closes_its_local_cluster(tmp_path, monkeypatch):
    """run_survey on "local" leaves no worker behind; a client passed in stays open."""
    from dask.distributed import Client, LocalCluster

    from spiralbayes.pipeline.survey import run_survey

    path = tmp_path / "s.toml"
    path.write_text('[survey]\noutput = "out"\nfigures = false\n[[disc]]\nname = "missing"\npath = "none.h5"\n'
                    'distance = 140.0\ninc = 30.0\nPA = 10.0\n[templates]\nbank = "none.h5"\n')
    seen = set()
    real = Client.submit

    def submit(self, *args, **kw):
        if not seen:
            seen.update(_worker_pids(self))
        return real(self, *args, **kw)

    monkeypatch.setattr(Client, "submit", submit)
    run = run_survey(path, scheduler="local", n_workers=1, progress=False)
    monkeypatch.undo()
    assert run.engine == "LocalCluster(1 worker x 1 thread)" and run.exit_code == 1
    assert len(seen) == 1 and _wait_until_gone(seen) == set()
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        run = run_survey(path, scheduler=client, progress=False)
        assert client.status == "running" and run.engine == "LocalCluster(1 worker x 1 thread)"


def test_a_dask_engine_without_distributed_says_what_to_install(monkeypatch):
    import builtins

    from spiralbayes.exceptions import MissingDependencyError

    real_import = builtins.__import__

    def no_distributed(name, *args, **kw):
        if name.startswith("distributed"):
            raise ImportError("no distributed here")
        return real_import(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_distributed)
    with pytest.raises(MissingDependencyError, match=r"scheduler = 'local' needs dask.distributed: pip install"), \
            open_scheduler("local"):
        pass
    with open_scheduler("serial") as client:  # serial needs no Dask
        assert client is None
