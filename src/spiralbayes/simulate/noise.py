"""Thermal noise of synthetic observations, and the beam and noise of the images they give."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..exceptions import InputError
from ..fourier import dirty_image, psf
from ..units import ARCSEC, JY, K_BOLTZMANN
from ..visibilities import Visibilities
from .coverage import UVCoverage
from .gains import GainErrors

__all__ = ["Radiometer", "fit_beam", "image_noise", "measure_image_noise", "observe", "sigma_for_sensitivity"]

@dataclass(frozen=True)
class Radiometer:
    """Thermal noise of one visibility from the radiometer equation.

    ``sigma = sqrt(2) k T_sys / (eta A sqrt(n_pol bandwidth t_int))`` per Re and Im of the
    Stokes I visibility, ``A = pi D^2 / 4``, ``eta = aperture x quantisation x correlator``
    efficiency (Thompson, Moran & Swenson ch. 6; the ALMA Technical Handbook's image noise
    ``2 k T_sys / (eta A sqrt(N_ant (N_ant - 1) n_pol bandwidth t))`` follows with
    ``sigma_img = sigma / sqrt(N)``).

    Defaults are rough, typical ALMA values: T_sys 150 K (Band 7, 0.87 mm, ~0.9 mm PWV at high
    elevation; use ~90 K for Band 6), 7.5 GHz continuum bandwidth, two polarisations,
    12-m dishes, aperture efficiency 0.68, quantisation 0.96, correlator 0.88.
    """

    T_sys: float = 150.0
    bandwidth: float = 7.5e9
    n_pol: int = 2
    dish_diameter: float = 12.0
    aperture_efficiency: float = 0.68
    quantisation_efficiency: float = 0.96
    correlator_efficiency: float = 0.88

    def sigma(self, integration_time: float) -> float:
        """Noise [Jy] of each of Re V and Im V for one integration [s]."""
        area = np.pi * self.dish_diameter**2 / 4.0
        eta = self.aperture_efficiency * self.quantisation_efficiency * self.correlator_efficiency
        sefd_term = np.sqrt(2.0) * K_BOLTZMANN * self.T_sys / (eta * area)
        return float(sefd_term / np.sqrt(self.n_pol * self.bandwidth * integration_time) / JY)


def sigma_for_sensitivity(sensitivity: float, n_vis: int) -> float:
    """Per-visibility noise [Jy] (each of Re, Im) giving the natural-weighted image noise
    ``sensitivity`` [Jy/beam] from ``n_vis`` equal-weight visibilities: ``sensitivity sqrt(n_vis)``.
    """
    if not sensitivity > 0:
        raise InputError(f"sensitivity must be a positive image noise [Jy/beam], got {sensitivity}")
    return float(sensitivity) * np.sqrt(n_vis)


def image_noise(weights) -> float:
    """Natural-weighted image noise [Jy/beam] implied by weights: ``1 / sqrt(sum w)``."""
    return float(1.0 / np.sqrt(np.sum(weights)))


def observe(model, coverage: UVCoverage, sensitivity: float | None = None, *,
            sigma: float | None = None, radiometer: Radiometer | None = None,
            add_noise: bool = True, seed=0, provenance: dict | None = None,
            gains: GainErrors | None = None) -> Visibilities:
    """Model visibilities at the coverage's baselines plus thermal noise.

    Parameters
    ----------
    model : callable, array or None
        ``model(u, v) -> V`` [Jy], or the model visibilities themselves (length ``coverage.n``),
        or None for a noise-only observation.
    coverage : UVCoverage
    sensitivity : float
        Requested natural-weighted image noise [Jy/beam]. Exactly one of ``sensitivity``,
        ``sigma`` (per-visibility noise of Re and Im [Jy]) and ``radiometer`` is needed.
    add_noise : bool
        False gives the noise-free model with the weights of the noisy one.
    seed : int or numpy Generator
        Seed of ``np.random.default_rng``: the same seed gives the same noise.
    gains : GainErrors, optional
        Antenna-based gain errors: the model visibilities become ``g_p conj(g_q) V`` before
        the noise is added (the noise and its seed are unchanged). Needs a coverage that knows
        its antennas (:func:`.uv_coverage` does).

    Returns
    -------
    Visibilities
        With ``weights = 1 / sigma^2``, the wavelength set, the antennas and times of every row
        (when the coverage knows them) and the provenance recording the coverage, the noise,
        the gain errors and the seed.
    """
    given = [x is not None for x in (sensitivity, sigma, radiometer)]
    if sum(given) != 1:
        raise InputError("give exactly one of sensitivity [Jy/beam], sigma [Jy] and radiometer")
    n = coverage.n
    if sensitivity is not None:
        sig = sigma_for_sensitivity(sensitivity, n)
        noise_note: dict[str, Any] = {"sensitivity_jy_beam": float(sensitivity)}
    elif sigma is not None:
        if not sigma > 0:
            raise InputError(f"sigma must be positive [Jy], got {sigma}")
        sig = float(sigma)
        noise_note = {}
    else:
        assert radiometer is not None  # exactly one of the three is given (checked above)
        sig = radiometer.sigma(coverage.integration_time)
        noise_note = {"radiometer": asdict(radiometer)}
    noise_note.update(sigma_vis_jy=sig, image_noise_jy_beam=sig / np.sqrt(n))

    if model is None:
        V = np.zeros(n, dtype=complex)
    elif callable(model):
        V = np.asarray(model(coverage.u, coverage.v), dtype=complex)
    else:
        V = np.asarray(model, dtype=complex)
    if V.shape != (n,):
        raise InputError(f"model visibilities have shape {V.shape}, the coverage has {n} baselines")
    rows = {} if coverage.antenna1 is None else {
        "antenna1": coverage.antenna1, "antenna2": coverage.antenna2, "time": coverage.times()}
    if gains is not None:
        if not rows:
            raise InputError("gains= needs a uv coverage that records its antennas (from uv_coverage); "
                             "this one has none: drop gains= or rebuild the coverage")
        V = gains.corrupt(V, rows["antenna1"], rows["antenna2"], rows["time"])
    if add_noise:
        rng = np.random.default_rng(seed)
        V = V + sig * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    prov = {
        "source": "spiralbayes.simulate",
        "coverage": coverage.describe(),
        "noise": {**noise_note, "added": bool(add_noise)},
        "seed": seed if isinstance(seed, (int, np.integer, type(None))) else repr(seed),
        **({} if gains is None else {"gain_errors": gains.to_dict()}),
        **(provenance or {}),
    }
    return Visibilities(coverage.u, coverage.v, V, np.full(n, sig**-2), wavelength=coverage.wavelength,
                        provenance=prov, layout=coverage.layout(), antenna1=rows.get("antenna1"),
                        antenna2=rows.get("antenna2"), time=rows.get("time"))


def fit_beam(u, v, weights=None, *, pixel_size: float | None = None, n: int = 128):
    """Fit an elliptical Gaussian to the main lobe of the naturally weighted PSF.

    Uses the pixels of the central lobe above half maximum (as CASA's restoring-beam fit does
    for its main lobe). Returns ``(bmaj, bmin, bpa)``: FWHM [arcsec] and position angle [deg,
    east of north].
    """
    from scipy import ndimage, optimize

    u, v = np.asarray(u, float), np.asarray(v, float)
    weights = np.ones(u.size) if weights is None else np.asarray(weights, float)
    if pixel_size is None:
        uv_max = float(np.max(np.hypot(u, v)))
        pixel_size = 1.0 / uv_max / ARCSEC / 12.0
    for _ in range(4):
        beam = psf(u, v, weights, (n, n), pixel_size)
        labels, _ = ndimage.label(beam > 0.5)
        lobe = labels == labels[n // 2, n // 2]
        iy, ix = np.nonzero(lobe)
        if iy.min() > 0 and ix.min() > 0 and iy.max() < n - 1 and ix.max() < n - 1 and lobe.sum() > 30:
            break
        pixel_size *= 2.0 if lobe.sum() > 30 else 0.5
    l = -(ix - n // 2) * pixel_size
    m = (iy - n // 2) * pixel_size
    data = beam[iy, ix]

    def gauss(params):
        sx, sy, th = params
        c, s = np.cos(th), np.sin(th)
        a = (l * s + m * c) / sx  # along PA (east of north)
        b = (l * c - m * s) / sy
        return np.exp(-0.5 * (a**2 + b**2)) - data

    s0 = np.sqrt(lobe.sum() / np.pi) * pixel_size / 1.1774
    res = optimize.least_squares(gauss, [s0, s0, 0.0])
    sx, sy, th = res.x
    f = 2 * np.sqrt(2 * np.log(2))
    bmaj, bmin = f * abs(sx), f * abs(sy)
    pa = np.degrees(th)
    if bmin > bmaj:
        bmaj, bmin, pa = bmin, bmaj, pa + 90.0
    return float(bmaj), float(bmin), float((pa + 90.0) % 180.0 - 90.0)


def measure_image_noise(vis: Visibilities, *, n: int = 256, pixel_size: float | None = None) -> float:
    """RMS [Jy/beam] of the natural-weighted dirty image of ``vis`` (use noise-only data)."""
    if pixel_size is None:
        pixel_size = 1.0 / float(np.max(vis.uv_distance)) / ARCSEC / 3.0
    return float(np.std(dirty_image(vis.u, vis.v, vis.V, vis.weights, (n, n), pixel_size)))
