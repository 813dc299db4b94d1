"""TemplateBank: HDF5 round trip, selection, default bank cache; template plots."""

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from spiralbayes.templates import TemplateBank, make_template

TINY = dict(n_x=24, n_phi=90, n_eta=256)

@pytest.fixture(scope="module")
def small_bank():
    ts = [make_template(m, tau, b, h, store_brightness=False, **TINY)
          for m in (0.3, 1.0) for tau in (0.1, 3.0) for b in (0.0, 10.0) for h in "RL"]
    return TemplateBank(ts, {"note": "test"})


def test_plots_return_figures(small_bank):
    from matplotlib.figure import Figure

    from spiralbayes.plotting.templates import plot_bank_overview, plot_template

    t = make_template(1.0, 1.0, 10.0, **TINY)
    fig = plot_template(t, rmax=1.5)
    assert isinstance(fig, Figure) and len(fig.axes) >= 2
    xy = fig.axes[0].collections[0].get_coordinates()
    r_edge = np.hypot(xy[..., 0], xy[..., 1]).max()
    cell = (2.2 / 0.2) ** (1 / 24)
    assert 1.5 / cell < r_edge < 1.5 * cell  # the map stops within a cell of rmax
    fig = plot_template(small_bank[0])  # no stored brightness
    assert isinstance(fig, Figure)
    fig = plot_bank_overview(small_bank, beta=10.0, hand="L")
    assert isinstance(fig, Figure)
    panels = [ax for ax in fig.axes if ax.collections and ax.get_label() != "<colorbar>"]
    assert len(panels) == 4  # 2 masses × 2 τ0
    with pytest.raises(ValueError, match="no templates"):
        plot_bank_overview(small_bank, beta=3.0)
    # a bank with several aspect ratios: one H/r per figure (0.07 by default)
    mixed = TemplateBank(list(small_bank) + [make_template(1.0, 3.0, 10.0, "L", h_p=0.05, **TINY)])
    fig = plot_bank_overview(mixed, beta=10.0, hand="L")
    assert len([ax for ax in fig.axes if ax.collections and ax.get_label() != "<colorbar>"]) == 4
    assert "0.07" in fig._suptitle.get_text()
    fig = plot_bank_overview(mixed, beta=10.0, hand="L", h_p=0.05)
    assert len([ax for ax in fig.axes if ax.collections and ax.get_label() != "<colorbar>"]) == 1
