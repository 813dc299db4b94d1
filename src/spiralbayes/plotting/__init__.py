"""Plots of spiralbayes results; every function returns a Matplotlib Figure (no pyplot state).

In a notebook the Figure displays itself; elsewhere call ``fig.savefig(path)``.
"""

from .alternatives import plot_residual_comparison
from .axisymmetric import plot_binned_visibilities, plot_profile
from .calibration import plot_gain_phases
from .limits import plot_completeness, plot_excluded_fraction, plot_mass_radius
from .posterior import plot_corner, plot_hypotheses, plot_template_probabilities, plot_trace
from .scan import plot_chi2_vs_rp, plot_heatmap, plot_heatmap_pair, plot_template_grid_heatmaps
from .templates import plot_bank_overview, plot_template

__all__ = [
    "plot_bank_overview",
    "plot_binned_visibilities",
    "plot_chi2_vs_rp",
    "plot_completeness",
    "plot_corner",
    "plot_excluded_fraction",
    "plot_gain_phases",
    "plot_heatmap",
    "plot_heatmap_pair",
    "plot_hypotheses",
    "plot_mass_radius",
    "plot_profile",
    "plot_residual_comparison",
    "plot_template",
    "plot_template_grid_heatmaps",
    "plot_template_probabilities",
    "plot_trace",
]
