"""Priors of the spiral posterior's continuous parameters.

``r_p`` is uniform on ``[r_min, r_max]`` (default: the disc's extent, ``R_eff / 25`` to ``R_eff``,
never beyond the profile's ``Rmax``), ``phi_p`` uniform on the circle, and ``inc``, ``PA``,
``dRA``, ``dDec`` Gaussian, centred on the frank geometry with user-set widths (defaults 5 deg,
5 deg, 0.05 arcsec, 0.05 arcsec).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..units import ARCSEC, TWO_PI
from .likelihood import PARAMETER_NAMES

__all__ = ["DEFAULT_WIDTHS", "N_DIM", "Priors"]

N_DIM = len(PARAMETER_NAMES)
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

    ``phi_p`` is uniform on the circle (no parameters).
    """

    r_p: tuple
    inc: tuple
    PA: tuple
    dRA: tuple
    dDec: tuple

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

    @classmethod
    def default(cls, axisymmetric, *, geometry: DiscGeometry | None = None, r_p=None, widths: dict | None = None,
                ) -> "Priors":
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
            :data:`DEFAULT_WIDTHS`.
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
                   (geometry.dRA, widths["dRA"]), (geometry.dDec, widths["dDec"]))

    @classmethod
    def from_dict(cls, d: dict) -> "Priors":
        unknown = set(d) - {"r_p", "inc", "PA", "dRA", "dDec"}
        if unknown:
            raise InputError(f"unknown prior keys {sorted(unknown)}: use r_p, inc, PA, dRA, dDec")
        return cls(**{k: tuple(v) for k, v in d.items()})

    def to_dict(self) -> dict:
        return {k: list(v) for k, v in asdict(self).items()}

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

    def draw(self, n: int, rng) -> np.ndarray:
        """``n`` samples from the prior, shape (n, 6)."""
        out = np.empty((n, N_DIM))
        out[:, 0] = rng.uniform(*self.r_p, n)
        out[:, 1] = rng.uniform(0, TWO_PI, n)
        for j, (mu, sigma) in enumerate((self.inc, self.PA, self.dRA, self.dDec), start=2):
            out[:, j] = rng.normal(mu, sigma, n)
        out[:, 2] = np.clip(out[:, 2], 0.0, 89.9)
        return out
