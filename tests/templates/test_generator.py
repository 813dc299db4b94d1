"""Built-in wake generator: geometry, amplitude trends, cooling, radiative transfer."""

import numpy as np
import pytest

from spiralbayes.templates import make_template, paper_grid
from spiralbayes.templates.wake import (
    WakeSettings,
    surface_density_perturbation,
)

SMALL = dict(n_x=120, n_phi=360, n_eta=1024)

def test_amplitude_grows_with_mass_and_falls_with_tau_isothermal():
    rms = {}
    for m in (0.1, 0.3, 1.0, 3.0):
        for tau in (0.1, 1.0, 3.0):
            rms[m, tau] = make_template(m, tau, 0.0, store_brightness=False, **SMALL).rms()
    for tau in (0.1, 1.0, 3.0):
        vals = [rms[m, tau] for m in (0.1, 0.3, 1.0, 3.0)]
        assert np.all(np.diff(vals) > 0), (tau, vals)
    for m in (0.1, 0.3, 1.0, 3.0):
        vals = [rms[m, tau] for tau in (0.1, 1.0, 3.0)]
        assert np.all(np.diff(vals) < 0), (m, vals)


@pytest.mark.parametrize("mass", [0.3, 1.0, 3.0])
def test_slow_cooling_brightens_optically_thick_spirals(mass):
    """τ0 = 3: the β = 10 temperature perturbation makes the residual larger (paper App. B)."""
    iso = make_template(mass, 3.0, 0.0, store_brightness=False, **SMALL)
    adi = make_template(mass, 3.0, 10.0, store_brightness=False, **SMALL)
    assert adi.rms() > 1.5 * iso.rms()


def test_isothermal_thick_disc_suppressed_like_linear_theory():
    """δ ≈ [τ e^{-τ}/(1 − e^{-τ})] δΣ/Σ for β = 0 (template-physics §2): small δΣ limit."""
    st = WakeSettings(secondary=False, gap=False, **SMALL)
    mass = 0.01
    dsig = surface_density_perturbation(mass, 0.0, st)
    for tau0 in (0.1, 1.0, 3.0):
        t = make_template(mass, tau0, 0.0, secondary=False, gap=False, **SMALL)
        i = np.argmin(np.abs(t.x - 1.0 / 1.5))
        tau = tau0 / t.x[i]  # τ = τ0 x^{-p}
        factor = tau * np.exp(-tau) / -np.expm1(-tau)
        ratio = np.max(t.delta[i]) / np.max(dsig[i])
        assert ratio == pytest.approx(factor, rel=0.05), tau0


def test_paper_grid_has_64_templates_per_aspect_ratio():
    grid = paper_grid(n_x=24, n_phi=90, n_eta=256)
    assert len(grid) == 64
    assert len({t.name for t in grid}) == 64
    assert {t.hand for t in grid} == {"R", "L"}
    assert all(t.delta.dtype == np.float32 and t.delta.shape == (24, 90) for t in grid)
    two = paper_grid(masses=(1.0,), taus=(3.0,), betas=(0.0,), h_ps=(0.05, 0.10), n_x=24, n_phi=90, n_eta=256)
    assert [t.name for t in two] == ["wake_m1_tau3_b0_h0.05_R", "wake_m1_tau3_b0_h0.05_L",
                                     "wake_m1_tau3_b0_h0.10_R", "wake_m1_tau3_b0_h0.10_L"]
    assert [t.h_p for t in two] == [0.05, 0.05, 0.10, 0.10]


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((-1.0, 1.0, 0.0), {}, "mass"),
        ((1.0, 0.0, 0.0), {}, "tau0"),
        ((1.0, 1.0, -2.0), {}, "beta"),
        ((1.0, 1.0, 0.0, "Q"), {}, "hand"),
        ((1.0, 1.0, 0.0), {"h_p": 2.0}, "h_p"),
        ((1.0, 1.0, 0.0), {"bogus": 1}, "valid options"),
        ((1.0, 1.0, 0.0), {"backend": "nope"}, "backend"),
    ],
)
def test_make_template_bad_inputs(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_template(*args, **{**SMALL, **kwargs})


def test_wakeflow_backend_was_removed_with_a_pointer():
    with pytest.raises(ValueError, match="template_from_perturbation"):
        make_template(1.0, 1.0, 0.0, backend="wakeflow", **SMALL)
