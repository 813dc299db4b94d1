"""The learned model's predictive uncertainty: :class:`PredictionUncertainty`.

The outputs of the model (basis coefficients, gap coefficients, amplitudes) are Gaussian-process
predictions with standard deviations; :func:`prediction_uncertainty` draws them from their
predictive distributions, puts each draw through the template's isothermal transfer, and adds what
the map basis leaves out of the training maps. The result is the spread of the predicted ``δΣ/Σ``
and δ per cell and the expected relative error of the template as the visibilities weigh it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..radiative import template_from_perturbation
from .training import DISC_EXTENT, FLARING

__all__ = ["PredictionUncertainty", "prediction_uncertainty", "transfer"]


@dataclass
class PredictionUncertainty:
    """The model's predictive uncertainty at one point
    (:meth:`~spiralbayes.templates.learned.model.LearnedTemplateModel.predict_uncertainty`).

    Attributes
    ----------
    dsigma_std : (n_x, n_phi) array
        Standard deviation of the predicted δΣ/Σ per cell (the coefficients' and the amplitude's
        Gaussian-process errors, and what the basis leaves out of the training maps).
    delta_std : (n_x, n_phi) array
        Standard deviation of the template's δ at the τ0 asked for (the draws through the transfer).
    coefficient_std : (n_components,) array
        Predictive standard deviations of the basis coefficients (normalised, weighted map units).
    gap_coefficient_std : (n_gap_components [+ 1],) array
        The gap's coefficients (and ``ln D``, its depth, with ``gap_depth``).
    patch_coefficient_std : (n_patch_components [+ 1],) array
        The near-planet patch's coefficients and ``ln P``, its RMS (empty without ``patch``).
    log_amplitude_std : float
        Standard deviation of ``ln A`` (the map's weighted RMS).
    relative_error : float
        Expected ``‖δ_true − δ_predicted‖ / ‖δ_predicted‖`` at the τ0 asked for, weighted as the
        visibilities weigh δ: the model's own estimate of ``sqrt(1 − recovery)``.
    """

    dsigma_std: np.ndarray
    delta_std: np.ndarray
    coefficient_std: np.ndarray
    gap_coefficient_std: np.ndarray
    patch_coefficient_std: np.ndarray
    log_amplitude_std: float
    relative_error: float

    @property
    def expected_recovery(self) -> float:
        """``1 − relative_error²``: the fraction of the true map's Δχ² the template should recover."""
        return float(1.0 - self.relative_error**2)


def transfer(x: np.ndarray, phi: np.ndarray, dsigma: np.ndarray, gap: np.ndarray, tau0: float,
             slope: float) -> np.ndarray:
    """δ at ``tau0`` of a surface density: the isothermal transfer of the learned model's templates.

    Parameters
    ----------
    x, phi : arrays
        The grid (``r / r_p``, azimuth [rad]).
    dsigma : (n_x, n_phi) array
        ``δΣ/Σ``.
    gap : (n_x,) array
        ``⟨Σ⟩_φ / Σ_init``.
    tau0 : float
        Initial dust optical depth at r_p.
    slope : float
        Surface-density slope ``p`` (Σ_init ∝ x^-p).

    Returns
    -------
    (n_x, n_phi) array
    """
    t = template_from_perturbation(x, phi, dsigma, float(tau0), sigma_axisym=gap * x**-float(slope),
                                   sigma_slope=float(slope), flaring=FLARING, store_brightness=False)
    return np.asarray(t.delta, dtype=float)


def prediction_uncertainty(model, y: np.ndarray, s: np.ndarray, h_p: float, slope: float, tau0: float,
                           n_samples: int, seed: int) -> PredictionUncertainty:
    """The uncertainty of a prediction from its outputs' means and standard deviations.

    Parameters
    ----------
    model : LearnedTemplateModel
        The model that predicted them.
    y, s : (n_outputs,) arrays
        The outputs' predictive means and standard deviations at the point.
    h_p, slope, tau0 : float
        The point's aspect ratio, Σ slope and the optical depth of δ.
    n_samples : int
        Independent draws of the outputs.
    seed : int
        Seed of the draws.

    Returns
    -------
    PredictionUncertainty
    """
    at = model._layout()
    depth = [] if at["ln_gap_depth"] is None else [s[at["ln_gap_depth"]]]
    patch = [] if at["ln_patch"] is None else [s[at["ln_patch"]]]
    x, phi = model.x, model.phi
    d0, gap0, _ = model._maps(y, h_p)
    delta0 = transfer(x, phi, d0, gap0, tau0, slope)
    rng = np.random.default_rng(seed)
    d_var = np.zeros_like(d0)
    delta_var = np.zeros_like(d0)
    for draw in y + s * rng.standard_normal((n_samples, y.size)):
        d, gap, _ = model._maps(draw, h_p)
        d_var += (d - d0) ** 2
        delta_var += (transfer(x, phi, d, gap, tau0, slope) - delta0) ** 2
    trunc = model.residual_variance * math.exp(2 * y[-1]) / model.weight**2  # what the global basis leaves out
    tau = tau0 * gap0 * x**-float(slope)
    factor = tau * np.exp(-tau) / -np.expm1(-tau)  # d ln I / d ln Σ of the isothermal slab
    d_var = d_var / n_samples + trunc[:, None]
    delta_var = delta_var / n_samples + (trunc * factor**2)[:, None]
    w2 = (x * -np.expm1(-tau0 / x)) ** 2  # x² I_axi², I_axi ∝ x^-1/2 (1 − e^{−τ0/x})
    w2 = w2 * ((x >= DISC_EXTENT[0]) & (x <= DISC_EXTENT[1]))
    norm2 = float(np.sum(w2[:, None] * delta0**2))
    rel = math.sqrt(float(np.sum(w2[:, None] * delta_var)) / norm2) if norm2 > 0 else float("inf")
    return PredictionUncertainty(dsigma_std=np.sqrt(d_var), delta_std=np.sqrt(delta_var),
                                 coefficient_std=s[at["map"]], gap_coefficient_std=np.r_[s[at["gap"]], depth],
                                 patch_coefficient_std=np.r_[s[at["patch"]], patch],
                                 log_amplitude_std=float(s[-1]), relative_error=rel)
