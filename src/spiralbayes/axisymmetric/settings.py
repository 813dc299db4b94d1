"""How frank is fitted: :class:`FrankSettings`, the ``[frank]`` section of the configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ..exceptions import InputError
from ..settings import documented, is_integer, option
from .model import DEFAULT_HYPERPARAMETERS, _check_hyperparameters

__all__ = ["FRANK_METHODS", "FrankSettings", "GEOMETRY_FITTERS"]

GEOMETRY_FITTERS = ("gaussian", "nonparametric")
"""frank's geometry fitters: a Gaussian fitted in uv space, or a Fourier–Bessel profile (N = 20)."""
FRANK_METHODS = ("Normal", "LogNormal")
"""frank's brightness models."""
CONVERGENCE_FAILURES = ("raise", "warn", "ignore")


@documented
@dataclass(frozen=True)
class FrankSettings:
    """Options of :func:`~spiralbayes.axisymmetric.fit_axisymmetric` (TOML section ``[frank]``, which adds
    the pipeline's ``model``: a saved fit to use instead).

    The defaults are the paper's hyperparameters (:data:`~spiralbayes.axisymmetric.model.DEFAULT_HYPERPARAMETERS`).
    Every field's description is its ``metadata["doc"]``; ``help()``, the API pages and
    ``--print-config`` show them. ``None`` means automatic (written ``0`` in the TOML file).
    """

    N: int | None = option(None, "number of radial collocation points; 0: the paper's "
                                 f"{DEFAULT_HYPERPARAMETERS['N']}, or for fewer than {DEFAULT_HYPERPARAMETERS['N']} "
                                 "visibilities the count their longest baseline needs (x1.25)", toml=0)
    Rmax: float = option(DEFAULT_HYPERPARAMETERS["Rmax"], "outer radius of the fit [arcsec]")
    alpha: float = option(DEFAULT_HYPERPARAMETERS["alpha"], "order parameter of the power-spectrum prior")
    p0: float = option(DEFAULT_HYPERPARAMETERS["p0"], "scale parameter of the power-spectrum prior [Jy^2]")
    weights_smooth: float = option(DEFAULT_HYPERPARAMETERS["weights_smooth"], "strength of the power-spectrum "
                                                                              "smoothing")
    nonnegative: bool = option(False, "use frank's non-negative profile")
    # code only: the configuration sets the geometry fit with [geometry] fit
    fit_geometry: str | None = option(None, "'gaussian' or 'nonparametric': fit (inc, PA, dRA, dDec) first "
                                            "(default: 'gaussian' when no geometry is given, else none)",
                                      config=False)
    method: str = option("Normal", "frank's brightness model, 'Normal' or 'LogNormal'", config=False)
    max_iter: int = option(2000, "largest number of power-spectrum iterations", config=False)
    tol: float = option(1e-3, "frank stops when no power-spectrum coefficient changes by more than this fraction",
                        config=False)
    convergence_failure: str = option("raise", "'raise', 'warn' or 'ignore' when frank has not converged after "
                                               "max_iter iterations", config=False)
    blas_threads: int | None = option(1, "BLAS threads during the fit (None: leave them alone)", config=False)

    def __post_init__(self):
        if self.N is not None and (not is_integer(self.N) or self.N < 2):
            raise InputError(f"N = {self.N!r} must be None (0 in a configuration file: automatic) or an integer >= 2 "
                             f"(the paper uses {DEFAULT_HYPERPARAMETERS['N']})")
        _check_hyperparameters(DEFAULT_HYPERPARAMETERS["N"] if self.N is None else self.N, self.Rmax, self.alpha,
                               self.p0, self.weights_smooth)
        if self.method not in FRANK_METHODS:
            raise InputError(f"method = {self.method!r}: frank's brightness models are 'Normal' and 'LogNormal'")
        if self.convergence_failure not in CONVERGENCE_FAILURES:
            raise InputError(f"convergence_failure = {self.convergence_failure!r} must be 'raise', 'warn' or 'ignore'")
        if isinstance(self.tol, bool) or not (isinstance(self.tol, (int, float)) and 0 < self.tol < 1):
            raise InputError(f"tol = {self.tol!r}: frank's convergence tolerance must be a fraction in (0, 1), "
                             "e.g. 1e-3")
        if not is_integer(self.max_iter) or self.max_iter < 1:
            raise InputError(f"max_iter = {self.max_iter!r} must be a positive number of iterations")
        if self.fit_geometry is not None and self.fit_geometry not in GEOMETRY_FITTERS:
            raise InputError(f"fit_geometry = {self.fit_geometry!r} must be one of {GEOMETRY_FITTERS} or None")
