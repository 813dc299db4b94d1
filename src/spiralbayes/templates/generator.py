"""Make templates with the built-in wake model: one at a time, or the paper's whole grid.

:func:`make_template` turns the wake map of :mod:`.wake` (δΣ/Σ and the temperature response)
into a brightness residual with the S22 radiative transfer
(:func:`~spiralbayes.templates.radiative.template_from_perturbation`); :func:`paper_grid` makes
the 64 templates of Stevenson et al. (2024) for each disc aspect ratio.

There is no wakeflow backend: wakeflow 1.4.0 runs only with several workarounds and takes 20–130 s
per model (see ``tools/make_wakeflow_references.py``, which uses it to make the reference maps the
generator is fitted to, docs/templates.md). To use a wakeflow map as a template, compute
δΣ/Σ with wakeflow and pass it to :func:`~spiralbayes.templates.radiative.template_from_perturbation`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..exceptions import InputError
from .radiative import template_from_perturbation
from .template import (
    SpiralTemplate,
    check_mass_beta,
    check_tau0,
    template_name,
    validate_hand,
)
from .wake import (
    GENERATOR_VERSION,
    PAPER_BETAS,
    PAPER_MASSES,
    PAPER_TAUS,
    WakeSettings,
    cooling_response,
    gap_profile,
    surface_density_perturbation,
)

__all__ = ["make_template", "paper_grid"]


def make_template(
    mass: float,
    tau0: float,
    beta: float,
    hand: str = "R",
    *,
    h_p: float = 0.07,
    flaring: float = 0.25,
    wavelength: float = 0.87e-3,
    n_x: int = 320,
    n_phi: int = 720,
    x_range: tuple[float, float] = (0.2, 2.2),
    backend: str = "builtin",
    store_brightness: bool = True,
    **options,
) -> SpiralTemplate:
    """Make one spiral template with the built-in semi-analytic wake model.

    Parameters
    ----------
    mass : float
        Planet mass ``M_p/M_th`` (``M_th = h_p³ M_*``), > 0.
    tau0 : float
        Initial dust optical depth at ``r_p``, > 0.
    beta : float
        Cooling time ``β = t_c Ω`` (0: isothermal; 10: the paper's slow cooling).
    hand : {'R', 'L'}
        R: anticlockwise orbit with trailing arms; L: its mirror image.
    h_p, flaring : float
        ``H/r`` at the planet and flaring index.
    wavelength : float
        Observing wavelength [m] (0.87e-3: ALMA Band 7).
    n_x, n_phi : int
        Grid size (log-spaced radii, uniform azimuths; keep ``n_phi`` a multiple of 90).
    x_range : (float, float)
        Radial extent ``(x_min, x_max)`` in ``r/r_p``.
    backend : {'builtin'}
        Only the built-in generator (the wakeflow backend was removed: see the module docstring).
    store_brightness : bool
        Keep the normalised intensity map (for plots).
    **options
        Other :class:`WakeSettings` fields (``sigma_slope``, ``gamma``, ``alpha``, ``mstar``,
        ``r_p_au``, ``profile_amp``, ``secondary``, ``gap``, ``nonlinear``, ...).

    Returns
    -------
    SpiralTemplate
    """
    hand = validate_hand(hand)
    check_mass_beta(mass, beta)
    check_tau0(tau0)
    try:
        st = WakeSettings(h_p=h_p, flaring=flaring, wavelength=wavelength, n_x=n_x, n_phi=n_phi,
                          x_min=x_range[0], x_max=x_range[1], **options)
    except TypeError as exc:
        valid = sorted(f.name for f in dataclasses.fields(WakeSettings))
        raise InputError(f"make_template: {exc}; valid options are {valid}") from None
    return _make_from_settings(float(mass), float(tau0), float(beta), hand, st, backend, store_brightness)


def _make_from_settings(mass, tau0, beta, hand, st: WakeSettings, backend="builtin", store_brightness=True):
    x, phi = st.grid()
    if backend == "builtin":
        dsig = surface_density_perturbation(mass, beta, st)
    elif backend == "wakeflow":
        raise InputError("backend='wakeflow' was removed: compute δΣ/Σ with wakeflow (as "
                         "tools/make_wakeflow_references.py does) and pass it to template_from_perturbation")
    else:
        raise InputError(f"unknown backend {backend!r}: use 'builtin'")
    sig_ax = x**-st.sigma_slope * (gap_profile(x, mass, st) if st.gap else 1.0)
    tfac = None
    if beta > 0:
        f_beta = cooling_response(x, beta, st.h_p, st.gamma, st.m_eff_factor)[2]
        tfac = np.clip(1.0 + dsig, 1e-3, None) ** ((st.gamma - 1.0) * f_beta[:, None])
    prov = {
        "generator": f"spiralbayes.templates.wake ({backend})",
        "generator_version": GENERATOR_VERSION,
        "settings": st.to_dict(),
        "references": "Rafikov 2002; Goodman & Rafikov 2001; Bollati et al. 2021; Miranda & Rafikov "
        "2019, 2020a; Fung & Dong 2015; Kanagawa et al. 2016; Speedie, Booth & Dong 2022",
    }
    tmpl = template_from_perturbation(
        x, phi, dsig, tau0, temperature_factor=tfac, sigma_axisym=sig_ax, hand="R", mass=mass,
        beta=beta, h_p=st.h_p, flaring=st.flaring, sigma_slope=st.sigma_slope,
        wavelength=st.wavelength, mstar=st.mstar, r_p_au=st.r_p_au, mu=st.mu,
        name=template_name(mass, tau0, beta, "R", h_p=st.h_p), provenance=prov, store_brightness=store_brightness,
    )
    return tmpl if hand == "R" else tmpl.mirror()


def paper_grid(
    masses=PAPER_MASSES, taus=PAPER_TAUS, betas=PAPER_BETAS, hands=("R", "L"), h_ps=None,
    *, store_brightness: bool = False, progress: bool = False, **options,
) -> list[SpiralTemplate]:
    """The paper's template grid: ``M_p/M_th ∈ {0.1, 0.3, 1, 3} × τ0 ∈ {0.1, 0.3, 1, 3} ×
    β ∈ {0, 10} × {R, L}`` = 64 templates (Stevenson et al. 2024, sec. 2.3) for each disc aspect
    ratio in ``h_ps`` (default: ``options["h_p"]``, else 0.07 as in the paper).

    ``options`` go to :class:`WakeSettings` (e.g. ``n_x``, ``n_phi``). Ordered by H/r, then mass,
    then τ0, then β, then hand.
    """
    if h_ps is None:
        h_ps = (options.pop("h_p", WakeSettings.h_p),)
    elif "h_p" in options:
        raise InputError("paper_grid: give the aspect ratios as h_ps=..., not h_p=")
    settings = [WakeSettings(h_p=float(hp), **options) for hp in h_ps]
    combos = [(st, m, t, b, h) for st in settings for m in masses for t in taus for b in betas for h in hands]
    it = combos
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(combos, desc="templates", unit="tmpl")
    out = []
    for st, m, t, b, h in it:
        out.append(_make_from_settings(float(m), float(t), float(b), validate_hand(h), st,
                                       store_brightness=store_brightness))
    return out
