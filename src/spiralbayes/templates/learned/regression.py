"""The learned model's regression: Gaussian processes over a linear trend, from physics to coefficients.

Every output of the bases (:mod:`.basis`: coefficients and amplitudes) is a Gaussian process
(scikit-learn's ``GaussianProcessRegressor``: constant × anisotropic RBF + white noise,
hyperparameters by maximum marginal likelihood, one kernel per group of outputs) of the inputs
``(ln M_p, h_p, p, log10 α, ln orbits)`` (:data:`~.training.PARAMETERS`), each scaled to the
training box, over a linear trend in those scaled inputs (:data:`TRENDS` says which outputs have
one). The processes' predictive standard deviations are the model's uncertainty.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["MIN_LENGTH_SCALE", "TRENDS", "fit_hyperparameters", "fit_trends", "gaussian_process", "kernel",
           "output_groups", "trend_at"]

TRENDS = {"disc": "disc", "map": "map", "amplitudes": "amplitudes", "all": "all", "none": "none", True: "all",
          False: "none"}
"""The ``trend`` options of :meth:`~spiralbayes.templates.learned.model.LearnedTemplateModel.fit` (and the
booleans they stand for)."""


MIN_LENGTH_SCALE = 0.1
"""Lower bound of the RBF length scales, in units of the training box's side. The design's distinct
values lie 0.05-0.125 of the box apart (H/r rounded to 0.01, p to 0.05, α to 0.1 dex), so the data
cannot tell a shorter length scale from noise; left free to 0.01, the marginal likelihood sometimes
settles there for the map's coefficients in H/r, and runs between the training values' rows then
fall back to the trend (docs/templates.md, "What each part is worth")."""


def kernel(n_inputs: int, min_length_scale: float = MIN_LENGTH_SCALE):
    """Constant × anisotropic RBF + white noise, on inputs scaled to the unit box.

    Parameters
    ----------
    n_inputs : int
        Dimensions of the inputs (one RBF length scale each).
    min_length_scale : float
        Lower bound of the length scales [box sides] (:data:`MIN_LENGTH_SCALE`).

    Returns
    -------
    sklearn.gaussian_process.kernels.Kernel
    """
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    return (ConstantKernel(1.0, (1e-3, 1e3)) * RBF(np.ones(n_inputs), (float(min_length_scale), 1e2))
            + WhiteKernel(1e-2, (1e-6, 1.0)))


def gaussian_process(n_inputs: int, theta=None, restarts: int = 0, min_length_scale: float = MIN_LENGTH_SCALE):
    """A Gaussian-process regressor of :func:`kernel`: to be fitted, or with fixed hyperparameters.

    Parameters
    ----------
    n_inputs : int
        Dimensions of the inputs.
    theta : array, optional
        The kernel's log hyperparameters (``kernel_.theta`` of a fitted regressor); given, the
        regressor keeps them (no optimisation).
    restarts : int
        Extra random starts of the hyperparameter optimisation (without ``theta``).
    min_length_scale : float
        Lower bound of the fitted length scales [box sides].

    Returns
    -------
    sklearn.gaussian_process.GaussianProcessRegressor
        With ``normalize_y``.
    """
    from sklearn.gaussian_process import GaussianProcessRegressor

    k = kernel(n_inputs, min_length_scale)
    if theta is None:
        return GaussianProcessRegressor(k, normalize_y=True, n_restarts_optimizer=restarts, random_state=0)
    return GaussianProcessRegressor(k.clone_with_theta(np.asarray(theta, float)), normalize_y=True, optimizer=None)


def trend_at(z: np.ndarray, trends: np.ndarray) -> np.ndarray:
    """The outputs' linear trends at the scaled inputs ``z``, held at the box's faces outside it: an
    extrapolation follows the processes (which revert to the trend there, their uncertainty growing),
    not a line through the few runs near an edge.

    Parameters
    ----------
    z : (n, n_inputs) array
        Inputs scaled to the training box (0 to 1 inside).
    trends : (n_outputs, n_inputs + 1) array
        Intercept and slopes of each output.

    Returns
    -------
    (n, n_outputs) array
    """
    return np.column_stack([np.ones(len(z)), np.clip(z, 0.0, 1.0)]) @ trends.T


def fit_trends(z: np.ndarray, targets: np.ndarray, trend: str, n_map: int, n_coefficients: int) -> np.ndarray:
    """Least-squares linear trends of the outputs in the scaled inputs.

    Parameters
    ----------
    z : (n_runs, n_inputs) array
        The training runs' scaled inputs (age last).
    targets : (n_runs, n_outputs) array
        Their outputs (``Bases.targets`` of :func:`~.basis.fit_bases`).
    trend : str
        A value of :data:`TRENDS`: ``disc`` the amplitudes on every input and the map's coefficients on
        the disc's inputs but not its age, ``map`` both on every input, ``amplitudes`` the amplitudes
        alone, ``all`` every output, ``none`` none.
    n_map : int
        The map's coefficients (the first outputs).
    n_coefficients : int
        All basis coefficients (map, gap and patch); the outputs after them are the amplitudes.

    Returns
    -------
    (n_outputs, n_inputs + 1) array
        Intercept and slopes per output (zero for the outputs without a trend).
    """
    design = np.column_stack([np.ones(len(z)), z])
    trends = np.zeros((targets.shape[1], design.shape[1]))
    n_out = targets.shape[1]
    amplitudes = np.arange(n_coefficients, n_out)  # ln D, ln P, ln A
    with_trend = {"all": np.arange(n_out), "map": np.r_[np.arange(n_map), amplitudes], "amplitudes": amplitudes,
                  "disc": amplitudes, "none": np.array([], int)}[trend]
    if with_trend.size:
        trends[with_trend] = np.linalg.lstsq(design, targets[:, with_trend], rcond=None)[0].T
    if trend == "disc":  # the map's coefficients on the disc's inputs, not on its age
        static = design[:, :-1]
        trends[:n_map, :-1] = np.linalg.lstsq(static, targets[:, :n_map], rcond=None)[0].T
    return trends


def output_groups(sizes: tuple[int, int, int], n_outputs: int, sharing: str) -> list[np.ndarray]:
    """The groups of outputs that share one kernel.

    Parameters
    ----------
    sizes : (int, int, int)
        Coefficients of the map, the gap and the patch (the first outputs, in that order).
    n_outputs : int
        All outputs (the amplitudes follow the coefficients).
    sharing : {'grouped', 'independent'}
        ``grouped``: one group per basis and one per amplitude; ``independent``: one per output.

    Returns
    -------
    list of int arrays
        The non-empty groups' output indices.
    """
    k, kg, kp = sizes
    if sharing == "grouped":
        groups = [np.arange(k), np.arange(k, k + kg), np.arange(k + kg, k + kg + kp),
                  *(np.array([j]) for j in range(k + kg + kp, n_outputs))]
    else:
        groups = [np.array([j]) for j in range(n_outputs)]
    return [g for g in groups if g.size]


def fit_hyperparameters(z: np.ndarray, residuals: np.ndarray, groups: list[np.ndarray], restarts: int,
                        min_length_scale: float = MIN_LENGTH_SCALE) -> np.ndarray:
    """Each group's kernel fitted to its outputs' summed marginal likelihood.

    Parameters
    ----------
    z : (n_runs, n_inputs) array
        Scaled inputs.
    residuals : (n_runs, n_outputs) array
        The outputs less their trends.
    groups : list of int arrays
        :func:`output_groups`.
    restarts : int
        Extra random starts of each optimisation.
    min_length_scale : float
        Lower bound of the length scales [box sides].

    Returns
    -------
    (n_outputs, n_theta) array
        The fitted log hyperparameters, one row per output (a group's rows alike).
    """
    thetas = np.zeros((residuals.shape[1], kernel(z.shape[1]).n_dims))
    for g in groups:
        gp = gaussian_process(z.shape[1], restarts=restarts, min_length_scale=min_length_scale)
        with warnings.catch_warnings():  # hyperparameters at a bound are not an error
            warnings.simplefilter("ignore")
            gp.fit(z, residuals[:, g] if g.size > 1 else residuals[:, g[0]])
        thetas[g] = gp.kernel_.theta
    return thetas
