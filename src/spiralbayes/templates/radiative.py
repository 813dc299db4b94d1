"""S22-style radiative transfer: surface density and temperature → residual brightness δ.

Following Speedie, Booth & Dong (2022, ApJ 930, 40; "S22") as used by Stevenson et al. (2024):

* optical depth ``τ = τ0 Σ_d / Σ_d,0(r_p)`` (τ0 is the *initial* optical depth at the planet);
* emergent intensity of a vertically isothermal slab ``I = B_ν(T) (1 − e^{−τ})`` with the full
  Planck function (Rayleigh–Jeans is not valid at ~20 K in ALMA bands: ``d ln B/d ln T`` is 1.47
  at 345 GHz and 20 K, not 1);
* ``δ = I / <I>_φ − 1``.

The dust opacity cancels once τ0 is fixed. The midplane temperature follows the disc's flaring
profile, ``T = μ m_H c_s² / k_B`` with ``c_s = h Ω r`` (19.7 K at 50 au for ``M_* = 0.8 M_sun``,
``h = 0.07``, ``μ = 2.34``).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..settings import DEFAULT_MSTAR_MSUN
from ..units import AU, C_LIGHT, G_NEWTON, H_PLANCK, K_BOLTZMANN, M_HYDROGEN, M_SUN
from .template import SpiralTemplate, check_tau0, template_name

__all__ = [
    "planck_nu",
    "dlnB_dlnT",
    "midplane_temperature",
    "brightness",
    "residual",
    "template_from_perturbation",
]


def planck_nu(T, wavelength: float) -> np.ndarray:
    """Planck function ``B_ν(T)`` [W m⁻² Hz⁻¹ sr⁻¹] at ``wavelength`` [m]; 0 where ``T <= 0``."""
    T = np.asarray(T, dtype=float)
    nu = C_LIGHT / wavelength
    out = np.zeros_like(T)
    pos = T > 0
    out[pos] = 2.0 * H_PLANCK * nu**3 / C_LIGHT**2 / np.expm1(H_PLANCK * nu / (K_BOLTZMANN * T[pos]))
    return out


def dlnB_dlnT(T, wavelength: float):
    """Logarithmic slope ``d ln B_ν / d ln T = a e^a/(e^a − 1)``, ``a = hν/kT`` (1 in Rayleigh–Jeans)."""
    a = H_PLANCK * C_LIGHT / (wavelength * K_BOLTZMANN * np.asarray(T, dtype=float))
    return a / -np.expm1(-a)


def midplane_temperature(
    x, *, r_p_au: float = 50.0, mstar: float = DEFAULT_MSTAR_MSUN, h_p: float = 0.07, flaring: float = 0.25,
    mu: float = 2.34,
):
    """Passive-disc midplane temperature [K] at ``x = r/r_p``.

    ``T = μ m_H c_s²/k_B`` with ``c_s = (H/r) v_K``, ``H/r = h_p x**flaring``, so
    ``T ∝ x**(2 flaring − 1)`` (S22's ``H/r ∝ r^{1/4}`` gives ``T ∝ r^{-1/2}``).

    Parameters
    ----------
    x : array
        ``r / r_p``.
    r_p_au : float
        Planet radius [au] that sets the absolute temperature scale (S22: 50 au).
    mstar : float
        Stellar mass [M_sun] (Stevenson et al. 2024: 0.8).
    h_p, flaring : float
        ``H/r`` at ``r_p`` and flaring index.
    mu : float
        Mean molecular weight.
    """
    x = np.asarray(x, dtype=float)
    vk2 = G_NEWTON * mstar * M_SUN / (r_p_au * AU)
    T_p = mu * M_HYDROGEN * h_p**2 * vk2 / K_BOLTZMANN
    return T_p * x ** (2.0 * flaring - 1.0)


def brightness(tau, T, wavelength: float) -> np.ndarray:
    """Emergent intensity ``I = B_ν(T) (1 − e^{−τ})`` [W m⁻² Hz⁻¹ sr⁻¹]."""
    tau = np.clip(np.asarray(tau, dtype=float), 0.0, None)
    return planck_nu(T, wavelength) * -np.expm1(-tau)


def residual(intensity, axis: int = -1) -> np.ndarray:
    """``δ = I / <I>_φ − 1`` with the mean taken along ``axis`` (the azimuth); 0 where ``<I> = 0``."""
    intensity = np.asarray(intensity, dtype=float)
    mean = intensity.mean(axis=axis, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(mean > 0, intensity / mean - 1.0, 0.0)
    return d


def template_from_perturbation(
    x,
    phi,
    dsigma,
    tau0: float,
    *,
    temperature_factor=None,
    sigma_axisym=None,
    hand: str = "R",
    mass: float = float("nan"),
    beta: float = float("nan"),
    h_p: float = 0.07,
    flaring: float = 0.25,
    sigma_slope: float = 1.0,
    wavelength: float = 0.87e-3,
    mstar: float = DEFAULT_MSTAR_MSUN,
    r_p_au: float = 50.0,
    mu: float = 2.34,
    name: str | None = None,
    provenance: dict | None = None,
    store_brightness: bool = True,
) -> SpiralTemplate:
    """S22-style radiative transfer of a surface-density map into a :class:`SpiralTemplate`.

    Parameters
    ----------
    x, phi : 1-D arrays
        ``r/r_p`` (increasing) and azimuths ``2πk/n`` [rad], planet at φ = 0.
    dsigma : (n_x, n_phi) array
        ``Σ_d/Σ_d,axisym − 1`` (dust follows gas for Stokes number ≲ 0.1).
    tau0 : float
        Initial optical depth at ``r_p``: ``τ = τ0 Σ_d/Σ_d,0(r_p)``.
    temperature_factor : (n_x, n_phi) array, optional
        ``T/T_0(r)`` (1 if omitted: isothermal).
    sigma_axisym : (n_x,) array, optional
        Axisymmetric ``Σ_d/Σ_d,0(r_p)`` (default ``x^{-p}``, no gap).
    hand : {'R', 'L'}
        Hand of the input map; the template keeps it.
    wavelength, mstar, r_p_au, mu, h_p, flaring : float
        Observing wavelength [m] and the disc parameters of the temperature
        (:func:`~spiralbayes.templates.radiative.midplane_temperature`).

    Returns
    -------
    SpiralTemplate
        ``δ = I/<I>_φ − 1`` with ``I = B_ν(T)(1 − e^{−τ})`` (float32 δ).
    """
    check_tau0(tau0)
    x = np.asarray(x, dtype=float)
    phi = np.asarray(phi, dtype=float)
    dsigma = np.asarray(dsigma, dtype=float)
    if dsigma.shape != (x.size, phi.size):
        raise InputError(f"dsigma has shape {dsigma.shape}, expected ({x.size}, {phi.size})")
    sig_ax = x**-sigma_slope if sigma_axisym is None else np.asarray(sigma_axisym, dtype=float)
    ratio = np.clip(1.0 + dsigma, 1e-3, None)
    tau = tau0 * sig_ax[:, None] * ratio
    T = midplane_temperature(x, r_p_au=r_p_au, mstar=mstar, h_p=h_p, flaring=flaring, mu=mu)[:, None]
    if temperature_factor is not None:
        T = T * np.asarray(temperature_factor, dtype=float)
    intensity = brightness(tau, T, wavelength)
    delta = residual(intensity, axis=1).astype(np.float32)
    bright = None
    if store_brightness:
        i_p = np.argmin(np.abs(np.log(x)))
        ref = intensity[i_p].mean()
        bright = intensity / ref if ref > 0 else intensity
    return SpiralTemplate(
        x=x, phi=phi, delta=delta, mass=mass, tau0=tau0, beta=beta, h_p=h_p, flaring=flaring,
        wavelength=wavelength, hand=hand, name=name or template_name(mass, tau0, beta, hand),
        provenance=provenance or {}, brightness=bright,
    )
