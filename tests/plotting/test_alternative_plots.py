"""The residual comparison figure: one colour scale, the right images, the right labels."""

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest

from spiralbayes.fourier import dirty_image
from spiralbayes.plotting.alternatives import plot_residual_comparison


def test_residual_comparison_shares_one_scale_and_adds_up(planet_observation, planet_scan, planet_alternatives,
                                                          planet_templates):
    vis, axisym = planet_observation
    fig = plot_residual_comparison(vis, axisym, planet_scan, planet_alternatives, planet_templates)
    images = [ax.images[0] for ax in fig.axes if ax.images]
    assert len(images) == 5
    assert len({(im.norm.vmin, im.norm.vmax) for im in images}) == 1
    data, spiral, alternative, left_after_spiral, left_after_alt = (np.asarray(im.get_array()) for im in images)
    assert images[0].norm.vmax == pytest.approx(np.max(np.abs(data)))
    np.testing.assert_allclose(left_after_spiral, data - spiral, atol=1e-6 * np.max(np.abs(data)))
    np.testing.assert_allclose(left_after_alt, data - alternative, atol=1e-6 * np.max(np.abs(data)))
    n = data.shape[0]
    pixel = abs(images[0].get_extent()[1] - images[0].get_extent()[0]) / n
    V_A = axisym.visibilities(vis.u, vis.v, planet_scan.geometry)
    np.testing.assert_allclose(data, dirty_image(vis.u, vis.v, vis.V - V_A, vis.weights, (n, n), pixel),
                               atol=1e-9 * np.max(np.abs(data)))
    titles = " ".join(ax.get_title() for ax in fig.axes)
    assert "wake_m1_tau3_b10_h0.07_R" in titles and planet_alternatives.best.label in titles
    # the spiral explains the residual: what it leaves is much fainter than the data residual
    assert np.std(left_after_spiral) < 0.8 * np.std(data)
