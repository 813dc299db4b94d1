"""ScanSettings: one default per scan option, validation naming the field, and ``scan(settings=)`` equal to keywords."""

import dataclasses

import numpy as np
import pytest

import spiralbayes as sb
from spiralbayes.exceptions import InputError
from spiralbayes.inference.scan.run import scan
from spiralbayes.inference.scan.settings import R_EFF_FRACTION, ScanSettings, grid_radii
from tests._support.helpers import GEOMETRY

SMALL = dict(n_phi_p=16, progress=False)
RADII = np.array([0.15, 0.3, 0.45])


def test_defaults_are_the_papers_grid_rule_and_the_exact_quadrature():
    s = sb.ScanSettings()
    assert sb.ScanSettings is ScanSettings
    assert (s.r_p_min, s.r_p_max, s.n_r_p, s.n_phi_p) == (None, None, 25, 90)
    assert (s.amplitude, s.quadrature, s.power_path, s.nthreads) == ("fixed", "product", "auto", 1)
    assert s.building_blocks and s.checkpoint and s.free_amplitude is None
    assert ScanSettings(amplitude="free").free_amplitude == "free"
    assert all(f.metadata["doc"] for f in dataclasses.fields(ScanSettings))


@pytest.mark.parametrize("field,value,match", [
    ("r_p_min", -0.1, "positive, finite number"),
    ("r_p_max", float("nan"), "positive, finite number"),
    ("r_p_max", "0.5", "positive, finite number"),
    ("n_r_p", 0, "integer >= 1"),
    ("n_r_p", 2.0, "integer >= 1"),
    ("n_phi_p", 15, "positive, even integer"),
    ("n_phi_p", True, "positive, even integer"),
    ("amplitude", "fitted", "'fixed', 'free'"),
    ("quadrature", "simpson", "'product', 'midpoint'"),
    ("cell_factor", 0.0, "positive number"),
    ("power_path", "gpu", "'auto', 'polar', 'direct'"),
    ("nthreads", 0, "integer >= 1"),
    ("building_blocks", "yes", "True or False"),
    ("checkpoint", 1, "True or False"),
])
def test_bad_values_raise_input_error_naming_the_field(field, value, match):
    with pytest.raises(InputError, match=rf"ScanSettings\.{field} = .* {match}"):
        ScanSettings(**{field: value})


def test_bounds_must_be_ordered():
    with pytest.raises(InputError, match=r"r_p_min = 0.5 must be smaller than r_p_max = 0.4"):
        ScanSettings(r_p_min=0.5, r_p_max=0.4)


class _Profile:
    """Stands in for an AxisymmetricModel: only R_eff matters to the grid."""

    def __init__(self, r_eff):
        self.r_eff = r_eff

    def R_eff(self):
        return self.r_eff


def test_automatic_grid_is_the_papers_for_its_discs_and_scales_with_r_eff():
    paper = ScanSettings().planet_radii(_Profile(0.5 / R_EFF_FRACTION))  # R_eff 0.833 arcsec: r_p_max 0.5
    np.testing.assert_allclose(paper, np.linspace(0.02, 0.5, 25), rtol=1e-12)
    np.testing.assert_allclose(ScanSettings(r_p_min=0.02, r_p_max=0.5).planet_radii(), paper, rtol=1e-12)
    small = ScanSettings(n_r_p=4).planet_radii(_Profile(1.0))
    np.testing.assert_allclose(small, [0.15, 0.3, 0.45, 0.6], rtol=1e-12)
    np.testing.assert_allclose(ScanSettings(r_p_min=0.3, n_r_p=3).planet_radii(_Profile(1.0)), [0.3, 0.45, 0.6])
    with pytest.raises(InputError, match="automatic grid needs an axisymmetric model"):
        ScanSettings().planet_radii(object())
    with pytest.raises(InputError, match=r"r_p_min = 0.7 arcsec is not below the automatic r_p_max = 0.6"):
        grid_radii(0.7, None, 5, _Profile(1.0))


def test_scan_with_settings_equals_scan_with_keywords(planet_observation, small_bank):
    vis, axisym = planet_observation
    templates = list(small_bank)[:2]
    settings = ScanSettings(n_phi_p=16, power_path="direct", building_blocks=False, nthreads=1)
    by_settings = scan(vis, axisym, templates, GEOMETRY, settings=settings, r_p=RADII, progress=False)
    by_keywords = scan(vis, axisym, templates, GEOMETRY, r_p=RADII, n_phi_p=16, power_path="direct",
                       building_blocks=False, progress=False)
    mixed = scan(vis, axisym, templates, GEOMETRY, settings=ScanSettings(n_phi_p=90), r_p=RADII, n_phi_p=16,
                 power_path="direct", building_blocks=False, progress=False)  # keywords override settings
    for other in (by_keywords, mixed):
        np.testing.assert_array_equal(other.r_p, by_settings.r_p)
        np.testing.assert_array_equal(other.phi_p, by_settings.phi_p)
        np.testing.assert_array_equal(other.cross, by_settings.cross)
        np.testing.assert_array_equal(other.power, by_settings.power)
    assert by_settings.phi_p.size == 16
    assert by_settings.provenance["scan_settings"]["power_path"] == "direct"
    # and a different setting changes the numbers (the comparison can fail)
    midpoint = scan(vis, axisym, templates, GEOMETRY, settings=dataclasses.replace(settings, quadrature="midpoint"),
                    r_p=RADII, progress=False)
    assert not np.array_equal(midpoint.power, by_settings.power)


def test_default_grid_of_scan_is_the_settings_grid(planet_observation, planet_templates):
    vis, axisym = planet_observation
    result = scan(vis, axisym, planet_templates[:1], GEOMETRY, settings=ScanSettings(n_r_p=3, n_phi_p=16),
                  progress=False)
    np.testing.assert_allclose(result.r_p, R_EFF_FRACTION * axisym.R_eff() * np.array([1, 2, 3]) / 3, rtol=1e-12)


def test_old_keywords_warn_and_unknown_ones_are_refused(planet_observation, planet_templates):
    vis, axisym = planet_observation
    with pytest.warns(FutureWarning, match=r"scan\(rule=...\) is renamed quadrature="):
        old = scan(vis, axisym, planet_templates[:1], GEOMETRY, r_p=RADII, rule="midpoint", **SMALL)
    assert old.provenance["scan_settings"]["quadrature"] == "midpoint"
    with pytest.warns(FutureWarning, match=r"scan\(client=...\) is renamed scheduler="):
        scan(vis, axisym, planet_templates[:1], GEOMETRY, r_p=RADII, client=None, **SMALL)
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['n_phi'\]"):
        scan(vis, axisym, planet_templates[:1], GEOMETRY, r_p=RADII, n_phi=16, progress=False)
    with pytest.raises(TypeError, match="pass scheduler= only"):
        scan(vis, axisym, planet_templates[:1], GEOMETRY, r_p=RADII, client="local", scheduler="local", **SMALL)
    with pytest.raises(InputError, match=r"ScanSettings.n_phi_p = 15"):
        scan(vis, axisym, planet_templates[:1], GEOMETRY, r_p=RADII, n_phi_p=15, progress=False)


def test_checkpoint_false_writes_no_checkpoint(tmp_path, planet_observation, planet_templates):
    vis, axisym = planet_observation
    path = tmp_path / "scan.h5"
    scan(vis, axisym, planet_templates[:1], GEOMETRY, settings=ScanSettings(n_phi_p=16, checkpoint=False), r_p=RADII,
         checkpoint=path, progress=False)
    assert not path.exists()
    scan(vis, axisym, planet_templates[:1], GEOMETRY, settings=ScanSettings(n_phi_p=16), r_p=RADII, checkpoint=path,
         progress=False)
    assert path.exists()


class _GeometryAlternative:
    """Stands in for an AlternativesResult whose geometry alternative found the disc's own geometry."""

    def fitted_geometry(self):
        return GEOMETRY


def test_rescan_takes_scan_settings_and_reuses_the_first_scans_grid(planet_observation, planet_templates):
    from spiralbayes.inference.detection.follow_up import rescan_at_fitted_geometry

    vis, axisym = planet_observation
    template = planet_templates[:1]
    first = scan(vis, axisym, template, GEOMETRY, r_p=RADII, **SMALL)
    kwargs = dict(refit=lambda geometry: axisym, refit_alternatives=False)  # the same model: the same numbers
    again = rescan_at_fitted_geometry(vis, axisym, template, _GeometryAlternative(), scan_result=first, **kwargs)
    np.testing.assert_array_equal(again.scan.r_p, first.r_p)
    assert again.scan.phi_p.size == 16  # the first scan's azimuths, not the default 90
    np.testing.assert_array_equal(again.scan.cross, first.cross)
    assert again.verdict.template == first.best.template
    coarser = rescan_at_fitted_geometry(vis, axisym, template, _GeometryAlternative(), scan_result=first,
                                        settings=ScanSettings(n_phi_p=8, amplitude="free"), **kwargs)
    assert coarser.scan.phi_p.size == 8 and coarser.scan.r_p.size == RADII.size
    with pytest.warns(FutureWarning, match=r"previous_scan=...\) is renamed scan_result="):
        old = rescan_at_fitted_geometry(vis, axisym, template, _GeometryAlternative(), previous_scan=first,
                                        amplitude=None, nthreads=1, **kwargs)
    np.testing.assert_array_equal(old.scan.cross, first.cross)
    with pytest.raises(TypeError, match="unknown keyword"):
        rescan_at_fitted_geometry(vis, axisym, template, _GeometryAlternative(), scan_result=first, n_phi=8, **kwargs)


def test_scheduler_addresses_are_checked_under_the_name_the_user_gave():
    from spiralbayes.pipeline.scan_command import check_dask_address

    for serial in ("", "serial", "local"):
        check_dask_address(serial)
    with pytest.raises(InputError, match=r"^scan.scheduler = 'tcp://:0' is not a scheduler address"):
        check_dask_address("tcp://:0")
    with pytest.raises(InputError, match=r"^--dask = 'tcp://:0'"):
        check_dask_address("tcp://:0", option="--dask")
