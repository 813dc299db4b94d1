"""Axisymmetric frank model: fits recover known discs, exact visibilities, image vs Hankel, I/O.

References used: analytic transforms of Gaussians, frank's own ``sol.predict`` /
``predict_deprojected`` / ``interpolate_brightness``, the NUFFT of ``spiralbayes.fourier``,
and synthetic data with a known profile, geometry and noise."""

import matplotlib
import pytest

matplotlib.use("Agg")
from tests._support.axisymmetric_setup import ring_and_core


# --- plots and the CLI function ----------------------------------------------------------------------
def test_plots_return_figures(fixed_fit, synthetic):
    from matplotlib.figure import Figure

    from spiralbayes.plotting.axisymmetric import plot_binned_visibilities, plot_profile

    fig = plot_profile(fixed_fit, truth=ring_and_core, distance=140.0)
    assert isinstance(fig, Figure) and len(fig.axes) >= 1
    fig = plot_binned_visibilities(synthetic, fixed_fit, bin_width=50e3)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    fig = plot_binned_visibilities(synthetic, fixed_fit, bin_width=50e3, logx=True, units="Mlambda")
    assert fig.axes[0].get_xscale() == "log"
    with pytest.raises(ValueError, match="units"):
        plot_binned_visibilities(synthetic, fixed_fit, units="parsec")
