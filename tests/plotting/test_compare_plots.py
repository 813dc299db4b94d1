"""The Fig. 7-style comparison figure: images north up / east left, the scan's planet where it is."""

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest

from spiralbayes.image_plane import CleanImage, CleanResiduals, gap_depth, residual_detection
from spiralbayes.fourier import image_axes
from spiralbayes.inference.detection.verdict import detect
from spiralbayes.plotting.compare import plot_comparison
from tests._support.helpers import DISTANCE, GEOMETRY

CELL, N = 0.02, 160


def _clean(image):
    return CleanImage(image=image, residual=np.zeros_like(image), model=np.zeros_like(image), cell=CELL,
                      beam=(0.1, 0.06, 30.0), sumwt=1.0, iterations=0)


def test_comparison_figure(planet_scan):
    l, m = image_axes((N, N), CELL)
    ll, mm = np.meshgrid(l, m)
    r, _ = GEOMETRY.sky_to_disc(ll, mm)
    disc = np.where(r < 0.75, 1e-3 * (0.1 + r) ** -1, 0.0)
    east_blob = 1e-4 * np.exp(-0.5 * ((ll - 0.4) ** 2 + mm**2) / 0.03**2)  # 0.4" east
    rng = np.random.default_rng(0)
    residual = east_blob + rng.normal(scale=1e-5, size=(N, N))
    data = _clean(disc + residual)
    det = residual_detection(residual, CELL, GEOMETRY, 0.75, data.beam)
    residuals = CleanResiduals(data=data, model=_clean(residual), difference=residual, detection=det,
                               method="visibilities")
    gap = gap_depth(data, GEOMETRY, 0.75, noise=1e-5)
    verdict = detect(planet_scan)
    fig = plot_comparison(residuals, gap, planet_scan, verdict, GEOMETRY, distance=DISTANCE)
    image_ax, residual_ax, heatmap_ax, profile_ax = fig.axes[:4]
    # east is left: the x axis runs from +RA offsets on the left to -RA on the right
    left, right = image_ax.get_xlim()
    assert left > 0 > right
    # the brightest residual pixel is drawn at +0.4" (east), where it was put
    shown = residual_ax.images[0].get_array()
    iy, ix = np.unravel_index(np.argmax(shown), shown.shape)
    x0, x1, y0, y1 = residual_ax.images[0].get_extent()
    x = x0 + (ix + 0.5) * (x1 - x0) / shown.shape[1]
    assert x == pytest.approx(0.4, abs=CELL) and det.verdict == "detected"
    # the scan's planet is marked at its sky position
    l_p, m_p = GEOMETRY.disc_to_sky(verdict.r_p, np.radians(verdict.phi_p_deg))
    px, py = residual_ax.lines[0].get_data()
    assert px[0] == pytest.approx(l_p) and py[0] == pytest.approx(m_p)
    assert "Delta" in heatmap_ax.get_title() or "BIC" in heatmap_ax.get_title()
    assert "au" in profile_ax.get_xlabel() and "none" in profile_ax.get_title()
