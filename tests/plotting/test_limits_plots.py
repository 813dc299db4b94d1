"""Limits plots: excluded-fraction heatmaps, the mass–radius plane, the completeness map."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from spiralbayes.inference.limits.recovery import completeness
from spiralbayes.inference.limits.exclusion import compute_limits
from spiralbayes.plotting.limits import plot_completeness, plot_excluded_fraction, plot_mass_radius


@pytest.fixture(scope="module")
def limits_and_completeness(bright_case):
    vis, model, templates, result = bright_case
    limits = compute_limits(result, resolution=0.2, bright_radius=np.inf)
    comp = completeness(vis, model, templates, result, n_azimuths=2, progress=False)
    return limits, comp


def test_plots_are_figures_with_the_right_panels(tmp_path, limits_and_completeness):
    limits, comp = limits_and_completeness
    fig = plot_excluded_fraction(limits)
    assert isinstance(fig, Figure) and len(fig.axes) == 3  # two hands + colour bar
    mesh = fig.axes[0].collections[0]
    values = np.ma.getdata(mesh.get_array()).reshape(3, -1)
    np.testing.assert_allclose(values[:, 1:], limits.excluded_fraction[::2, 1:])  # R rows, unflagged radii
    assert np.isnan(values[:, 0]).all()  # the flagged radius is not coloured
    fig = plot_mass_radius(limits, completeness=comp)
    assert len(fig.axes) == 2 and fig.axes[1].get_ylabel().endswith("[$M_{\\rm Jup}$]")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any("M_{\\rm lim}" in t for t in labels) and any("50%" in t for t in labels)
    fig = plot_completeness(comp, unit="arcsec")
    assert fig.axes[0].get_xlabel() == "r_p [arcsec]"
    fig.savefig(tmp_path / "c.png")
    assert (tmp_path / "c.png").stat().st_size > 1000


def test_bad_unit(limits_and_completeness):
    with pytest.raises(ValueError, match="unit"):
        plot_completeness(limits_and_completeness[1], unit="pc")
