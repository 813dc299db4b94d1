"""Priors of the spiral posterior's parameters.

``r_p`` is uniform on ``[r_min, r_max]`` (default: the disc's extent, ``R_eff / 25`` to ``R_eff``,
never beyond the profile's ``Rmax / 2.2``, so that the template's 2.2 r_p stays inside the
profile), ``phi_p`` uniform on the circle, ``inc``, ``PA``, ``dRA``, ``dDec`` Gaussian, centred on
the frank geometry with user-set widths (defaults 5 deg, 5 deg, 0.05 arcsec, 0.05 arcsec), and
the spiral amplitude ``A`` uniform on ``[0, amplitude_max]`` (default 2).

The amplitude prior: ``A`` multiplies the template's ``delta``; ``A = 1`` is the template as
simulated (the paper's fixed choice) and ``A = 0`` the disc without a planet, so the
no-planet hypothesis is this prior's edge. The templates' shapes follow from the wake physics,
their contrast less surely (cooling, opacity, dust coupling are fixed per template), hence a
range of a factor 2 around 1. The evidence for a planet pays ``ln(amplitude_max / A-width)``
for this freedom, so a wider range makes "no planet" easier to prefer; ``amplitude_max = None``
fixes ``A = 1``.

The geometry priors are those of the no-planet hypothesis too: both hypotheses marginalise
the same geometry, so their evidences compare like with like.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ...exceptions import InputError
from ...geometry import DiscGeometry
from ...units import ARCSEC, TWO_PI
from .conditional import PARAMETER_NAMES
from .likelihood import DEFAULT_AMPLITUDE_MAX

__all__ = ["DEFAULT_AMPLITUDE_MAX", "DEFAULT_WIDTHS", "GEOMETRY_NAMES", "N_DIM", "Priors"]

N_DIM = len(PARAMETER_NAMES)
GEOMETRY_NAMES = ("inc", "PA", "dRA", "dDec")
DEFAULT_WIDTHS = {"inc": 5.0, "PA": 5.0, "dRA": 0.05, "dDec": 0.05}


@dataclass(frozen=True)
class Priors:
    """Priors of the six continuous parameters.

    Parameters
    ----------
    r_p : (float, float)
        Uniform range of the planet radius [arcsec], ``0 < r_min < r_max``.
    inc, PA : (float, float)
        Gaussian (mean, sigma) [deg]; the inclination is also truncated to [0, 90).
    dRA, dDec : (float, float)
        Gaussian (mean, sigma) [arcsec].
    amplitude_max : float or None
        ``A`` uniform on ``[0, amplitude_max]``; ``None`` fixes ``A = 1``.

    ``phi_p`` is uniform on the circle (no parameters).
    """

    r_p: tuple
    inc: tuple
    PA: tuple
    dRA: tuple
    dDec: tuple
    amplitude_max: float | None = DEFAULT_AMPLITUDE_MAX

    def __post_init__(self):
        lo, hi = (float(x) for x in self.r_p)
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= 0 or hi <= lo:
            raise InputError(f"Priors.r_p = {self.r_p!r}: need 0 < r_min < r_max [arcsec] (planet radii "
                             "must be positive and the range non-empty)")
        object.__setattr__(self, "r_p", (lo, hi))
        for name in ("inc", "PA", "dRA", "dDec"):
            value = getattr(self, name)
            if np.ndim(value) != 1 or len(value) != 2:
                raise InputError(f"Priors.{name} = {value!r}: give (mean, sigma)")
            mean, sigma = float(value[0]), float(value[1])
            if not np.isfinite(mean) or not np.isfinite(sigma) or sigma <= 0:
                unit = "deg" if name in ("inc", "PA") else "arcsec"
                raise InputError(f"Priors.{name}: the width must be a positive number of {unit}, got {sigma!r} "
                                 "(negative or zero widths are not allowed)")
            object.__setattr__(self, name, (mean, sigma))
        if not 0 <= self.inc[0] < 90:
            raise InputError(f"Priors.inc mean = {self.inc[0]} deg is outside [0, 90)")
        if self.amplitude_max is not None:
            a = float(self.amplitude_max)
            if not (np.isfinite(a) and a > 0):
                raise InputError(f"Priors.amplitude_max = {self.amplitude_max!r}: the amplitude prior needs a "
                                 "positive upper bound (or None to fix A = 1)")
            object.__setattr__(self, "amplitude_max", a)

    @classmethod
    def default(cls, axisymmetric, *, geometry: DiscGeometry | None = None, r_p=None, widths: dict | None = None,
                amplitude_max: float | None = DEFAULT_AMPLITUDE_MAX) -> Priors:
        """Defaults: r_p over the disc's extent, geometry centred on the frank geometry.

        Parameters
        ----------
        axisymmetric : AxisymmetricModel
            Its ``R_eff()`` and ``Rmax`` set the r_p range; its ``geometry`` the centre.
        geometry : DiscGeometry, optional
            Centre of the geometry priors (default: the model's).
        r_p : (float, float), optional
            Override the r_p range [arcsec].
        widths : dict, optional
            Sigmas for ``inc``, ``PA`` [deg], ``dRA``, ``dDec`` [arcsec]; defaults
            ``DEFAULT_WIDTHS``.
        amplitude_max : float or None
            Upper end of the amplitude prior (None: ``A = 1`` fixed).
        """
        geometry = geometry or axisymmetric.geometry
        widths = {**DEFAULT_WIDTHS, **(widths or {})}
        unknown = set(widths) - set(DEFAULT_WIDTHS)
        if unknown:
            raise InputError(f"unknown prior widths {sorted(unknown)}: use {sorted(DEFAULT_WIDTHS)}")
        if r_p is None:
            r_eff = float(axisymmetric.R_eff())
            r_max = min(r_eff, float(getattr(axisymmetric, "Rmax", np.inf)) / 2.2)
            r_p = (r_eff / 25.0, r_max)
        return cls(tuple(r_p), (geometry.inc, widths["inc"]), (geometry.PA, widths["PA"]),
                   (geometry.dRA, widths["dRA"]), (geometry.dDec, widths["dDec"]), amplitude_max)

    @classmethod
    def from_dict(cls, d: dict) -> Priors:
        unknown = set(d) - {"r_p", "inc", "PA", "dRA", "dDec", "amplitude_max"}
        if unknown:
            raise InputError(f"unknown prior keys {sorted(unknown)}: use r_p, inc, PA, dRA, dDec, amplitude_max")
        values: dict[str, Any] = {k: (v if k == "amplitude_max" else tuple(v)) for k, v in d.items()}
        return cls(**values)

    def to_dict(self) -> dict:
        return {k: (v if k == "amplitude_max" else list(v)) for k, v in asdict(self).items()}

    def check_data(self, vis, axisymmetric) -> None:
        """Raise ``ValueError`` if the r_p range lies outside what the data and model can describe."""
        lo, hi = self.r_p
        r_out = getattr(axisymmetric, "Rmax", None)
        if r_out is not None and hi > float(r_out):
            raise InputError(f"Priors.r_p upper bound {hi} arcsec lies beyond the disc model's extent "
                             f"(Rmax = {float(r_out)} arcsec): the profile is zero there; lower it")
        if r_out is not None and lo >= float(r_out):
            raise InputError(f"Priors.r_p = {self.r_p} lies entirely outside the disc (Rmax = {float(r_out)} arcsec)")
        resolution = 1.0 / float(np.max(vis.uv_distance)) / ARCSEC
        if hi < 0.25 * resolution:
            raise InputError(f"Priors.r_p = {self.r_p} arcsec is far below the data's resolution "
                             f"(1 / u_max = {resolution:.3g} arcsec): the data cannot constrain it")

    @property
    def centre(self) -> np.ndarray:
        """The prior's centre: mid r_p, phi_p = 0, the geometry means."""
        return np.array([0.5 * sum(self.r_p), 0.0, self.inc[0], self.PA[0], self.dRA[0], self.dDec[0]])

    @property
    def widths(self) -> np.ndarray:
        """A scale per parameter (r_p range / sqrt 12, pi, sigmas)."""
        return np.array([(self.r_p[1] - self.r_p[0]) / np.sqrt(12.0), np.pi, self.inc[1], self.PA[1],
                         self.dRA[1], self.dDec[1]])

    def log_prior(self, theta) -> float:
        """Normalised log prior density (``-inf`` outside the support)."""
        r_p, _, inc, PA, dRA, dDec = theta
        lo, hi = self.r_p
        if not (lo <= r_p <= hi) or not (0.0 <= inc < 90.0):
            return -np.inf
        value = -np.log(hi - lo) - np.log(TWO_PI)
        for x, (mu, sigma) in ((inc, self.inc), (PA, self.PA), (dRA, self.dRA), (dDec, self.dDec)):
            value += -0.5 * ((x - mu) / sigma) ** 2 - np.log(sigma) - 0.5 * np.log(TWO_PI)
        return float(value)

    @property
    def geometry_centre(self) -> np.ndarray:
        return np.array([self.inc[0], self.PA[0], self.dRA[0], self.dDec[0]])

    @property
    def geometry_widths(self) -> np.ndarray:
        return np.array([self.inc[1], self.PA[1], self.dRA[1], self.dDec[1]])

    def log_prior_geometry(self, g) -> float:
        """Normalised log prior density of ``(inc, PA, dRA, dDec)`` alone (the no-planet hypothesis)."""
        g = np.asarray(g, dtype=float)
        if not 0.0 <= g[0] < 90.0:
            return -np.inf
        z = (g - self.geometry_centre) / self.geometry_widths
        return float(-0.5 * np.sum(z * z) - np.sum(np.log(self.geometry_widths)) - 2.0 * np.log(TWO_PI))

    def draw(self, n: int, rng) -> np.ndarray:
        """``n`` samples from the prior, shape (n, 6)."""
        out = np.empty((n, N_DIM))
        out[:, 0] = rng.uniform(*self.r_p, n)
        out[:, 1] = rng.uniform(0, TWO_PI, n)
        for j, (mu, sigma) in enumerate((self.inc, self.PA, self.dRA, self.dDec), start=2):
            out[:, j] = rng.normal(mu, sigma, n)
        out[:, 2] = np.clip(out[:, 2], 0.0, 89.9)
        return out
