"""Read what a configuration names: the data, the templates and the axisymmetric model."""

from __future__ import annotations

import logging
from collections.abc import Callable

from ..averaging import DEFAULT_MAX_SMEARING, average_visibilities
from ..axisymmetric import AxisymmetricModel, FrankSettings, fit_axisymmetric
from ..calibration.settings import CalibrationSettings
from ..axisymmetric.provenance import check_fitted_to
from ..config import geometry_given
from ..exceptions import ConfigError, InputError
from ..geometry import DiscGeometry
from ..inference.limits.families import template_families
from ..io import load_visibilities
from ..templates import TemplateBank, compromise_bank, default_bank
from ..templates.bank import DEFAULT_H_PS
from ..templates.template import template_metadata
from ..visibilities import estimate_weights

__all__ = ["learned_templates", "load_axisymmetric", "load_data", "load_maps", "load_templates", "select_templates"]

log = logging.getLogger(__name__)


def select_templates(bank, mass=(), tau0=(), beta=(), hand=(), h_p=()):
    """The templates of ``bank`` matching every non-empty criterion (lists of allowed values)."""
    chosen = bank.select(mass=list(mass) or None, tau0=list(tau0) or None, beta=list(beta) or None,
                         hand=list(hand) or None, h_p=list(h_p) or None)
    if not len(chosen):
        raise InputError(f"no template matches mass={list(mass)}, tau0={list(tau0)}, beta={list(beta)}, "
                         f"hand={list(hand)}, h_p={list(h_p)}; the bank ({len(bank)} templates) has "
                         f"{_bank_values(bank)}")
    return list(chosen)


def _bank_values(bank) -> str:
    """The values each template parameter takes in ``bank``, e.g. ``mass 0.3, 1, 3; hand L, R``."""
    parts = []
    for key in ("mass", "tau0", "beta", "hand", "h_p"):
        values = sorted({getattr(t, key) for t in bank if getattr(t, key, None) is not None}, key=str)
        values = [v for v in values if not (isinstance(v, float) and v != v)]
        parts.append(f"{key} {', '.join(f'{v:g}' if isinstance(v, float) else str(v) for v in values) or '-'}")
    return "; ".join(parts)


def load_data(data: dict, geometry: DiscGeometry | None = None, *, config: dict | None = None):
    """A :class:`~spiralbayes.visibilities.Visibilities` from the ``[data]`` section of a configuration.

    With ``estimate_weights = true`` the weights are rescaled by one factor from the scatter of
    each visibility about the plane through its uv neighbours (``method="neighbours"`` of
    :func:`~spiralbayes.visibilities.estimate_weights`: no model, geometry or symmetry assumed;
    uv cells, the ``"scatter"`` method without a geometry, were measured 40x off on the fiducial
    set-up, where the bright disc's structure dominates the scatter within a cell); otherwise they
    are checked on load and a DataWarning gives this fix when they do not look statistical.
    ``geometry`` is kept for callers that pass it; the estimate does not use it.

    With ``average = 'time'`` or ``'uv'`` the data are then averaged
    (:func:`~spiralbayes.averaging.average_visibilities`) within ``max_smearing`` of the model's L1
    norm inside ``config``'s ``[frank] Rmax`` (offset by its ``[geometry]`` centre); with
    ``[calibration] solve`` set, time averages stay within one solution interval.
    """
    if not data["path"]:
        raise InputError("data.path is empty: give the visibility file in the [data] section")
    kwargs = {}
    if data["uv_units"]:
        kwargs["uv_units"] = data["uv_units"]
    if data["wavelength"]:
        kwargs["wavelength"] = data["wavelength"]
    if data["conjugated"]:
        kwargs["conjugated"] = True
    vis = load_visibilities(data["path"], check_weights_on_load=not data["estimate_weights"], **kwargs).standardised()
    vis = estimate_weights(vis, method="neighbours") if data["estimate_weights"] else vis
    return average_data(vis, data, config)


def average_data(vis, data: dict, config: dict | None):
    """``vis`` averaged as ``[data] average`` asks (the same for every command and every survey disc)."""
    mode = data.get("average", "none")
    if mode == "none":
        return vis
    config = config or {}
    frank = config.get("frank", {})
    r_out = frank.get("Rmax") or FrankSettings().Rmax
    time_bin = data.get("time_bin") or None
    calibration = config.get("calibration", {})
    if mode == "time" and calibration.get("solve", "none") != "none":
        interval = calibration.get("interval_s") or CalibrationSettings().interval_s
        time_bin = interval if time_bin is None else min(time_bin, interval)
    try:
        geometry = _geometry(config) if "geometry" in config else None
        return average_visibilities(vis, mode, r_out=r_out, geometry=geometry,
                                    max_smearing=data.get("max_smearing", DEFAULT_MAX_SMEARING), time_bin=time_bin)
    except InputError as err:
        raise InputError(f"[data] average = {mode!r}: {err}") from None


BANKS: dict[str, Callable[..., TemplateBank]] = {"default": default_bank, "variants": default_bank,
                                                 "compromise": compromise_bank}
"""The built-in banks by their ``[templates] bank`` name (:data:`spiralbayes.config.BUILT_IN_BANKS`):
``default`` and ``variants`` are the morphology-robust bank, ``compromise`` the single-morphology one."""


def load_templates(templates: dict, *, progress: bool = False) -> list:
    """The templates chosen by the ``[templates]`` section of a configuration: a built-in bank by
    name (:data:`BANKS`; the default is robust to the spiral's morphology, docs/limits.md §4d) or
    a TemplateBank file, then the section's selection, then the ``maps`` files' templates
    (:func:`load_maps`); ``bank = "learned"``: :func:`learned_templates`. ``h_p`` values a built-in
    bank does not hold (it has :data:`~spiralbayes.templates.bank.DEFAULT_H_PS`) make that bank at
    those aspect ratios."""
    name = templates["bank"]
    h_ps = sorted({float(h) for h in templates.get("h_p", ())})
    if name == "learned":
        chosen = learned_templates(templates, progress=progress)
    elif name in BANKS and h_ps and not set(h_ps) <= set(DEFAULT_H_PS):
        # aspect ratios the cached bank lacks: the same built-in bank made at them (generator templates, cached)
        chosen = select_templates(BANKS[name](h_ps=tuple(h_ps)), templates["mass"], templates["tau0"],
                                  templates["beta"], templates["hand"])
    else:
        bank = BANKS[name]() if name in BANKS else TemplateBank.load(name)
        chosen = select_templates(bank, templates["mass"], templates["tau0"], templates["beta"], templates["hand"],
                                  h_ps)
    maps = load_maps(templates, {t.name for t in chosen})
    if maps:
        try:  # two maps for one mass of one family would stop the limits after the scan: say so now
            template_families([template_metadata(t) for t in chosen + maps])
        except InputError as err:
            raise InputError(f"[templates] maps: {err}") from None
    return chosen + maps


def learned_templates(templates: dict, *, progress: bool = False) -> list:
    """The templates of ``[templates] bank = "learned"``: the saved model ``learned_model`` predicts one at
    every combination of the section's ``mass``, ``h_p``, ``slope``, ``alpha``, ``orbits``, ``tau0`` and
    ``hand`` (:func:`~spiralbayes.templates.learned.learned_bank`, cached); an empty option takes the
    built-in banks' values (masses, H/r, τ0) or the learned bank's defaults (slope, α, age:
    :data:`~spiralbayes.templates.learned.bank.DEFAULT_SLOPES` ...). The model is isothermal, so ``beta``
    may only hold 0."""
    from ..templates.learned import DEFAULT_ALPHAS, DEFAULT_ORBITS, DEFAULT_SLOPES, learned_bank, model_from_file
    from ..templates.wake import PAPER_MASSES, PAPER_TAUS

    betas = [float(b) for b in templates.get("beta", ())]
    if betas and 0.0 not in betas:
        raise InputError(f"[templates] beta = {betas}: the learned model's templates are isothermal (beta 0); "
                         "add 0 or leave beta empty")
    model = model_from_file(templates["learned_model"])
    try:
        bank = learned_bank(model, templates.get("mass") or PAPER_MASSES, templates.get("h_p") or DEFAULT_H_PS,
                            templates.get("slope") or DEFAULT_SLOPES, templates.get("alpha") or DEFAULT_ALPHAS,
                            templates.get("orbits") or DEFAULT_ORBITS, templates.get("tau0") or PAPER_TAUS,
                            [h.upper() for h in templates.get("hand", ())] or ("R", "L"), progress=progress)
    except InputError as err:
        raise InputError(f"[templates] bank = 'learned' ({templates['learned_model']}): {err}") from None
    log.info("learned bank: %d templates from %s", len(bank), templates["learned_model"])
    for t in bank:  # the posterior's continuous mass remakes each disc's family from this file
        t.provenance["learned"]["model_file"] = str(templates["learned_model"])
    return list(bank)


def load_maps(templates: dict, taken=frozenset()) -> list:
    """The templates of the ``[templates] maps`` files (TemplateBank HDF5: maps from the user's own
    simulations) that match the section's ``mass``, ``tau0``, ``beta`` and ``hand``; a simulation has
    its own H/r, so ``h_p`` does not select among them. ``taken``: names already in the scan."""
    out: list = []
    taken = set(taken)
    for path in templates.get("maps", ()):
        maps = TemplateBank.load(path)
        try:
            chosen = select_templates(maps, templates["mass"], templates["tau0"], templates["beta"], templates["hand"])
        except InputError as err:
            raise InputError(f"[templates] maps {path}: {err}") from None
        clash = sorted(taken & {t.name for t in chosen})
        if clash:
            raise InputError(f"[templates] maps {path}: template names {clash[:5]} are already in the scan "
                             "(the bank or another maps file); rename them before saving, "
                             "e.g. dataclasses.replace(template, name='run42_R')")
        taken |= {t.name for t in chosen}
        out += chosen
    return out


def _geometry(config: dict) -> DiscGeometry:
    g = config["geometry"]
    return DiscGeometry(g["inc"], g["PA"], g["dRA"], g["dDec"])


def load_axisymmetric(config: dict, vis, *, progress: bool = True) -> AxisymmetricModel:
    """The axisymmetric model of a configuration: ``[frank] model`` if given, else a frank fit."""
    f = config["frank"]
    if f["model"]:
        model = AxisymmetricModel.load(f["model"])
        check_fitted_to(model, vis, f"[frank] model {f['model']}")
        return model
    if not config["geometry"]["fit"] and not geometry_given(config):
        raise ConfigError(f"{getattr(config, 'source', '') or 'the configuration'}: no [geometry] inc and PA, and "
                          "frank must be fitted: give the disc's inclination and position angle in degrees ([geometry] "
                          "inc = ..., PA = ...), or set [geometry] fit = true to fit them")
    axisym = fit_axisymmetric(vis, _geometry(config), N=f["N"] or None, Rmax=f["Rmax"], alpha=f["alpha"], p0=f["p0"],
                              weights_smooth=f["weights_smooth"], nonnegative=f["nonnegative"],
                              fit_geometry="nonparametric" if config["geometry"]["fit"] else None, progress=progress)
    return axisym.nonnegative() if f["nonnegative"] else axisym
