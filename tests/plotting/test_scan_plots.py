"""Scan plots: diverging colours centred on zero, the best instance marked where it is."""

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest

from spiralbayes.plotting.scan import (
    plot_chi2_vs_rp,
    plot_heatmap,
    plot_heatmap_pair,
    plot_template_grid_heatmaps,
)
from tests._support.helpers import DISTANCE


def test_heatmap_pair_shares_a_zero_centred_colour_scale(planet_scan):
    fig = plot_heatmap_pair(planet_scan, 0, 1)
    meshes = [ax.collections[0] for ax in fig.axes[:2]]
    assert meshes[0].norm is meshes[1].norm
    assert meshes[0].norm.vcenter == 0
    assert meshes[0].norm.vmax == pytest.approx(np.max(planet_scan.dchi2[:2]))


def test_heatmap_marks_best_instance_in_au(planet_scan):
    fig = plot_heatmap(planet_scan, 0, unit="au")
    ax = fig.axes[0]
    x, y = ax.lines[0].get_data()
    best = planet_scan.peak(0)
    r = best.r_p * DISTANCE
    assert x[0] == pytest.approx(r * np.cos(best.phi_p)) and y[0] == pytest.approx(r * np.sin(best.phi_p))
    assert "au" in ax.get_xlabel() and "minor axis" in ax.get_xlabel()


def test_asymmetric_limits_and_other_plots(planet_scan):
    fig = plot_heatmap(planet_scan, 1, vmin=-50, vmax=200, unit="arcsec")
    norm = fig.axes[0].collections[0].norm
    assert (norm.vmin, norm.vcenter, norm.vmax) == (-50, 0, 200)
    fig = plot_chi2_vs_rp(planet_scan, quantity="delta_chi2")
    assert len(fig.axes[0].lines) == 3  # two templates + the zero line
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), planet_scan.dchi2[0].max(axis=1))
    fig = plot_chi2_vs_rp(planet_scan)  # chi2_SA: the noise-free signal of each template, with 6 ln N
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), planet_scan.power[0].mean(axis=1))
    assert fig.axes[0].lines[-1].get_ydata()[0] == pytest.approx(6 * np.log(planet_scan.n_data))
    fig = plot_template_grid_heatmaps(planet_scan, hand="R")
    assert len([a for a in fig.axes if a.get_title().startswith("M=")]) == 1
    with pytest.raises(ValueError, match="no scanned template"):
        plot_template_grid_heatmaps(planet_scan, hand="R", beta=0.0)
