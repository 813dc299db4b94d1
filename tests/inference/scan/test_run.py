"""The grid scan: exactness, injection-recovery, null and phase-centre-error cases, resume, Dask."""

import numpy as np
import pytest

from spiralbayes.exceptions import ResumeMismatchError
from spiralbayes.fourier import sample_image
from spiralbayes.inference.scan.run import ScanResult, scan
from spiralbayes.inference.scan.engine import direct_delta_chi2
from spiralbayes.inference.scan.statistics import chi2
from spiralbayes.model import render_perturbation_image
from tests._support.helpers import DISTANCE, GEOMETRY, SCAN_RP


def image_delta_chi2(vis, axisym, template, r_p, phi_p, pixel):
    """Naive reference: render the perturbation image, NUFFT it, sum chi^2 (as the authors' loop)."""
    n = int(2 * 2.3 * r_p / pixel) + 16
    n += n % 2
    image = render_perturbation_image(axisym.brightness, template, r_p, phi_p, GEOMETRY.inc, (n, n), pixel)
    dV = sample_image(image, pixel, vis.u, vis.v, PA=GEOMETRY.PA, dRA=GEOMETRY.dRA, dDec=GEOMETRY.dDec)
    VA = axisym.visibilities(vis.u, vis.v, GEOMETRY)
    return chi2(VA, vis.V, vis.weights) - chi2(VA + dV, vis.V, vis.weights)


def test_scan_equals_direct_image_evaluation(planet_observation, planet_templates, planet_scan):
    vis, axisym = planet_observation
    rng = np.random.default_rng(11)
    picks = [(0, 14, 0)] + [(int(rng.integers(2)), int(rng.integers(1, 10)), int(rng.integers(90))) for _ in range(3)]
    for t, i, j in picks:
        r_p, phi_p = SCAN_RP[i], planet_scan.phi_p[j]
        coarse = image_delta_chi2(vis, axisym, planet_templates[t], r_p, phi_p, 0.002)
        fine = image_delta_chi2(vis, axisym, planet_templates[t], r_p, phi_p, 0.001)
        assert abs(fine - coarse) <= 0.01 * abs(fine) + 0.02  # the reference itself is converged
        fast = planet_scan.dchi2[t, i, j]
        assert abs(fast - fine) <= 0.05 + 1e-3 * abs(fine), (t, r_p, phi_p, fast, fine)


def test_scan_equals_exact_quadrature_sum(planet_observation, planet_templates, planet_scan):
    vis, axisym = planet_observation
    for t, i, j in [(0, 3, 10), (1, 20, 77), (0, 24, 45)]:
        exact = direct_delta_chi2(vis, axisym, GEOMETRY, planet_templates[t], SCAN_RP[i], planet_scan.phi_p[j])
        assert planet_scan.dchi2[t, i, j] == pytest.approx(exact, rel=2e-5, abs=1e-3)


def test_free_amplitude_never_worse(planet_scan):
    free = planet_scan.delta_chi2("free")
    assert np.all(free >= planet_scan.dchi2 - 1e-9)
    assert np.all(free >= -1e-9)


def test_resume_after_interruption_gives_identical_result(tmp_path, monkeypatch, planet_observation, small_bank):
    import importlib

    # the package exports a function of that name
    scan_module = importlib.import_module("spiralbayes.inference.scan.run")

    vis, axisym = planet_observation
    kwargs = dict(r_p=np.linspace(0.1, 0.5, 5), n_phi_p=30, progress=False)
    reference = scan(vis, axisym, small_bank, GEOMETRY, **kwargs)
    checkpoint = tmp_path / "scan.h5"
    real = scan_module.scan_template
    calls = {"n": 0}

    def interrupted(context, template):
        if calls["n"] == 2:
            raise KeyboardInterrupt
        calls["n"] += 1
        return real(context, template)

    monkeypatch.setattr(scan_module, "scan_template", interrupted)
    with pytest.raises(KeyboardInterrupt):
        scan(vis, axisym, small_bank, GEOMETRY, checkpoint=checkpoint, **kwargs)
    partial = ScanResult.load(checkpoint)
    assert partial.completed.tolist() == [True, True, False, False]
    monkeypatch.setattr(scan_module, "scan_template", real)
    calls_after = {"n": 0}

    def counting(context, template):
        calls_after["n"] += 1
        return real(context, template)

    monkeypatch.setattr(scan_module, "scan_template", counting)
    resumed = scan(vis, axisym, small_bank, GEOMETRY, checkpoint=checkpoint, **kwargs)
    assert calls_after["n"] == 2  # only the two missing templates were computed
    np.testing.assert_array_equal(resumed.dchi2, reference.dchi2)


def test_checkpoint_for_other_inputs_is_refused(tmp_path, planet_observation, small_bank):
    vis, axisym = planet_observation
    checkpoint = tmp_path / "scan.h5"
    scan(vis, axisym, small_bank[:2], GEOMETRY, r_p=[0.2, 0.3], n_phi_p=10, progress=False, checkpoint=checkpoint)
    with pytest.raises(ResumeMismatchError, match=r"other inputs — the planet grid \(2 r_p from 0.2 to 0.3 arcsec"):
        scan(vis, axisym, small_bank[:2], GEOMETRY, r_p=[0.2, 0.4], n_phi_p=10, progress=False,
             checkpoint=checkpoint)


def test_dask_and_serial_agree(planet_observation, small_bank):
    from dask.distributed import Client, LocalCluster

    vis, axisym = planet_observation
    kwargs = dict(r_p=np.linspace(0.1, 0.5, 4), n_phi_p=30, progress=False)
    serial = scan(vis, axisym, small_bank, GEOMETRY, **kwargs)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        parallel = scan(vis, axisym, small_bank, GEOMETRY, scheduler=client, **kwargs)
    np.testing.assert_array_equal(parallel.dchi2, serial.dchi2)


def test_save_load_round_trip(tmp_path, planet_scan):
    path = planet_scan.save(tmp_path / "result.h5")
    loaded = ScanResult.load(path)
    np.testing.assert_array_equal(loaded.dchi2, planet_scan.dchi2)
    assert loaded.templates == planet_scan.templates
    assert loaded.geometry == planet_scan.geometry and loaded.distance == DISTANCE
    assert loaded.best == planet_scan.best


def test_bad_inputs(planet_observation, small_bank):
    vis, axisym = planet_observation
    with pytest.raises(ValueError, match="no templates"):
        scan(vis, axisym, [], GEOMETRY, r_p=[0.2])
    with pytest.raises(ValueError, match="r_p must be positive"):
        scan(vis, axisym, small_bank, GEOMETRY, r_p=[-0.1, 0.2])
    first = small_bank[0]
    with pytest.raises(ValueError, match=f"'{first.name}'.*give each template its own"):
        scan(vis, axisym, [first, *small_bank], GEOMETRY, r_p=[0.2])


def test_without_dask_a_parallel_request_falls_back_to_serial(monkeypatch, caplog, planet_observation, small_bank):
    import builtins

    vis, axisym = planet_observation
    kwargs = dict(r_p=[0.2, 0.3], n_phi_p=10, progress=False)
    serial = scan(vis, axisym, small_bank[:2], GEOMETRY, **kwargs)
    real_import = builtins.__import__

    def no_dask(name, *args, **kw):
        if name.startswith("dask"):
            raise ImportError("no dask here")
        return real_import(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    fallback = scan(vis, axisym, small_bank[:2], GEOMETRY, scheduler="local", **kwargs)
    np.testing.assert_array_equal(fallback.dchi2, serial.dchi2)
    assert "scanning serially" in caplog.text
