"""Axisymmetric brightness model: a frank fit and everything computed from it.

The axisymmetric disc ``I_A(r)`` of Stevenson et al. (2024, sec. 2.1) is fitted to the
visibilities with frank (Jennings et al. 2020), a Gaussian-process Fourier–Bessel fit of the
deprojected visibilities. The paper's hyperparameters are the defaults here: ``N = 200``
collocation points, ``Rmax = 1.2 arcsec``, ``alpha = 1.05``, ``p0 = 1e-15 Jy^2`` and
``weights_smooth = 0.1`` (frank's JSON parameter file calls them ``n``, ``rout``, ``alpha``,
``p0``, ``wsmooth``; this module uses frank's Python names).

Conventions
-----------
* ``r`` in arcsec, brightness ``I`` in Jy/sr, baselines in wavelengths, angles in degrees.
* frank's brightness is a Fourier–Bessel series: ``I`` holds its values at the ``N``
  collocation radii ``r_k = Rmax j_{0,k} / j_{0,N+1}``. Between them the brightness is
  frank's band-limited interpolant (:meth:`AxisymmetricModel.brightness`); it is zero at and
  beyond ``Rmax``. Its visibilities at any baseline are the exact discrete Hankel transform
  (frank's ``DiscreteHankelTransform``).
* Optically thick, geometrically thin disc (frank's default and the paper's choice): an
  inclined disc has sky brightness ``I(r_disc)``, so its flux, and every visibility, is the
  face-on value times ``cos i``.
* Sky images follow :mod:`spiralbayes.fourier`: the disc is drawn with its major axis to the
  north and centred on the image; ``PA`` and the offset ``(dRA, dDec)`` are applied in the uv
  plane when the image is sampled, as frank and galario do.
"""

from .fit import fit_axisymmetric
from .model import DEFAULT_HYPERPARAMETERS, AxisymmetricModel
from .settings import FRANK_METHODS, GEOMETRY_FITTERS, FrankSettings

__all__ = ["AxisymmetricModel", "DEFAULT_HYPERPARAMETERS", "FRANK_METHODS", "FrankSettings", "GEOMETRY_FITTERS",
           "fit_axisymmetric"]
