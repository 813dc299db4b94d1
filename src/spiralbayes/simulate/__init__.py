"""Synthetic ALMA observations: uv coverage, thermal noise and model discs.

Three independent pieces, joined by :func:`simulate_observation`:

1. **uv coverage** (:func:`uv_coverage`) — Earth-rotation synthesis of the ALMA 12-m array from
   the packaged antenna configurations (``data/alma-configurations``, see its README for the
   provenance). Antenna positions ``(x east, y north, z up)`` [m] in the local tangent plane at
   latitude ``phi = -23.0234 deg`` are turned into equatorial baseline components
   ``X = -y sin(phi) + z cos(phi)``, ``Y = x``, ``Z = y cos(phi) + z sin(phi)`` and projected for
   hour angle ``H`` and declination ``delta`` (Thompson, Moran & Swenson 2017, *Interferometry and
   Synthesis in Radio Astronomy*, 3rd ed., eqs. 4.1 and 4.15)::

       u =  sin H X + cos H Y
       v = -sin delta cos H X + sin delta sin H Y + cos delta Z
       w =  cos delta cos H X - cos delta sin H Y + sin delta Z

   divided by the wavelength. Hour angles advance at the sidereal rate (1.0027379 sidereal s
   per s) and each integration is sampled at its mid-point (no time smearing). Integrations with
   the source below ``min_elevation`` are dropped. **Shadowing of one antenna by another is
   ignored**, as are flagging, bandwidth smearing and the primary beam
   (the discs are ~1.6" across, the 12-m primary beam ~18" FWHM at 0.87 mm). Residual
   antenna-based gain errors are optional (``gains=GainErrors(...)``, :mod:`.gains`).

2. **Thermal noise** (:func:`observe`) — independent Gaussian noise of standard deviation
   ``sigma`` on each of Re V and Im V, weights ``1 / sigma^2``. With natural weighting and the
   conjugate baselines implied, the dirty image (:func:`spiralbayes.fourier.dirty_image`) of pure
   noise has, at every pixel, the variance ``1 / sum(w)``: each term ``Re(eps_k e^{-i theta})`` has
   variance ``sigma^2``. So an image sensitivity ``sigma_img`` [Jy/beam] from ``N`` equal-weight
   visibilities needs ``sigma = sigma_img sqrt(N)`` (not ``sqrt(2N)``: the conjugates carry
   no independent noise); this is measured in the tests. Alternatively ``sigma`` follows from the
   radiometer equation (:class:`Radiometer`).

3. **Model discs** (:class:`DiscModel`) — the disc of Stevenson et al. (2024, sec. 3): surface
   density ``Sigma ~ r^-p`` and temperature ``T ~ r^-q`` between an inner and an outer edge (10
   and 110 au at 140 pc), brightness ``I = B_nu(T) (1 - exp(-tau))``, optionally multiplied by
   ``1 + delta(r, phi)`` for a perturbation (a spiral template). The disc is inclined in the
   optically thick limit (the sky brightness at a point is the face-on brightness at its
   deprojected position, so the flux scales as ``cos i``), rotated by ``PA`` and shifted by
   ``(dRA, dDec)``. The axisymmetric part is transformed exactly (a Hankel transform by
   Gauss-Legendre quadrature between the edges); the perturbation ``I delta`` is rendered on a
   fine grid in the frame of :func:`spiralbayes.fourier.sample_image` and sampled by NUFFT.

Rendering (:func:`render_disc_image`): spiral shocks and disc edges are sharp, so the default
pixel is 4 mas and each pixel is the mean of ``supersample x supersample`` (default 3 x 3)
point samples. Sampling the averaged image at pixel centres multiplies the transform by the
sub-sample kernel ``D_K(u) = sin(pi u d) / (K sin(pi u d / K))`` per axis (``d`` the pixel, ``K`` the
supersampling; ~1 % at 4 Mlambda for 4 mas); :func:`image_visibilities` divides it out
(``pixel_window_correction``), which leaves the transform of the fine ``d / K`` grid up to
aliasing far beyond the longest baseline. Measured (``benchmarks/bench_simulate.py``, fiducial
coverage): a smooth Gaussian disc matches its closed form to 1e-13 of the peak (3e-5 without the
correction); the whole power-law disc with its sharp edges matches the exact Hankel transform
to 1.6e-4 relative RMS (5.8e-5 at 2 mas); the perturbation part of a built-in spiral template
(M_p = M_th, tau0 = 0.3, isothermal, r_p = 0.4") matches a 1-mas 5 x 5 reference to 3e-3 relative
RMS and 1e-5 in ``sum |Delta V|^2``, whereas 16-mas pixels without supersampling err by 38 %
and 3 %.

A second backend, ``simulate_observation(..., backend="casa")`` (:mod:`spiralbayes.simulate.casa`,
optional ``casa`` extra), observes the same sky with CASA's simobserve; that module lists what
each backend assumes and how far they agree.

Units: u, v [lambda]; angles on the sky [arcsec]; inc, PA, declination [deg]; hour angles [h];
times [s]; wavelength [m]; brightness [Jy/sr]; images [Jy/pixel]; distances [pc]; disc radii in
:class:`DiscModel` [au].
"""

from .asymmetric import ExactAxisymmetric, eccentric_ring, lopsided_disc, vortex_arc
from .coverage import (
    ALMA_LATITUDE,
    UVCoverage,
    available_configurations,
    baseline_uvw,
    elevation,
    load_configuration,
    uv_coverage,
)
from .discs import (
    DiscModel,
    disc_visibilities,
    hankel_visibilities,
    image_visibilities,
    planck,
    render_disc_image,
)
from .gains import GainErrors, antenna_gain_series
from .noise import (
    Radiometer,
    fit_beam,
    image_noise,
    measure_image_noise,
    observe,
    sigma_for_sensitivity,
)
from .presets import (
    PRESETS,
    Preset,
    get_preset,
    preset_coverage,
    preset_table,
    simulate_observation,
)

__all__ = [
    "ALMA_LATITUDE",
    "DiscModel",
    "ExactAxisymmetric",
    "GainErrors",
    "PRESETS",
    "Preset",
    "Radiometer",
    "UVCoverage",
    "antenna_gain_series",
    "available_configurations",
    "baseline_uvw",
    "disc_visibilities",
    "eccentric_ring",
    "elevation",
    "fit_beam",
    "get_preset",
    "hankel_visibilities",
    "image_visibilities",
    "image_noise",
    "load_configuration",
    "lopsided_disc",
    "measure_image_noise",
    "observe",
    "planck",
    "preset_coverage",
    "preset_table",
    "render_disc_image",
    "sigma_for_sensitivity",
    "simulate_observation",
    "uv_coverage",
    "vortex_arc",
]
