"""χ² metrics, the Gaussian visibility likelihood and the BIC.

Notation of Stevenson et al. (2024, sec. 2.3): ``chi2_PQ = sum_k w_k |V_P,k - V_Q,k|^2`` with
the observed weights ``w_k = 1/sigma_k^2`` [Jy^-2] (sigma the noise of each of Re and Im);
O observed, A axisymmetric, S spiral. ``delta_chi2 = chi2_AO - chi2_SO`` is positive when the
spiral model fits better. With ``k`` extra parameters and ``N`` visibility points,
``delta_BIC = delta_chi2 - k ln N``; the paper uses k = 6, so ``delta_chi2 (delta_BIC = 0) = 6 ln N``,
and ``delta_BIC > 10`` counts as very strong evidence (Kass & Raftery 1995).
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError

__all__ = [
    "N_SPIRAL_PARAMETERS",
    "bic_threshold",
    "chi2",
    "delta_bic",
    "delta_chi2_from_terms",
    "fitted_amplitude",
    "gaussian_log_likelihood",
]

N_SPIRAL_PARAMETERS = 6
"""Extra parameters of the spiral model in the paper's BIC (r_p, phi_p and the template's four)."""


def chi2(V_model, V_obs, weights) -> float:
    """``sum w |V_model - V_obs|^2`` (dimensionless)."""
    diff = np.asarray(V_model) - np.asarray(V_obs)
    return float(np.sum(np.asarray(weights) * (diff.real ** 2 + diff.imag ** 2)))


def gaussian_log_likelihood(V_model, V_obs, weights, normalised: bool = True) -> float:
    """Log-likelihood of complex visibilities with independent Gaussian noise on Re and Im.

    ``ln L = -chi2 / 2 + sum ln(w / 2 pi)`` (the second term, constant in the model, is
    left out when ``normalised`` is False).
    """
    value = -0.5 * chi2(V_model, V_obs, weights)
    if normalised:
        value += float(np.sum(np.log(np.asarray(weights) / (2 * np.pi))))
    return value


def bic_threshold(n_data: int, n_params: int = N_SPIRAL_PARAMETERS) -> float:
    """``k ln N``: the Δχ² at which ΔBIC = 0 (the paper's 6 ln N)."""
    if n_data < 1:
        raise InputError(f"n_data must be a positive number of visibility points, got {n_data}")
    return n_params * float(np.log(n_data))


def delta_bic(delta_chi2, n_data: int, n_params: int = N_SPIRAL_PARAMETERS):
    """``BIC_A - BIC_S = delta_chi2 - k ln N`` (positive favours the spiral)."""
    return np.asarray(delta_chi2) - bic_threshold(n_data, n_params)


def fitted_amplitude(cross, power, amplitude=None):
    """The spiral amplitude ``A`` a Δχ² uses: 1 (None, the paper's), the number given, or with
    ``"free"`` the best non-negative ``max(cross / power, 0)`` (0 where ``power`` is 0)."""
    if amplitude is None:
        return np.ones(np.shape(cross)) if np.ndim(cross) else 1.0
    if isinstance(amplitude, str):
        if amplitude != "free":
            raise InputError(f"amplitude must be a number or 'free', got {amplitude!r}")
        cross = np.asarray(cross, dtype=float)
        power = np.asarray(power, dtype=float)
        return np.where(power > 0, np.maximum(cross, 0) / np.where(power > 0, power, 1), 0.0)
    return amplitude


def delta_chi2_from_terms(cross, power, amplitude=None):
    """Δχ² of adding ``A ΔV`` to a model, from ``cross = Re sum w R* ΔV`` and ``power = sum w |ΔV|^2``.

    ``R = V_O - V_A`` is the residual of the model without the perturbation. With a fixed
    amplitude ``A`` (default 1, the paper's choice) Δχ² = 2 A cross - A² power. With
    ``amplitude="free"`` the best non-negative amplitude ``A = max(cross / power, 0)`` is used,
    giving ``cross^2 / power`` where ``cross > 0`` and 0 elsewhere (:func:`fitted_amplitude`).
    """
    cross = np.asarray(cross, dtype=float)
    power = np.asarray(power, dtype=float)
    if amplitude is None:
        return 2 * cross - power
    a = fitted_amplitude(cross, power, amplitude)
    return 2 * a * cross - a ** 2 * power
