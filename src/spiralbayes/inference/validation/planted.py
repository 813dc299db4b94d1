"""Calibration of exclusion limits: how often is a planet that is really there wrongly excluded?

:func:`planted_exclusion_rate` plants a planet (any template object: a bank template at the
reported limiting mass, or a spiral not made by the bank's generator, such as the reference maps
of the template-fidelity work) at ``(r_p, phi_p)`` into noise realisations of the data's own uv
coverage and weights, computes the family's limiting mass at ``r_p`` each time
(:func:`~spiralbayes.inference.limits.compute_limits`), and counts the realisations where the
planted mass lies in the excluded region (``M_lim <= M_true``). A calibrated limit at CL = 95 %
excludes a planet planted exactly as a bank template in at most 5 % of realisations; a planted
spiral that the bank's templates reproduce badly is excluded more often — the template systematic.

Noise enters the cross term linearly (``cross = cross_planet + cross_noise``), so each realisation
costs one residual dirty image on the quadrature at ``r_p`` and one FFT correlation per template;
neither frank nor the power term is recomputed. The axisymmetric model is the truth (the
realisations are model + planet + noise), which isolates the statistics of the limit from frank.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...exceptions import InputError
from ...results import ResultMixin, fields_dict
from ...model import perturbation_visibilities
from ...templates.template import template_metadata
from ..limits.exclusion import compute_limits
from ..scan.run import ScanResult
from ..scan.engine import ScanContext, cross_template, scan_template, with_residual
from ..scan.settings import ScanSettings

__all__ = ["PlantedExclusion", "planted_exclusion_rate"]


@dataclass(repr=False)
class PlantedExclusion(ResultMixin):
    """How often a planted planet was excluded.

    Attributes
    ----------
    planted : str
        Name of the planted template.
    family : str
        Label of the template family the limit assumes.
    true_mass : float
        Mass of the planted planet [M_th].
    r_p, phi_p : float
        Where it was planted [arcsec, rad].
    m_lim : ndarray
        Limiting mass at ``r_p`` in each realisation [M_th] (NaN: no limit).
    wrongly_excluded : ndarray of bool
        ``M_lim <= true_mass`` in each realisation.
    cl : float
    details : dict
        Method, hand, and the planted template's power ``sum w |ΔV|^2``.
    """

    planted: str
    family: str
    true_mass: float
    r_p: float
    phi_p: float
    m_lim: np.ndarray
    wrongly_excluded: np.ndarray
    cl: float
    details: dict = field(default_factory=dict)

    KIND = "spiralbayes.PlantedExclusion"
    WHAT = "planted-exclusion result"

    @property
    def n(self) -> int:
        return int(self.wrongly_excluded.size)

    @property
    def rate(self) -> float:
        return float(np.mean(self.wrongly_excluded))

    @property
    def rate_error(self) -> float:
        """Binomial standard error at the nominal rate ``1 - CL`` (the null hypothesis)."""
        p = 1.0 - self.cl
        return float(np.sqrt(p * (1 - p) / self.n))

    def summary(self) -> str:
        return (f"{self.planted} planted at r_p = {self.r_p:.3f} arcsec ({self.true_mass:.3g} M_th): wrongly "
                f"excluded in {self.wrongly_excluded.sum()} of {self.n} noise realisations "
                f"({100 * self.rate:.1f} %, nominal {100 * (1 - self.cl):.0f} % +- {100 * self.rate_error:.1f} %) "
                f"by the limit of the template family {self.family}.")

    def to_dict(self) -> dict:
        """The fields as JSON-safe values, with the rate and its error."""
        return {**fields_dict(self), "rate": self.rate, "rate_error": self.rate_error}

    def __repr__(self) -> str:
        return (f"PlantedExclusion({self.planted} at r_p = {self.r_p:.3g} arcsec, {self.true_mass:.3g} M_th: "
                f"wrongly excluded {self.wrongly_excluded.sum()} of {self.n}, CL = {self.cl:g})")


def planted_exclusion_rate(vis, axisymmetric, family_templates, planted, r_p: float, phi_p: float,
                           true_mass: float, *, n_realisations: int = 50, cl: float = 0.95, method: str = "all_phi",
                           hand: str = "both", n_phi_p: int = ScanSettings.n_phi_p, geometry=None, seed: int = 0,
                           amplitude: float = 1.0, robust: bool = False) -> PlantedExclusion:
    """Plant ``planted`` at ``(r_p, phi_p)`` into noise realisations and count wrong exclusions.

    Parameters
    ----------
    vis : Visibilities
        Supplies the uv points and weights (noise ``sigma_k = 1 / sqrt(w_k)``); its V are not used.
    axisymmetric : AxisymmetricModel or (profile, V_A)
        The disc (truth and model).
    family_templates : sequence of SpiralTemplate
        One template family (masses and hands) whose limit is tested.
    planted : SpiralTemplate
        The planet's spiral (need not come from the bank's generator).
    r_p, phi_p : float
        Planet position [arcsec, rad].
    true_mass : float
        The planted planet's mass [M_th]: "wrongly excluded" means ``M_lim(r_p) <= true_mass``.
    n_realisations : int
        Noise realisations (seeds ``seed ... seed + n - 1``).
    robust : bool
        ``family_templates`` may hold several families (e.g. the morphology variants of one
        (τ0, β, h_p), :mod:`spiralbayes.templates.variants`): the limit is then the robust one over
        all of them (:meth:`ExclusionLimits.robust_m_lim`), and ``details["m_lim_by_family"]``
        keeps each family's own limit from the same realisations (the single-template "before").
    """
    if n_realisations < 1:
        raise InputError(f"n_realisations must be >= 1, got {n_realisations}")
    geometry = geometry or axisymmetric.geometry
    vis = vis.standardised()
    templates = list(family_templates)
    context = ScanContext.build(vis, axisymmetric, geometry, [float(r_p)], n_phi_p,
                                x_max=max(float(np.max(t.x)) for t in templates))
    power = np.array([scan_template(context, t)[1] for t in templates])
    dv = amplitude * perturbation_visibilities(vis.u, vis.v, geometry, context.profile, planted, r_p, phi_p,
                                               cell_factor=context.cell_factor)
    cross_planet = np.array([cross_template(with_residual(context, dv), t) for t in templates])
    sigma = 1.0 / np.sqrt(vis.weights)
    meta = [template_metadata(t) for t in templates]
    phi_grid = 2 * np.pi * np.arange(n_phi_p) / n_phi_p
    m_lim = np.full(n_realisations, np.nan)
    wrong = np.zeros(n_realisations, dtype=bool)
    label = ""
    by_family: dict = {}
    for j in range(n_realisations):
        rng = np.random.default_rng(seed + j)
        noise = sigma * (rng.standard_normal(vis.n) + 1j * rng.standard_normal(vis.n))
        noisy = with_residual(context, noise)
        cross = cross_planet + np.array([cross_template(noisy, t) for t in templates])
        result = ScanResult(meta, context.r_p, phi_grid, cross, power, 0.0, vis.n, geometry)
        limits = compute_limits(result, cl=cl, method=method, hand=hand, resolution=0.0, bright_radius=np.inf)
        if robust:
            label = "robust over " + "; ".join(f.label for f in limits.families)
            value, stat = limits.robust_m_lim()
            value, status = value[0], stat[0]
            for fi, fam in enumerate(limits.families):
                ok = limits.m_lim_status[fi, 0] in ("limit", "below_bank")
                row = by_family.setdefault(fam.label, np.full(n_realisations, np.nan))
                row[j] = limits.m_lim[fi, 0] if ok else np.nan
        else:
            label = limits.families[0].label
            value, status = limits.m_lim[0, 0], limits.m_lim_status[0, 0]
        if status in ("limit", "below_bank"):
            m_lim[j] = value
            wrong[j] = m_lim[j] <= true_mass * (1 + 1e-9)
    planted_power = float(np.real(np.sum(vis.weights * np.abs(dv) ** 2)))
    return PlantedExclusion(getattr(planted, "name", "planted"), label, float(true_mass), float(r_p), float(phi_p),
                            m_lim, wrong, float(cl), {"method": method, "hand": hand, "planted_power": planted_power,
                             "m_lim_by_family": by_family})
