"""The :class:`LearnedTemplateModel`: spiral templates at any point of disc physics inside its training box.

The model returns a template at any planet mass ``M_p``, aspect ratio ``h_p = H/r`` at the planet,
surface-density slope ``p`` (Σ ∝ r^-p), viscosity ``α`` at the planet and age (orbits) inside the
box its training runs span (:mod:`.training`), from a low-rank description of the runs'
surface-density maps (:mod:`.basis`, with the near-planet patch of :mod:`.patch`) whose
coefficients are Gaussian processes of the physics (:mod:`.regression`).

The predicted ``δΣ/Σ`` and gap go through the package's isothermal transfer
(:func:`~spiralbayes.templates.radiative.template_from_perturbation`, ``τ = τ0 Σ/Σ_0(r_p)``,
``Σ_axi = gap · x^-p``), as the reduced runs' ``delta_tau*`` maps were made, so one model serves
every optical depth τ0. Predictions outside the training box raise
:class:`~spiralbayes.exceptions.InputError` unless ``extrapolate=True``; the predictive
uncertainty is :meth:`LearnedTemplateModel.predict_uncertainty`
(:class:`~.uncertainty.PredictionUncertainty`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..._provenance import provenance_record
from ...exceptions import InputError
from ...results import ResultMixin
from ..family import shift_rows
from ..radiative import template_from_perturbation
from ..template import SpiralTemplate, check_tau0, validate_hand
from ..wake import wake_shape
from .basis import fit_bases
from .patch import from_patch
from .regression import (MIN_LENGTH_SCALE, TRENDS, fit_hyperparameters, fit_trends, gaussian_process, output_groups,
                         trend_at)
from .scaling import AZIMUTH_SCALING, check_power, expand, scale_factor
from .training import FLARING, MAX_CHANGE, PARAMETERS, TrainingRun, parameter_vector, read_training_runs
from .uncertainty import PredictionUncertainty, prediction_uncertainty

__all__ = ["LEARNED_KIND", "MODEL_VERSION", "LearnedTemplateModel"]

log = logging.getLogger(__name__)

LEARNED_KIND = "spiralbayes.LearnedTemplateModel"
"""The ``kind`` root attribute of a saved model (:mod:`spiralbayes.results`)."""

MODEL_VERSION = 4
"""Version of the fit: it changes when a fit of the same runs with the same options gives another model
(cached measurements, e.g. ``tools/learned_model_loro.py``'s, key on it)."""


@dataclass(eq=False, repr=False)
class LearnedTemplateModel(ResultMixin):
    """Spiral templates continuous in (M_p, H/r, Σ slope, α, age), learned from hydrodynamic runs.

    Make one with :meth:`from_references` (reduced FARGO3D files) or :meth:`fit` (runs already read),
    keep it with ``save`` / ``load`` (:class:`~spiralbayes.results.ResultMixin`: one HDF5 file; the
    Gaussian processes are rebuilt on load from the inputs, targets and fitted hyperparameters, with
    no refit); :meth:`predict` gives a :class:`~spiralbayes.templates.template.SpiralTemplate`.
    The representation, basis and regression are in the docstrings of :mod:`spiralbayes.templates.learned`.

    Attributes
    ----------
    x : (n_x,) array
        ``r / r_p`` of the model's rows (the rows every training run holds); templates are zero
        outside ``[x[0], x[-1]]``.
    phi : (n_phi,) array
        Azimuths [rad] (planet at 0).
    weight : (n_x,) array
        :func:`~spiralbayes.templates.learned.training.row_weight` at ``x``.
    mean : (n_x, n_phi) array
        Mean of the aligned, weighted, normalised training maps.
    components : (n_components, n_x, n_phi) array
        Their principal components (orthonormal over all cells).
    gap_mean : (n_x,) array
        Mean ``ln(⟨Σ⟩_φ / Σ_init)`` of the training runs (of its shape, with ``gap_depth``).
    gap_components : (n_gap_components, n_x) array
        Its principal components.
    inputs : (n_runs, 5) array
        The training runs' :data:`~spiralbayes.templates.learned.training.PARAMETERS`.
    targets : (n_runs, n_outputs) array
        Their outputs: the map's coefficients, the gap's shape coefficients, the patch's
        coefficients, then ``ln D`` (with ``gap_depth``), ``ln P`` (with ``patch``) and ``ln A``.
    thetas : (n_outputs, n_theta) array
        The fitted kernels' log hyperparameters (scikit-learn's ``kernel_.theta``), one row per output.
    residual_variance : (n_x,) array
        Mean over the runs and azimuths of what the global basis leaves out of the normalised maps,
        per row.
    trends : (n_outputs, 6) array
        Each output's linear trend in the scaled inputs (intercept first); the processes model
        what it leaves (zero without ``trend``).
    patch_mean : (n_patch, n_patch) array
        Mean of the normalised near-planet patches (``patch``; empty without), on the grid
        ``ξ = (x − 1)/h_p``, ``η = φ/h_p`` of :func:`~spiralbayes.templates.learned.patch.patch_grid`.
    patch_components : (n_patch_components, n_patch, n_patch) array
        Their principal components.
    run_names : tuple of str
        The training runs.
    options : dict
        :meth:`fit`'s options (``n_components``, ``n_gap_components``, ``n_patch_components``, ``align``,
        ``restarts``, ``sharing``, ``trend``, ``gap_depth``, ``patch``).
    provenance : dict
        Versions, time, the training runs and the options.
    parameters : tuple of str
        The regression's inputs (:data:`~spiralbayes.templates.learned.training.PARAMETERS`; a file
        of other inputs is refused).
    """

    x: np.ndarray
    phi: np.ndarray
    weight: np.ndarray
    mean: np.ndarray
    components: np.ndarray
    gap_mean: np.ndarray
    gap_components: np.ndarray
    inputs: np.ndarray
    targets: np.ndarray
    thetas: np.ndarray
    residual_variance: np.ndarray
    trends: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    patch_mean: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    patch_components: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    run_names: tuple = ()
    options: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    parameters: tuple = PARAMETERS

    KIND = LEARNED_KIND
    WHAT = "learned template model"

    def __post_init__(self):
        if tuple(self.parameters) != PARAMETERS:
            raise InputError(f"inputs {list(self.parameters)} differ from {list(PARAMETERS)}: refit the model "
                             "(LearnedTemplateModel.from_references) and save it again")
        self.parameters = PARAMETERS
        self.run_names = tuple(self.run_names)
        if self.trends.size == 0:
            self.trends = np.zeros((self.targets.shape[1], self.inputs.shape[1] + 1))
        self._gps = None
        self._ridges: dict = {}

    # ---------------------------------------------------------------------------- building
    @classmethod
    def from_references(cls, paths: Iterable, *, exclude: Sequence[str] = (), max_change: float = MAX_CHANGE,
                        **options) -> LearnedTemplateModel:
        """Fit the model to the isothermal gas runs of reduced reference files.

        Parameters
        ----------
        paths : iterable of path
            Reduced FARGO3D files (:func:`~spiralbayes.templates.learned.training.read_training_runs`),
            e.g. ``tests/data/references/continuum/fargo3d_continuum.h5``.
        exclude : sequence of str
            Run names (``<source>:<group>``) to leave out (a held-out run).
        max_change : float
            Steadiness threshold of :func:`~spiralbayes.templates.learned.training.read_training_runs`.
        **options
            :meth:`fit`'s options.

        Returns
        -------
        LearnedTemplateModel
        """
        paths = list(paths)
        runs = [r for r in read_training_runs(paths, max_change=max_change) if r.name not in set(exclude)]
        model = cls.fit(runs, **options)
        model.provenance["files"] = [str(p) for p in paths]
        return model

    @classmethod
    def fit(cls, runs: Sequence[TrainingRun], *, n_components: int = 10, n_gap_components: int = 5,
            n_patch_components: int = 6, align: bool = True, restarts: int = 2, sharing: str = "grouped",
            trend: str = "disc", gap_depth: bool = True, patch: bool = False,
            min_length_scale: float = MIN_LENGTH_SCALE,
            azimuth_scaling: float = AZIMUTH_SCALING) -> LearnedTemplateModel:
        """Fit the bases (:func:`~spiralbayes.templates.learned.basis.fit_bases`) and the Gaussian
        processes (:mod:`spiralbayes.templates.learned.regression`) to ``runs``.

        Parameters
        ----------
        runs : sequence of TrainingRun
            At least 4 runs on one grid (the reduced files share ``x`` and ``phi``).
        n_components : int
            Principal components of the normalised, aligned δΣ/Σ maps.
        n_gap_components : int
            Principal components of the gaps ``ln(⟨Σ⟩_φ/Σ_init)``.
        n_patch_components : int
            Principal components of the near-planet patches (``patch``).
        align : bool
            Rotate each row onto the linear wake's ridge before the basis is fitted (the default;
            False only to measure what the alignment is worth).
        restarts : int
            Extra random starts of each process's hyperparameter optimisation.
        sharing : {'grouped', 'independent'}
            ``grouped``: one kernel (length scales, signal and noise level relative to each output's
            spread) for all map coefficients, one for the gap's, one for the patch's, one for each
            amplitude — fitted to the group's summed marginal likelihood, so that a component whose
            coefficients look like noise on their own borrows the length scales of the others;
            ``independent``: a kernel per output.
        trend : {'disc', 'map', 'amplitudes', 'all', 'none'}
            Which outputs are first regressed linearly on the scaled inputs (least squares), the
            processes modelling what the line leaves: ``disc`` (the default) the amplitudes ``ln A``,
            ``ln D`` and ``ln P`` on every input and the map's coefficients on the disc's inputs but
            not its age, ``map`` those on age too, ``amplitudes`` the amplitudes alone, ``all`` every
            output, ``none`` none. Towards the box's edges a trend keeps a prediction from falling
            back to the training mean. True and False mean ``all`` and ``none``; docs/templates.md
            gives the options' leave-one-run-out recoveries.
        gap_depth : bool
            Model the gap as ``ln(⟨Σ⟩_φ/Σ_init) = D g(x)``: its depth ``D`` (RMS of the log over the
            model's radii) regressed in ``ln D`` — with a trend, a power law in mass and age, as the
            gap deepens — and the shape ``g`` on a basis of its own, whose coefficients of gaps
            shallower than :data:`~spiralbayes.templates.learned.basis.GAP_DEPTH_FLOOR` are shrunk
            towards the mean shape (their shapes are noise and do not matter for δ). False: a basis
            of ``ln(⟨Σ⟩_φ/Σ_init)`` itself.
        patch : bool
            Model the planet's surroundings apart, in coordinates scaled by the scale height
            (:mod:`spiralbayes.templates.learned.patch`), normalised by its RMS (``ln P`` regressed)
            and given a basis of its own; the global maps are ``(1 − W) δΣ/Σ``. The near-planet peak
            and the wake's start scale with ``H_p``, not with ``r_p``, so in these coordinates the
            runs' patches look alike at every aspect ratio. Off by default: left out, the
            leave-one-run-out recoveries keep their medians and their worst runs do better
            (docs/templates.md).
        min_length_scale : float
            Lower bound of the processes' length scales, in units of the training box's side
            (:data:`~spiralbayes.templates.learned.regression.MIN_LENGTH_SCALE`).
        azimuth_scaling : float
            Power ``q`` in [0, 3]: aligned rows seen at azimuth offsets divided by ``(h_p/h_min)^q``
            (:mod:`spiralbayes.templates.learned.scaling`; default
            :data:`~spiralbayes.templates.learned.scaling.AZIMUTH_SCALING`); 0 is off; needs ``align``.

        Returns
        -------
        LearnedTemplateModel
        """
        runs = list(runs)
        if len(runs) < 4:
            raise InputError(f"a learned template model needs at least 4 training runs, got {len(runs)}")
        if sharing not in ("grouped", "independent"):
            raise InputError(f"sharing = {sharing!r}: use 'grouped' or 'independent'")
        if not (np.isfinite(min_length_scale) and 0 < min_length_scale < 100):
            raise InputError(f"min_length_scale = {min_length_scale!r}: use a length in (0, 100) box sides")
        if trend not in TRENDS:
            raise InputError(f"trend = {trend!r}: use one of {sorted(k for k in TRENDS if isinstance(k, str))}")
        azimuth_scaling = check_power(azimuth_scaling, align)
        b = fit_bases(runs, n_components=n_components, n_gap_components=n_gap_components,
                      n_patch_components=n_patch_components, align=align, gap_depth=gap_depth, patch=patch,
                      azimuth_scaling=azimuth_scaling)
        sizes = (b.components.shape[0], b.gap_components.shape[0], b.patch_components.shape[0])
        inputs = np.array([r.inputs for r in runs])
        model = cls(x=b.x, phi=runs[0].phi.copy(), weight=b.weight, mean=b.mean, components=b.components,
                    gap_mean=b.gap_mean, gap_components=b.gap_components, inputs=inputs, targets=b.targets,
                    thetas=np.zeros((b.targets.shape[1], 0)), residual_variance=b.residual_variance,
                    patch_mean=b.patch_mean, patch_components=b.patch_components,
                    run_names=tuple(r.name for r in runs),
                    options={"n_components": sizes[0], "n_gap_components": sizes[1], "n_patch_components": sizes[2],
                             "align": bool(align), "restarts": int(restarts), "sharing": str(sharing),
                             "trend": TRENDS[trend], "gap_depth": bool(gap_depth), "patch": bool(patch),
                             "min_length_scale": float(min_length_scale)})
        if azimuth_scaling:  # absent when off, as in models saved before the option existed
            model.options["azimuth_scaling"] = azimuth_scaling
        z = model._scaled(inputs)
        model.trends = fit_trends(z, b.targets, TRENDS[trend], sizes[0], sum(sizes))
        resid = b.targets - np.column_stack([np.ones(len(z)), z]) @ model.trends.T
        model.thetas = fit_hyperparameters(z, resid, output_groups(sizes, b.targets.shape[1], sharing), restarts,
                                           min_length_scale)
        model.provenance = provenance_record(
            generator="spiralbayes.templates.learned.LearnedTemplateModel.fit", model_version=MODEL_VERSION,
            runs=list(model.run_names), options=model.options)
        log.info("learned template model: %d runs, %d + %d components, box %s", len(runs), sizes[0], sizes[1],
                 {p: [round(float(lo), 4), round(float(hi), 4)] for p, lo, hi in zip(PARAMETERS, *model.box)})
        return model

    # ---------------------------------------------------------------------------- the box
    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)``: the training runs' range of each of
        :data:`~spiralbayes.templates.learned.training.PARAMETERS`."""
        return self.inputs.min(axis=0), self.inputs.max(axis=0)

    @property
    def bounds(self) -> dict:
        """The trained box in the units of :meth:`predict`: ``{name: (low, high)}`` for ``mass`` [M_th],
        ``h_p``, ``slope``, ``alpha`` and ``orbits``."""
        lo, hi = self.box
        conv = (math.exp, float, float, lambda v: 10.0**v, math.exp)
        names = ("mass", "h_p", "slope", "alpha", "orbits")
        return {n: (f(float(a)), f(float(b))) for n, f, a, b in zip(names, conv, lo, hi)}

    def _scaled(self, inputs: np.ndarray) -> np.ndarray:
        lo, hi = self.box
        span = np.where(hi > lo, hi - lo, 1.0)
        return (np.atleast_2d(inputs) - lo) / span

    def _check(self, mass, h_p, slope, alpha, orbits, extrapolate: bool) -> np.ndarray:
        values = {"mass": mass, "h_p": h_p, "slope": slope, "alpha": alpha, "orbits": orbits}
        for name, v in values.items():
            if not np.isfinite(v) or (name != "slope" and v <= 0):
                raise InputError(f"{name} = {v!r} must be {'finite' if name == 'slope' else 'positive and finite'}")
        u = parameter_vector(mass, h_p, slope, alpha, orbits)
        if not extrapolate:
            lo, hi = self.box
            out = [n for n, v, a, b in zip(values, u, lo, hi) if v < a - 1e-9 or v > b + 1e-9]
            if out:
                bounds = self.bounds
                detail = "; ".join(f"{n} = {values[n]:g} outside [{bounds[n][0]:g}, {bounds[n][1]:g}]" for n in out)
                raise InputError(f"{detail}: outside the box the learned model was trained on "
                                 f"({len(self.run_names)} runs). Train it on runs that cover the point, or pass "
                                 "extrapolate=True to accept an extrapolation (its uncertainty grows; "
                                 "predict_uncertainty says by how much)")
        return u

    # ---------------------------------------------------------------------------- prediction
    def _processes(self):
        if self._gps is None:
            z = self._scaled(self.inputs)
            resid = self.targets - trend_at(z, self.trends)
            gps = []
            for j, theta in enumerate(self.thetas):
                gp = gaussian_process(z.shape[1], theta)
                gp.fit(z, resid[:, j])
                gps.append(gp)
            self._gps = gps
        return self._gps

    def _outputs(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and standard deviation of every output at the inputs ``u``."""
        z = self._scaled(u)
        mean, std = zip(*(gp.predict(z, return_std=True) for gp in self._processes()))
        return trend_at(z, self.trends)[0] + np.array([m[0] for m in mean]), np.array([s[0] for s in std])

    def _ridge(self, h_p: float) -> np.ndarray:
        key = round(float(h_p), 12)
        if key not in self._ridges:
            self._ridges[key] = wake_shape(self.x, float(h_p), FLARING)
        return self._ridges[key]

    def _layout(self) -> dict:
        """Where each output sits in the output vector: slices ``map``, ``gap``, ``patch``; indices
        ``ln_gap_depth``, ``ln_patch`` (None without ``gap_depth`` / ``patch``) and ``ln_amplitude``."""
        k, kg, kp = self.components.shape[0], self.gap_components.shape[0], self.patch_components.shape[0]
        i = k + kg + kp
        out = {"map": slice(0, k), "gap": slice(k, k + kg), "patch": slice(k + kg, i), "ln_gap_depth": None,
               "ln_patch": None}
        if self.options.get("gap_depth", False):
            out["ln_gap_depth"], i = i, i + 1
        if self.options.get("patch", False):
            out["ln_patch"], i = i, i + 1
        out["ln_amplitude"] = i
        return out

    def _maps(self, y: np.ndarray, h_p: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(δΣ/Σ, gap ⟨Σ⟩/Σ_init, normalised weighted aligned map)`` of the outputs ``y``."""
        at = self._layout()
        shape = self.mean + np.tensordot(y[at["map"]], self.components, axes=1)
        d = shape * math.exp(y[at["ln_amplitude"]])
        q = self.options.get("azimuth_scaling", 0.0)
        if q:
            d = expand(d, self.phi, scale_factor(h_p, self.bounds["h_p"][0], q))
        d = d / self.weight[:, None]
        if self.options.get("align", True):
            d = shift_rows(d, self._ridge(h_p))
        if at["ln_patch"] is not None:
            local = math.exp(y[at["ln_patch"]]) * (self.patch_mean + np.tensordot(y[at["patch"]],
                                                                                  self.patch_components, axes=1))
            d = d + from_patch(local, self.x, self.phi, h_p)
        d -= d.mean(axis=1, keepdims=True)
        g = self.gap_mean + y[at["gap"]] @ self.gap_components
        if at["ln_gap_depth"] is not None:
            g = math.exp(y[at["ln_gap_depth"]]) * g
        return d, np.exp(g), shape

    def predict_dsigma(self, mass: float, h_p: float, slope: float, alpha: float, orbits: float, *,
                       extrapolate: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The predicted surface density at one point (hand R).

        Parameters
        ----------
        mass, h_p, slope, alpha, orbits, extrapolate
            As :meth:`predict`.

        Returns
        -------
        dsigma : (n_x, n_phi) array
            ``δΣ/Σ = Σ/⟨Σ⟩_φ − 1`` on ``(x, phi)``.
        gap : (n_x,) array
            ``⟨Σ⟩_φ / Σ_init`` (the gap; Σ_init ∝ x^-slope).
        """
        u = self._check(mass, h_p, slope, alpha, orbits, extrapolate)
        d, gap, _ = self._maps(self._outputs(u)[0], h_p)
        return d, gap

    def predict(self, mass: float, h_p: float, slope: float, alpha: float, orbits: float, tau0: float,
                hand: str = "R", *, extrapolate: bool = False) -> SpiralTemplate:
        """The template at one point of disc physics.

        Parameters
        ----------
        mass : float
            Planet mass ``M_p/M_th`` (``M_th = h_p³ M_*``).
        h_p : float
            Aspect ratio ``H/r`` at r_p (the runs flare as ``H/r ∝ r^0.25``).
        slope : float
            Surface-density slope ``p``: the disc's initial ``Σ ∝ r^-p``.
        alpha : float
            Viscosity parameter α at r_p (``ν = α h_p² r_p² Ω_p``).
        orbits : float
            Age of the planet [orbits].
        tau0 : float
            Initial dust optical depth at r_p (``τ = τ0 Σ/Σ_0(r_p)``).
        hand : {'R', 'L'}
            Handedness (L: the mirror image).
        extrapolate : bool
            Allow a point outside the training box (:attr:`bounds`); otherwise that raises
            :class:`~spiralbayes.exceptions.InputError` naming the parameter and the box.

        Returns
        -------
        SpiralTemplate
            ``δ = I/⟨I⟩_φ − 1`` on ``(x, phi)``, β = 0 (isothermal), named
            ``learned_m<M>_tau<τ0>_b0_h<h>_p<p>_a<α>_o<orbits>_<hand>``; ``provenance["learned"]``
            holds the point, whether it lies in the training box, and the expected relative error of the
            weighted δΣ/Σ map (``dsigma_relative_error``; :meth:`predict_uncertainty` gives δ's at τ0),
            ``provenance["variant"]`` the physics point, so that
            templates of one disc at several masses form one mass family.
        """
        check_tau0(tau0)
        hand = validate_hand(hand)
        u = self._check(mass, h_p, slope, alpha, orbits, extrapolate)
        y, s = self._outputs(u)
        d, gap, shape = self._maps(y, h_p)
        rel = self._relative_error(shape, s)
        point = {"mass": float(mass), "h_p": float(h_p), "slope": float(slope), "alpha": float(alpha),
                 "orbits": float(orbits)}
        lo, hi = self.box
        inside = bool(np.all((u >= lo - 1e-9) & (u <= hi + 1e-9)))
        physics = f"p{slope:g}_a{alpha:.2g}_o{orbits:g}"
        prov = {"learned": {"model": "spiralbayes.templates.learned.LearnedTemplateModel", "point": point,
                            "inside_box": inside, "dsigma_relative_error": rel, "n_runs": len(self.run_names),
                            "options": dict(self.options), "created": self.provenance.get("created")},
                "variant": f"learned_{physics}"}
        name = f"learned_m{mass:g}_tau{tau0:g}_b0_h{h_p:g}_{physics}_R"
        t = template_from_perturbation(self.x, self.phi, d, float(tau0), sigma_axisym=gap * self.x**-float(slope),
                                       hand="R", mass=float(mass), beta=0.0, h_p=float(h_p), flaring=FLARING,
                                       sigma_slope=float(slope), name=name, provenance=prov,
                                       store_brightness=False)
        return t if hand == "R" else t.mirror()

    def _relative_error(self, shape: np.ndarray, std: np.ndarray) -> float:
        k = self.components.shape[0]
        norm2 = float(np.sum(shape**2))
        err2 = float(np.sum(std[:k] ** 2) + np.sum(self.residual_variance) * self.phi.size)
        return float(math.sqrt(err2 / norm2 + std[-1] ** 2)) if norm2 > 0 else float("inf")

    def predict_uncertainty(self, mass: float, h_p: float, slope: float, alpha: float, orbits: float,
                            tau0: float = 0.3, *, extrapolate: bool = False, n_samples: int = 64,
                            seed: int = 0) -> PredictionUncertainty:
        """The predictive uncertainty of :meth:`predict` at one point (arguments as there).

        The outputs (basis coefficients, gap coefficients, amplitudes) are drawn ``n_samples`` times
        from their processes' predictive distributions (independently: correlations between the
        outputs' errors are ignored), each draw is put through the same transfer as the template,
        and the spread of the draws around the prediction, plus what the basis leaves out of the
        training maps (per row), is the uncertainty.

        Parameters
        ----------
        mass, h_p, slope, alpha, orbits, tau0, extrapolate
            As :meth:`predict`.
        n_samples : int
            Draws of the outputs.
        seed : int
            Seed of the draws (the result is deterministic for a given seed).

        Returns
        -------
        PredictionUncertainty
            ``relative_error`` is taken with the visibilities' weighting of δ at ``tau0``: disc area
            times the squared brightness of the fiducial disc, ``x² I_axi(x)²`` over log radius.
        """
        check_tau0(tau0)
        if int(n_samples) < 2:
            raise InputError(f"n_samples = {n_samples!r}: need at least 2 draws")
        u = self._check(mass, h_p, slope, alpha, orbits, extrapolate)
        y, s = self._outputs(u)
        return prediction_uncertainty(self, y, s, h_p, slope, float(tau0), int(n_samples), seed)

    def summary(self) -> str:
        """The training set, the bases and the box, in one line."""
        b = self.bounds
        return (f"learned template model from {len(self.run_names)} runs, {self.components.shape[0]} map + "
                f"{self.gap_components.shape[0]} gap + {self.patch_components.shape[0]} patch components; box "
                f"M_p {b['mass'][0]:g}-{b['mass'][1]:g} M_th, H/r {b['h_p'][0]:g}-{b['h_p'][1]:g}, "
                f"p {b['slope'][0]:g}-{b['slope'][1]:g}, alpha {b['alpha'][0]:.2g}-{b['alpha'][1]:.2g}, "
                f"{b['orbits'][0]:g}-{b['orbits'][1]:g} orbits")

    def __repr__(self) -> str:
        return f"LearnedTemplateModel({self.summary()})"
