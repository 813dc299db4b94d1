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
  the generator's gap) and linearised (``δ`` per unit peak ``δΣ/Σ``).

A variant's δ is ``scale (M_p/M_th)^scale_slope T + blob (M_p/M_th)^blob_slope B``. Templates
enter the visibilities linearly, so these are exactly the spirals the scan sees; the constants were
fitted with ``tools/fit_variants.py`` by least squares of the noise-free visibilities (the fiducial
observation, 50 au, 30° inclination: ``tests/templates/variant_fit.py``) to the reference maps named
in each variant's ``fitted_to``, with the two powers chosen on a grid, then shrunk by one factor so
that the variant's amplitude fit to each of those maps is at least ``1 / margin`` (a variant that
carries less power than the spiral it stands for cannot exclude it). **Hydrodynamics is the
reference** (docs/limits.md §4d): ``hydro`` is fitted to every finished FARGO3D reference run (the two runs of
``fargo3d_isothermal.h5`` and the library's ``role = library`` runs: isothermal gas at H/r 0.07 and
0.10, β = 10 against the β = 10 generator, gas + dust), at every τ0 they were reduced for; wakeflow
is a second witness with its own variant. The references are ``tests/data/references/``
(tools/README.md); the fit and the acceptance are in docs/templates.md ("Morphology variants") and
docs/limits.md §4d.

Names: ``<variant>_m1_tau0.3_b0_h0.07_R`` (the compromise keeps the generator's ``wake_`` prefix);
the variant is in ``provenance["variant"]`` and the template metadata (``variant``), so it is part of
the template family (:mod:`spiralbayes.inference.limits.families`) and of mirror matching.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np

from ..exceptions import InputError
from .generator import make_template
from .radiative import template_from_perturbation
from .template import SpiralTemplate, template_name, validate_hand
from .wake import PAPER_BETAS, PAPER_MASSES, PAPER_TAUS, WakeSettings, gap_profile

__all__ = ["DEFAULT_VARIANTS", "VARIANTS", "Variant", "blob_template", "get_variant", "variant_bank", "variant_grid",
           "variant_template"]


@dataclass(frozen=True)
class Variant:
    """One morphology: ``δ = scale μ^scale_slope T + blob μ^blob_slope B``, ``μ = M_p/M_th``
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
    fitted_to: tuple = ()
    note: str = ""
    extra: dict = field(default_factory=dict)

    def blob_amplitude(self, mass: float) -> float:
        """Peak δΣ/Σ of the near-planet peak at ``mass`` [M_th]."""
        return float(self.blob * float(mass) ** self.blob_slope)

    def scale_at(self, mass: float) -> float:
        """Factor on the generator's template at ``mass`` [M_th]."""
        return float(self.scale * float(mass) ** self.scale_slope)


VARIANTS: dict[str, Variant] = {
    "compromise": Variant(
        "compromise", note="the generator as calibrated in issue 9 against all 11 reference maps (wake.py, step 3)"),
    # fitted by tools/fit_variants.py; A_up per reference case in docs/templates.md, the
    # leave-one-source-out calibration in docs/limits.md §4d
    "hydro": Variant(
        "hydro", scale=0.3832, scale_slope=-0.4, blob=-0.0665, blob_slope=3.0, blob_width=0.5,
        fitted_to=("fargo3d_isothermal.h5:h0.07_mu0.3", "fargo3d_isothermal.h5:h0.07_mu1",
                   *(f"fargo3d_library.h5:{g}" for g in (
                       "h0.07_mu0.1", "h0.07_mu0.3", "h0.07_mu1", "h0.07_mu3", "h0.10_mu0.3", "h0.10_mu1",
                       "h0.07_mu0.3_beta10", "h0.07_mu1_beta10", "h0.07_mu1_st0.03", "h0.05_mu1", "h0.05_mu0.3"))),
        note="least squares to the 13 finished FARGO3D reference runs at every reduced tau0 (2 x 2 + 11 x 4 maps; "
             "beta = 10 runs against the beta = 10 generator): scale 0.5816 mu^-0.4, blob -0.1009 mu^3 (powers "
             "chosen on a grid), shrunk by k = 0.6588 so that fargo3d_library.h5:h0.07_mu0.1 at tau0 0.1, the "
             "binding case, has A_hat = 1/0.9; the falling scale follows the hydro's flatter power-mass law "
             "(E ~ M^1.8 vs the generator's M^2.2) and its lower overlap at 3 M_th; the negative peak at 3 M_th "
             "takes out the generator's excess at the planet (docs/templates.md)"),
    "wakeflow": Variant(
        "wakeflow", scale=0.7069, blob=0.1188, blob_slope=0.0, blob_width=0.5,
        fitted_to=tuple(f"wakeflow_isothermal.h5:h{h}_mu{m}" for h in ("0.05", "0.07", "0.10")
                        for m in ("0.1", "0.3", "1")),
        note="least squares to the 9 wakeflow maps at tau0 0.3 and 3 (scale 0.9748, blob 0.1639), shrunk by "
             "k = 0.7252 so that wakeflow_isothermal.h5:h0.05_mu1 at tau0 3, the binding case, has A_hat = 1/0.9"),
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


@functools.lru_cache(maxsize=64)
def _blob_delta(tau0: float, mass: float, h_p: float, width: float, settings: WakeSettings) -> np.ndarray:
    x, phi = settings.grid()
    d2 = x[:, None] ** 2 + 1.0 - 2.0 * x[:, None] * np.cos(phi[None, :])
    eps = 1e-3  # linearised: δ per unit peak δΣ/Σ
    dsig = eps * np.exp(-0.5 * d2 / (width * h_p) ** 2)
    sig_ax = x**-settings.sigma_slope * (gap_profile(x, mass, settings) if settings.gap else 1.0)
    t = template_from_perturbation(x, phi, dsig, tau0, sigma_axisym=sig_ax, h_p=h_p, flaring=settings.flaring,
                                   sigma_slope=settings.sigma_slope, wavelength=settings.wavelength,
                                   mstar=settings.mstar, r_p_au=settings.r_p_au, mu=settings.mu,
                                   store_brightness=False)
    out = np.asarray(t.delta, dtype=float) / eps
    out.setflags(write=False)
    return out


def blob_template(mass: float, tau0: float, beta: float, hand: str = "R", *, h_p: float = 0.07,
                  width: float = 0.5, **options) -> SpiralTemplate:
    """The near-planet peak ``B`` alone (δ per unit peak δΣ/Σ; module docstring)."""
    st = WakeSettings(h_p=h_p, **options)
    x, phi = st.grid()
    delta = _blob_delta(float(tau0), float(mass), float(h_p), float(width), st)
    t = SpiralTemplate(x=x, phi=phi, delta=np.array(delta), mass=float(mass), tau0=float(tau0), beta=float(beta),
                       h_p=float(h_p), flaring=st.flaring, wavelength=st.wavelength, hand="R",
                       name=template_name(mass, tau0, beta, "R", prefix="blob", h_p=h_p),
                       provenance={"generator": "spiralbayes.templates.variants.blob_template", "width_Hp": width})
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
    prefix = "wake" if v.name == "compromise" else v.name
    prov = {**base.provenance, "variant": v.name, "variant_constants": {
        "scale": v.scale, "scale_slope": v.scale_slope, "blob": v.blob, "blob_slope": v.blob_slope,
        "blob_width_Hp": v.blob_width, "fitted_to": list(v.fitted_to), "note": v.note}}
    t = replace(base, delta=delta.astype(base.delta.dtype, copy=False), brightness=None,
                name=template_name(mass, tau0, beta, "R", prefix=prefix, h_p=h_p), provenance=prov)
    return t if validate_hand(hand) == "R" else t.mirror()


def variant_grid(variants=DEFAULT_VARIANTS, masses=PAPER_MASSES, taus=PAPER_TAUS, betas=PAPER_BETAS,  # noqa: PLR0913
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
    """The default bank with morphology variants: :func:`variant_grid` for every H/r of
    :data:`~spiralbayes.templates.bank.DEFAULT_H_PS` (576 templates), cached on disk like
    :func:`~spiralbayes.templates.bank.default_bank` (``variants-<key>.h5``; the key hashes the
    generator settings, the H/r and every variant's constants, so a refit rebuilds).

    Scan it as the default bank; :func:`~spiralbayes.inference.limits.compute_limits` then reports
    robust limits (a mass is excluded only where every variant excludes it) and the price of
    robustness, and the detection's best template may be of any variant.
    """
    import hashlib
    import json
    from pathlib import Path

    from .bank import DEFAULT_H_PS, TemplateBank, default_cache_dir

    h_ps = tuple(float(h) for h in np.atleast_1d(DEFAULT_H_PS if h_ps is None else h_ps))
    chosen = [get_variant(v) for v in variants]
    settings = WakeSettings(h_p=h_ps[0], **{k: v for k, v in options.items() if k in WakeSettings.__dataclass_fields__})
    blob = json.dumps({"settings": settings.key(), "h_ps": h_ps, "options": sorted(options.items()),
                       "variants": [(v.name, v.scale, v.scale_slope, v.blob, v.blob_slope, v.blob_width)
                                    for v in chosen]},
                      default=str)
    key = hashlib.sha256(blob.encode()).hexdigest()[:16]
    path = (Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()) / f"variants-{key}.h5"
    n_expected = 64 * len(h_ps) * len(chosen)
    if path.exists() and not rebuild:
        try:
            bank = TemplateBank.load(path)
            if bank.provenance.get("variant_key") == key and len(bank) == n_expected:
                return bank
        except (ValueError, OSError, KeyError):
            pass
    templates = variant_grid(chosen, h_ps=h_ps, **options)
    bank = TemplateBank(templates, {"variant_key": key, "variants": [v.name for v in chosen], "h_ps": list(h_ps),
                                    "generator": "spiralbayes.templates.variants.variant_grid"})
    try:
        bank.save(path)
    except OSError:
        pass
    return bank
