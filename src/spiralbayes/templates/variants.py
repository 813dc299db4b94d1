"""Template morphology variants: a small set of spiral shapes per (M_p, H/r, τ0, β) spanning the references.

No template is the true spiral (docs/limits.md §4c): the built-in generator
(:mod:`.wake`, fitted as a compromise between wakeflow and FARGO3D) projects a
hydrodynamic spiral onto less than its own power, so a fixed-shape template wrongly excludes
planets that are there. The morphology is therefore a nuisance with a few discrete values, each a
linear combination of two building blocks on the generator's grid:

* ``T`` — the generator's template (:func:`~spiralbayes.templates.generator.make_template`);
* ``B`` — the **near-planet density peak** that both the FARGO3D and the wakeflow maps hold at the
  planet and the wake model does not: ``δΣ/Σ = exp(−d²/2w²)`` with ``d`` the distance from the
  planet [r_p] and ``w = blob_width H_p``, put through the same radiative transfer (isothermal, with
  the generator's gap) and linearised (``δ`` per unit peak ``δΣ/Σ``);
* ``W`` — the **broad wake**: the generator's template with its linear wake profile ``broad_width``
  times wider (``profile_width``; 3 by default). The hydrodynamic wakes are wider than the
  generator's and flanked by broad troughs (Fasano et al. 2024 find wakeflow's too narrow against
  FARGO3D; docs/templates.md), which ``T − c W`` describes: in the beam-smoothed image a third
  block of this width lifts the span's mean correlation with the 30 FARGO3D maps from 0.82 to 0.87
  (``T`` and ``B`` alone; 0.86 for twice the width, 0.84 for a narrower profile).

A fourth block, the **co-orbital dust band** ``D`` (:func:`coorbital_template`: dust piled up behind
the planet along its orbit and missing ahead of it, as the library's St 0.03–0.1 dust runs show),
is in no built-in variant: its amplitude spans two decades across Stokes numbers and disc ages
(docs/verdict.md, "The block in the scan").

A variant's δ is ``(M_p/M_th)^scale_slope (scale T + broad W) + blob (M_p/M_th)^blob_slope B``. Templates
enter the visibilities linearly, so these are exactly the spirals the scan sees; the constants were
fitted with ``tools/fit_variants.py`` by least squares of the noise-free visibilities (the fiducial
observation, 50 au, 30° inclination: ``tests/templates/variant_fit.py``) to the reference maps named
in each variant's ``fitted_to``, with the two powers chosen on a grid, then shrunk by one factor so
that the variant's amplitude fit to each of those maps is at least ``1 / margin`` (a variant that
carries less power than the spiral it stands for cannot exclude it). **Hydrodynamics is the
reference** (docs/limits.md §4d): ``hydro`` is fitted to every finished FARGO3D reference run (the two runs of
``fargo3d_isothermal.h5`` and the library's ``role = library`` runs: isothermal gas at H/r 0.05, 0.07 and
0.10, β = 10 against the β = 10 generator, gas + dust at St 0.03; the St 0.01 and 0.1 dust run set and
the ``physics`` run set are held out, as leave-one-source-out sources of their own), at every τ0 they
were reduced for; wakeflow
is a second witness with its own variant. The references are ``tests/data/references/``
(tools/README.md); the fit and the acceptance are in docs/templates.md ("Morphology variants") and
docs/limits.md §4d.

Names: ``<variant>_m1_tau0.3_b0_h0.07_R`` (the compromise keeps the generator's ``wake_`` prefix);
the variant is in ``provenance["variant"]`` and the template metadata (``variant``), so it is part of
the template family (:mod:`spiralbayes.inference.limits.families`) and of mirror matching.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import logging
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..exceptions import InputError
from .bank import DEFAULT_H_PS, TemplateBank, cached_bank, default_cache_dir
from .generator import make_template
from .radiative import template_from_perturbation
from .template import SpiralTemplate, template_name, validate_hand
from .wake import PAPER_BETAS, PAPER_MASSES, PAPER_TAUS, WakeSettings, gap_profile

__all__ = ["DEFAULT_VARIANTS", "VARIANTS", "Variant", "blob_template", "broad_template", "coorbital_template",
           "default_bank", "get_variant", "variant_bank", "variant_grid", "variant_template"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Variant:
    """One morphology: ``δ = μ^scale_slope (scale T + broad W) + blob μ^blob_slope B``, ``μ = M_p/M_th``
    (module docstring).

    Attributes
    ----------
    name : str
    scale : float
        Factor on the generator's template at 1 M_th.
    scale_slope : float
        Power of M_p/M_th in that factor.
    blob : float
        Peak δΣ/Σ of the near-planet density peak at 1 M_th.
    blob_slope : float
        Power of M_p/M_th in the peak's amplitude.
    blob_width : float
        Gaussian width of the peak [H_p].
    broad : float
        Factor on the broad wake ``W`` at 1 M_th (it follows ``scale_slope`` with mass).
    broad_width : float
        Width of ``W``'s linear wake profile, in units of the generator's ``profile_width``.
    mass_factors : tuple of (float, float)
        ``(M_p/M_th, k)`` pairs: every block is multiplied by ``k`` at that mass (the fit's shrink,
        one per reference mass, so that the spread of the references at one mass does not weaken
        the variant at another); linear in ``log M_p`` between them, constant beyond. Empty: 1.
    fitted_to : tuple of str
        Reference cases (``file:group``) the constants were fitted to (empty: not fitted here).
    note : str
        Where the constants come from.
    """

    name: str
    scale: float = 1.0
    scale_slope: float = 0.0
    blob: float = 0.0
    blob_slope: float = 1.0
    blob_width: float = 0.5
    broad: float = 0.0
    broad_width: float = 3.0
    mass_factors: tuple = ()
    fitted_to: tuple = ()
    note: str = ""
    extra: dict = field(default_factory=dict)

    def factor_at(self, mass: float) -> float:
        """The shrink ``k`` at ``mass`` [M_th] (``mass_factors``)."""
        if not self.mass_factors:
            return 1.0
        m, k = np.array(sorted(self.mass_factors), dtype=float).T
        return float(np.interp(np.log(float(mass)), np.log(m), k))

    def blob_amplitude(self, mass: float) -> float:
        """Peak δΣ/Σ of the near-planet peak at ``mass`` [M_th]."""
        return float(self.factor_at(mass) * self.blob * float(mass) ** self.blob_slope)

    def scale_at(self, mass: float) -> float:
        """Factor on the generator's template at ``mass`` [M_th]."""
        return float(self.factor_at(mass) * self.scale * float(mass) ** self.scale_slope)

    def broad_at(self, mass: float) -> float:
        """Factor on the broad wake at ``mass`` [M_th]."""
        return float(self.factor_at(mass) * self.broad * float(mass) ** self.scale_slope)

    def constants(self) -> dict:
        """The numbers that make the template (stored in its provenance and in bank cache keys)."""
        return {"scale": self.scale, "scale_slope": self.scale_slope, "blob": self.blob,
                "blob_slope": self.blob_slope, "blob_width_Hp": self.blob_width, "broad": self.broad,
                "broad_width": self.broad_width, "mass_factors": [list(p) for p in self.mass_factors]}

    @classmethod
    def from_constants(cls, name: str, constants: dict) -> Variant:
        """The variant of a template's ``provenance["variant_constants"]`` (:meth:`constants`; the keys
        added later default as in older banks). Raises KeyError, TypeError or ValueError when malformed."""
        c = constants
        return cls(str(name), scale=float(c["scale"]), scale_slope=float(c.get("scale_slope", 0.0)),
                   blob=float(c["blob"]), blob_slope=float(c["blob_slope"]), blob_width=float(c["blob_width_Hp"]),
                   broad=float(c.get("broad", 0.0)), broad_width=float(c.get("broad_width", 3.0)),
                   mass_factors=tuple((float(m), float(k)) for m, k in c.get("mass_factors", ())))


VARIANTS: dict[str, Variant] = {
    "compromise": Variant(
        "compromise", note="the generator as calibrated in issue 9 against all 11 reference maps (wake.py, step 3)"),
    # fitted by tools/fit_variants.py; A_up per reference case in docs/templates.md, the
    # leave-one-source-out calibration in docs/limits.md §4d
    "hydro": Variant(
        "hydro", scale=0.9529, scale_slope=-0.1, blob=0.1223, blob_slope=0.0, blob_width=0.5, broad=-0.1020,
        broad_width=3.0, mass_factors=((0.1, 0.7339), (0.3, 0.8000), (1.0, 0.7004), (3.0, 0.4288)),
        fitted_to=("fargo3d_isothermal.h5:h0.07_mu0.3", "fargo3d_isothermal.h5:h0.07_mu1",
                   *(f"fargo3d_library.h5:{g}" for g in (
                       "h0.05_mu0.3", "h0.05_mu1", "h0.05_mu3", "h0.05_mu3_orbits200", "h0.07_mu0.1", "h0.07_mu0.3",
                       "h0.07_mu0.3_beta10", "h0.07_mu1", "h0.07_mu1_beta10", "h0.07_mu1_orbits200", "h0.07_mu1_st0.03",
                       "h0.07_mu3", "h0.07_mu3_orbits200", "h0.10_mu0.3", "h0.10_mu1"))),
        note="least squares of (T, B, W) to the 17 quasi-steady FARGO3D reference runs at every reduced tau0 "
             "(2 x 2 + 15 x 4 maps; beta = 10 runs against the beta = 10 generator; powers of M_p chosen on a "
             "grid): mu^-0.1 (0.9529 T - 0.1020 W) + 0.1223 B, then one shrink per reference mass so that every "
             "map of that mass has A_hat >= 1/0.8 (margin 0.8: the largest of 0.9, 0.85, 0.8 that passes the "
             "leave-one-source-out calibration, docs/limits.md section 4d); binding cases "
             "h0.07_mu0.1 tau0 0.1 (0.1 M_th), h0.07_mu0.3_beta10 tau0 0.1 (0.3), h0.05_mu1 tau0 3 (1) and "
             "fargo3d_library.h5:h0.07_mu3 at tau0 0.1 (3 M_th, the binding case overall); the broad wake W "
             "(negative) makes the arms wider with troughs beside them, as the hydro's are (docs/templates.md)"),
    "wakeflow": Variant(
        "wakeflow", scale=0.9571, blob=0.4487, blob_slope=0.5, blob_width=0.5,
        mass_factors=((0.1, 0.7328), (0.3, 0.6695), (1.0, 0.6375)),
        fitted_to=tuple(f"wakeflow_isothermal.h5:h{h}_mu{m}" for h in ("0.05", "0.07", "0.10")
                        for m in ("0.1", "0.3", "1")),
        note="least squares of (T, B) to the 9 wakeflow maps at tau0 0.3 and 3: 0.9571 T + 0.4487 mu^0.5 B, then "
             "one shrink per mass (margin 0.8, as hydro); binding case wakeflow_isothermal.h5:h0.05_mu1 at tau0 3 "
             "(also h0.05_mu0.1 and h0.05_mu0.3 at tau0 3 for their masses); no broad wake: wakeflow's wakes are "
             "the narrow ones"),
}
"""The built-in variants, by name."""

DEFAULT_VARIANTS = ("compromise", "hydro", "wakeflow")
"""The morphology set of a variant bank (:func:`variant_grid`) unless told otherwise."""


def get_variant(variant) -> Variant:
    """A :class:`Variant` from itself or its name."""
    if isinstance(variant, Variant):
        return variant
    try:
        return VARIANTS[str(variant)]
    except KeyError:
        raise InputError(f"unknown morphology variant {variant!r}: use one of {sorted(VARIANTS)} "
                         "or a templates.variants.Variant") from None


def _perturbed_delta(dsig: np.ndarray, tau0: float, mass: float, h_p: float, settings: WakeSettings) -> np.ndarray:
    """δ of the generator's (gapped) disc perturbed by ``δΣ/Σ = dsig`` on ``settings.grid()``, through
    its radiative transfer."""
    x, phi = settings.grid()
    sig_ax = x**-settings.sigma_slope * (gap_profile(x, mass, settings) if settings.gap else 1.0)
    t = template_from_perturbation(x, phi, dsig, tau0, sigma_axisym=sig_ax, h_p=h_p, flaring=settings.flaring,
                                   sigma_slope=settings.sigma_slope, wavelength=settings.wavelength,
                                   mstar=settings.mstar, r_p_au=settings.r_p_au, mu=settings.mu,
                                   store_brightness=False)
    return np.asarray(t.delta, dtype=float)


@functools.lru_cache(maxsize=64)
def _blob_delta(tau0: float, mass: float, h_p: float, width: float, settings: WakeSettings) -> np.ndarray:
    x, phi = settings.grid()
    d2 = x[:, None] ** 2 + 1.0 - 2.0 * x[:, None] * np.cos(phi[None, :])
    eps = 1e-3  # linearised: δ per unit peak δΣ/Σ
    out = _perturbed_delta(eps * np.exp(-0.5 * d2 / (width * h_p) ** 2), tau0, mass, h_p, settings) / eps
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=64)
def _coorbital_delta(tau0: float, mass: float, h_p: float, width: float, settings: WakeSettings) -> np.ndarray:
    x, phi = settings.grid()
    band = np.exp(-0.5 * ((x - 1.0) / (width * h_p)) ** 2)[:, None] * -np.sin(phi)[None, :]
    eps = 1e-3  # a central difference: δ per unit δΣ/Σ, odd in φ like the band (no second-order term)
    out = (_perturbed_delta(eps * band, tau0, mass, h_p, settings)
           - _perturbed_delta(-eps * band, tau0, mass, h_p, settings)) / (2 * eps)
    out -= out.mean(axis=1, keepdims=True)  # an m = 1 pattern: nothing for the axisymmetric model to absorb
    out.setflags(write=False)
    return out


def _block_template(delta_of, prefix: str, mass: float, tau0: float, beta: float, hand: str, h_p: float,
                    width: float, options: dict) -> SpiralTemplate:
    """A building block as a template: ``delta_of(tau0, mass, h_p, width, settings)`` on the generator's
    grid, right-handed, mirrored for ``hand = "L"``."""
    st = WakeSettings(h_p=h_p, **options)
    x, phi = st.grid()
    delta = delta_of(float(tau0), float(mass), float(h_p), float(width), st)
    t = SpiralTemplate(x=x, phi=phi, delta=np.array(delta), mass=float(mass), tau0=float(tau0), beta=float(beta),
                       h_p=float(h_p), flaring=st.flaring, wavelength=st.wavelength, hand="R",
                       name=template_name(mass, tau0, beta, "R", prefix=prefix, h_p=h_p),
                       provenance={"generator": f"spiralbayes.templates.variants.{prefix}_template", "width_Hp": width})
    return t if validate_hand(hand) == "R" else t.mirror()


def coorbital_template(mass: float, tau0: float, beta: float, hand: str = "R", *, h_p: float = 0.07,
                       width: float = 1.0, **options) -> SpiralTemplate:
    """The co-orbital dust block ``D`` alone: ``δΣ/Σ = -exp(-(x - 1)²/2w²) sin Δφ`` with
    ``w = width H_p``, dust piled up behind the planet and depleted ahead of it (hand R: the planet
    moves towards +φ), through the same radiative transfer as the near-planet peak (δ per unit
    δΣ/Σ; module docstring)."""
    return _block_template(_coorbital_delta, "coorbital", mass, tau0, beta, hand, h_p, width, options)


def blob_template(mass: float, tau0: float, beta: float, hand: str = "R", *, h_p: float = 0.07,
                  width: float = 0.5, **options) -> SpiralTemplate:
    """The near-planet peak ``B`` alone (δ per unit peak δΣ/Σ; module docstring)."""
    return _block_template(_blob_delta, "blob", mass, tau0, beta, hand, h_p, width, options)


def broad_template(mass: float, tau0: float, beta: float, hand: str = "R", *, h_p: float = 0.07,
                   width: float = 3.0, **options) -> SpiralTemplate:
    """The broad wake ``W`` alone: the generator's template with a ``width`` times wider linear
    wake profile (module docstring)."""
    base_width = float(options.pop("profile_width", WakeSettings.profile_width))
    t = make_template(mass, tau0, beta, "R", h_p=h_p, store_brightness=False, profile_width=width * base_width,
                      **options)
    t = replace(t, name=template_name(mass, tau0, beta, "R", prefix="broad", h_p=h_p),
                provenance={**t.provenance, "generator": "spiralbayes.templates.variants.broad_template",
                            "width_factor": width})
    return t if validate_hand(hand) == "R" else t.mirror()


def variant_template(mass: float, tau0: float, beta: float, hand: str = "R", variant="compromise", *,
                     h_p: float = 0.07, **options) -> SpiralTemplate:
    """The template of one morphology ``variant`` (a name or :class:`Variant`) at these parameters.

    ``options`` go to :func:`~spiralbayes.templates.generator.make_template` (grid, disc settings).
    """
    v = get_variant(variant)
    base = make_template(mass, tau0, beta, "R", h_p=h_p, store_brightness=False, **options)
    delta = v.scale_at(mass) * np.asarray(base.delta, dtype=float)
    if v.blob != 0.0:
        grid_opts = {k: options[k] for k in options if k in WakeSettings.__dataclass_fields__}
        b = blob_template(mass, tau0, beta, "R", h_p=h_p, width=v.blob_width, **grid_opts)
        delta = delta + v.blob_amplitude(mass) * np.asarray(b.delta, dtype=float)
    if v.broad != 0.0:
        w = broad_template(mass, tau0, beta, "R", h_p=h_p, width=v.broad_width, **options)
        delta = delta + v.broad_at(mass) * np.asarray(w.delta, dtype=float)
    prefix = "wake" if v.name == "compromise" else v.name
    prov = {**base.provenance, "variant": v.name, "variant_constants": {
        **v.constants(), "fitted_to": list(v.fitted_to), "note": v.note}}
    t = replace(base, delta=delta.astype(base.delta.dtype, copy=False), brightness=None,
                name=template_name(mass, tau0, beta, "R", prefix=prefix, h_p=h_p), provenance=prov)
    return t if validate_hand(hand) == "R" else t.mirror()


def variant_grid(variants=DEFAULT_VARIANTS, masses=PAPER_MASSES, taus=PAPER_TAUS, betas=PAPER_BETAS,
                 hands=("R", "L"), h_ps=(0.07,), **options) -> list[SpiralTemplate]:
    """Every variant's template for each (H/r, mass, τ0, β, hand): the paper's grid times the
    morphology set (3 variants × 3 H/r × 64 = 576 templates with the defaults of the default bank)."""
    out = []
    for h in h_ps:
        for name in variants:
            for m in masses:
                for tau in taus:
                    for b in betas:
                        right = variant_template(m, tau, b, "R", name, h_p=float(h), **options)
                        for hand in hands:
                            out.append(right if validate_hand(hand) == "R" else right.mirror())
    return out


def variant_bank(variants=DEFAULT_VARIANTS, h_ps=None, cache_dir=None, rebuild: bool = False, **options):
    """The bank with morphology variants: :func:`variant_grid` for every H/r of ``h_ps`` (default
    :data:`~spiralbayes.templates.bank.DEFAULT_H_PS`: 576 templates with the default variants), cached
    on disk like :func:`~spiralbayes.templates.bank.compromise_bank` (``variants-<key>.h5``; the key
    hashes the generator settings, the H/r and every variant's constants, so a refit rebuilds).

    With its defaults this is :func:`default_bank`;
    :func:`~spiralbayes.inference.limits.compute_limits` then reports robust limits (a mass is
    excluded only where every variant excludes it) and the price of robustness, and the
    detection's best template may be of any variant.

    Parameters
    ----------
    variants : sequence of str
        Names of the morphology variants (default: compromise, hydro, wakeflow).
    h_ps : float or sequence of float, optional
        Aspect ratios H/r at the planet (default ``DEFAULT_H_PS``: 0.05, 0.07, 0.10).
    cache_dir : str or Path, optional
        Where to cache the bank (default: the package's cache folder).
    rebuild : bool
        Build the bank even when a cached copy exists.
    **options
        Generator options (fields of ``WakeSettings``), part of the cache key.

    Returns
    -------
    TemplateBank
        ``64 × len(h_ps) × len(variants)`` templates.
    """
    h_ps = tuple(float(h) for h in np.atleast_1d(DEFAULT_H_PS if h_ps is None else h_ps))
    chosen = [get_variant(v) for v in variants]
    settings = WakeSettings(h_p=h_ps[0], **{k: v for k, v in options.items() if k in WakeSettings.__dataclass_fields__})
    blob = json.dumps({"settings": settings.key(), "h_ps": h_ps, "options": sorted(options.items()),
                       "variants": [(v.name, sorted(v.constants().items())) for v in chosen]},
                      default=str)
    key = hashlib.sha256(blob.encode()).hexdigest()[:16]
    path = (Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()) / f"variants-{key}.h5"
    n_expected = 64 * len(h_ps) * len(chosen)
    cached = cached_bank(path, "variant_key", key, n_expected, rebuild)
    if cached is not None:
        return cached
    t0 = time.perf_counter()
    templates = variant_grid(chosen, h_ps=h_ps, **options)
    log.info("built the morphology-variant bank (%d templates) in %.1f s", len(templates), time.perf_counter() - t0)
    bank = TemplateBank(templates, {"variant_key": key, "variants": [v.name for v in chosen], "h_ps": list(h_ps),
                                    "generator": "spiralbayes.templates.variants.variant_grid"})
    with contextlib.suppress(OSError):  # a read-only cache folder costs a rebuild next time, nothing more
        bank.save(path)
    return bank


def default_bank(cache_dir=None, rebuild: bool = False, h_ps=DEFAULT_H_PS, **options) -> TemplateBank:
    """The default bank, robust to the spiral's morphology: the paper's 64-template grid for each
    ``H/r`` of :data:`~spiralbayes.templates.bank.DEFAULT_H_PS` in each morphology of
    :data:`DEFAULT_VARIANTS` (compromise, hydro, wakeflow: 576 templates; :func:`variant_bank`),
    cached on disk.

    No template is the true spiral (docs/limits.md §4c): a single morphology wrongly rules out
    planets whose spirals it overlaps poorly, so limits from this bank exclude a mass only where
    every variant excludes it, and name the price of that robustness. Select a subset with
    :meth:`~spiralbayes.templates.TemplateBank.select` (e.g. ``select(h_p=0.07, tau0=3)``) to scan
    faster; :func:`~spiralbayes.templates.bank.compromise_bank` is the single-morphology bank of
    the paper's comparisons.

    Parameters
    ----------
    cache_dir : path, optional
        Where to cache the bank (default :func:`~spiralbayes.templates.bank.default_cache_dir`).
    rebuild : bool
        Rebuild even if a cached copy exists.
    h_ps : sequence of float
        Disc aspect ratios ``H/r`` at r_p (``h_p=`` gives one).
    **options
        Passed to :func:`variant_bank` (``variants``, or :class:`~spiralbayes.templates.wake.WakeSettings`
        fields such as ``n_phi`` or ``wavelength``).

    Returns
    -------
    TemplateBank
        576 templates with the default H/r and morphologies (fewer with other ``h_ps``).
    """
    if "h_p" in options:
        h_ps = (options.pop("h_p"),)
    return variant_bank(h_ps=h_ps, cache_dir=cache_dir, rebuild=rebuild, **options)
