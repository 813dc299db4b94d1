"""Built-in semi-analytic spiral templates: planet wake → dust brightness residual δ.

The hydrodynamic templates of Stevenson et al. (2024) (2-D gas+dust FARGO3D runs of Speedie,
Booth & Dong 2022, "S22") are not public. This module makes templates of the same kind in
seconds from the analytic theory of planet wakes, so that the package works out of the box.
Every step cites its source; numbers marked "fitted" are defaults we fitted to the reference maps, not facts.

Recipe (``x = r/r_p``, ``h_p = H/r`` at ``r_p``, ``H/r ∝ r^f`` with flaring ``f``, so the sound
speed ``c_s ∝ r^{-q}`` with ``q = 1/2 − f``; ``Σ ∝ r^{-p}``; rotation anticlockwise, i.e. hand R):

1. **Cooling** (Miranda & Rafikov 2020a; Zhang & Zhu 2020): thermal relaxation ``t_c = β/Ω``,
   wave frequency ``ω ≈ m_eff |Ω − Ω_p|`` with ``m_eff = m_eff_factor / h_p`` (m_eff between
   ``1/(2h_p)`` and ``1/h_p``; default ``0.5/h_p``), so ``ω t_c = β m_eff |1 − x^{3/2}|``.
   Effective adiabatic index ``γ_eff = (1 + γ ω²t_c²)/(1 + ω²t_c²)`` (1 for β = 0) and
   temperature response ``f_β = ω t_c / √(1 + ω² t_c²)``.
2. **Wake shape** (Rafikov 2002, eq. 44; Ogilvie & Lubow 2002; Muto et al. 2012): the ridge
   satisfies ``dφ/dr = −(Ω − Ω_p)/c_s,eff`` with ``c_s,eff = √γ_eff c_s``; for γ_eff = 1 this is
   the closed form :func:`wake_shape`.
3. **Amplitude** (Goodman & Rafikov 2001; Rafikov 2002; Bollati et al. 2021): along the wake the
   profile ``χ(η, t)`` obeys the inviscid Burgers equation ``∂_t χ + χ ∂_η χ = 0`` in the wave
   "time" ``t(r)`` (:func:`wave_time`) and the azimuthal coordinate
   ``η = (3/(2h_p)) sgn(x − 1) (φ − φ_wake)``; ``δΣ/Σ = 2χ/((γ_B + 1) g(r))`` (:func:`g_factor`).
   The solve starts at ``t0 = t(r_p ± 2l)``, ``l = (2/3) H_p`` (Bollati et al. 2021), from
   ``χ0 = (γ_B + 1) β_p Λ(η) / 2^{3/4}`` with ``β_p = M_p/M_1 = 1.5 M_p/M_th``
   (``M_1 = (2/3) h_p³ M_*``, Goodman & Rafikov 2001). ``γ_B = 1`` for β = 0 and the adiabatic
   γ_eff at ``|1 − x^{3/2}| = 1/2`` otherwise. Λ, the linear wake profile for ``M_p = M_1``, is
   modelled as a zero-mean pulse: a positive Gaussian (peak ``profile_amp`` = 0.4, width
   ``profile_width`` = 0.95 in η) and a *broad* negative lobe of equal area (width 11.5 × 0.95 in
   η, i.e. ≈ 0.5 rad at h_p = 0.07, centred 0.5 × 0.95 behind the peak), then made exactly
   zero-mean on the η period. **Fitted** to all 11 reference maps
   (``tests/data/references/wakeflow_isothermal.h5``: wakeflow 1.4.0, H/r 0.05–0.10 × 0.1–1 M_th;
   ``fargo3d_isothermal.h5``: our FARGO3D runs, H/r 0.07 × 0.3 and 1 M_th), each for τ0 = 0.3
   and 3: the four numbers maximise the mean over the 22 δ maps of the beam-smoothed (0.061″ at
   140 pc) image-plane recovery ``(2⟨S,T⟩ − ⟨T,T⟩)/⟨S,S⟩`` (capped at 1), by Nelder–Mead from a
   first fit to wakeflow alone; mean 0.81 over the wakeflow maps and 0.61 over FARGO3D's (the
   pulse it replaced, and why: ``CHANGELOG.md``, History of earlier versions). Wakeflow's negative part is a shallow
   background spread over the annulus. Within ``near_planet`` = 4/3 H_p of the planet (= 2l, where the Burgers
   solve starts) the amplitude factor ``1/g`` is held at its value there instead of falling to 0
   at r_p (g → ∞); 0.5, 0.8, 4/3, 2 and 3 H_p were tried (mean wakeflow recovery 0.74, 0.75, 0.77, 0.78, 0.78
   with the first pulse fit; FARGO3D's 1 M_th case falls beyond 4/3). Pure Burgers decay is kept:
   Cimerman & Rafikov (2021) find it over-damps far from the planet, but at x = 1.5–2 the
   generator's peak δΣ/Σ already equals wakeflow's (within 5 %, h0.05–0.10 × 0.1–1 M_th) and
   exceeds FARGO3D's (by 15–60 %, h0.07 × 0.3 and 1 M_th), so no slower decay was fitted.
   Solved numerically (MUSCL–Godunov, second order, periodic in η), so shocks form and the wave
   decays as an N-wave, ``δΣ/Σ ∝ β_p^{1/2} t^{-1/2}``; the shock front moves ahead of the linear
   ridge by ``∝ √(β_p t)``, which opens the spiral with mass. (Cimerman & Rafikov 2021 note that
   pure Burgers decay over-damps far from the planet.)
4. **Inner secondary arm** (Miranda & Rafikov 2019; Bae & Zhu 2018; separation from Fung & Dong
   2015, ``φ_sep ≈ 102° (q_p/10⁻³)^{0.2}``): a copy of the primary inner arm at ``φ_wake + φ_sep``
   (towards +φ for hand R, further along the winding: our FARGO3D run
   ``fargo3d_isothermal.h5:h0.07_mu1`` has its secondary arm 78–86° from the primary at
   x = 0.4–0.55, where Fung & Dong give 82°),
   switched on below ``x ≈ 0.75`` and fully on by ``x = 0.5``, for ``M_p ≳ M_th`` (weight rising
   from 0 at 0.3 M_th to 1 at 1 M_th). No outer secondary arm (Miranda & Rafikov 2019).
   **Off by default** (``secondary=False``): against that FARGO3D run (40 orbits)
   the copy, on either side, changes the beam-smoothed recovery little (τ0 = 0.3: 0.36 without,
   0.33 with it at +φ_sep, 0.31 at −φ_sep; τ0 = 3: 0.54 in all three), FARGO3D's secondary arm
   being twice the primary's amplitude at x ≈ 0.5 where the copy has the primary's, and
   wakeflow has no secondary arm (its mean recovery drops from 0.81 to 0.79 with the copy).
5. **Gap** (Kanagawa et al. 2016, PASJ 68, 43; 2015 ApJL 806 L15): depth
   ``Σ_min/Σ_0 = 1/(1 + 0.04 K)``, ``K = q_p² h_p⁻⁵ α⁻¹``, full width
   ``Δ = 0.41 r_p (q_p² h_p⁻³ α⁻¹)^{1/4}``, with α = 10⁻² by default (**fitted**:
   the gap of ``fargo3d_isothermal.h5:h0.07_mu1`` after 40 orbits has Σ_min/Σ_0 = 0.78 at
   x = 1.11, which α = 10⁻² gives, 0.78; α = 10⁻³ gives 0.26 — the
   equilibrium of a much older disc — and cut the τ0 = 3, 1 M_th recovery against FARGO3D from
   0.51 to 0.03; the run's own ν is α = 2 × 10⁻⁴, so this α is an effective "gap age"); shape
   ``1 − (1 − depth) 2^{−(|x − 1|/(Δ/2))⁴}``. The gap enters through the optical depth only
   (δ is relative to the azimuthal mean).
6. **Brightness** (S22; :mod:`.radiative`): ``T = T_0(r) (Σ/Σ_0)^{(γ−1) f_β}`` (linearised:
   ``δT/T = (γ−1) f_β δΣ/Σ``; compression heating, absent for β = 0),
   ``τ = τ0 x^{-p} G_gap(x) (1 + δΣ/Σ)``, ``I = B_ν(T)(1 − e^{−τ})``, ``δ = I/<I>_φ − 1``.
   Dust follows gas (Stokes number ≲ 0.1; Sturm et al. 2020).
7. Hand L is the mirror image ``φ → −φ``.

The wake map depends only on (mass, β) and the disc settings, so it is cached and shared by all
τ0 and both hands.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from ..settings import DEFAULT_MSTAR_MSUN
from ..units import TWO_PI, wrap_angle
from .burgers import solve_burgers
from .template import check_mass_beta, validate_hand

__all__ = [
    "GENERATOR_VERSION",
    "WakeSettings",
    "PAPER_MASSES",
    "PAPER_TAUS",
    "PAPER_BETAS",
    "wake_shape",
    "wake_phase",
    "wave_time",
    "g_factor",
    "cooling_response",
    "gap_profile",
    "linear_profile",
    "surface_density_perturbation",
    "periodic_interp",
]

log = logging.getLogger(__name__)

GENERATOR_VERSION = 2
"""Bumped whenever the generator's output changes (it invalidates cached banks)."""

PAPER_MASSES = (0.1, 0.3, 1.0, 3.0)
"""Planet masses of the paper's grid [M_th] (Stevenson et al. 2024, sec. 2.3)."""
PAPER_TAUS = (0.1, 0.3, 1.0, 3.0)
"""Initial optical depths at r_p of the paper's grid."""
PAPER_BETAS = (0.0, 10.0)
"""Cooling times of the paper's grid (0 = isothermal)."""

_N_FINE = 4001  # points per side for the radial quadratures


@dataclass(frozen=True)
class WakeSettings:
    """Disc, grid and model settings of the built-in generator (all hashable).

    Parameters
    ----------
    h_p : float
        ``H/r`` at the planet (S22: 0.07).
    flaring : float
        ``H/r ∝ r**flaring`` (S22: 0.25, so ``c_s ∝ r^{-1/4}``, ``T ∝ r^{-1/2}``).
    sigma_slope : float
        ``p`` in ``Σ ∝ r^{-p}`` (S22: 1).
    gamma : float
        Adiabatic index (1.4).
    alpha : float
        Shakura–Sunyaev viscosity for the gap depth/width (Kanagawa et al. 2016); 1e-2, fitted
        to the gap of the FARGO3D reference ``h0.07_mu1`` at 40 orbits (module docstring, step 5).
    mstar : float
        Stellar mass [M_sun] for the temperature scale (0.8).
    r_p_au : float
        Planet radius [au] for the temperature scale (S22: 50 au → T_p = 19.7 K).
    mu : float
        Mean molecular weight (2.34).
    wavelength : float
        Observing wavelength [m] (0.87e-3, ALMA Band 7).
    n_x, n_phi : int
        Grid: ``n_x`` log-spaced radii (cell centres) in ``[x_min, x_max]``; ``n_phi`` azimuths
        ``2πk/n_phi`` (a multiple of 90 keeps the scan's azimuth shifts exact).
    x_min, x_max : float
        Radial extent in ``r/r_p`` (edges of the first and last cells); the paper's truncated
        domain is 0.2–2.2.
    profile_amp, profile_width : float
        Peak (0.4) and Gaussian width in η (0.95) of the linear wake profile Λ for ``M_p = M_1``.
    lobe_offset, lobe_width : float
        Centre (−0.5) and width (11.5) of Λ's negative lobe, in units of ``profile_width``. All four
        fitted to the reference maps (module docstring, step 3).
    near_planet : float
        Within this many ``H_p`` of the planet the wake amplitude is held at its value there
        (4/3: the start of the Burgers solve; fitted to wakeflow, step 3).
    m_eff_factor : float
        ``m_eff h_p`` in the cooling frequency ``ω = m_eff |Ω − Ω_p|`` (0.5–1; default 0.5).
    secondary, gap, nonlinear : bool
        Include the inner secondary arm (default False, see step 4) / the gap / Burgers evolution
        (False: linear profile).
    n_eta : int
        Points of the periodic Burgers grid in η (length ``3π/h_p``).
    cfl : float
        Courant number of the Burgers solver.
    """

    h_p: float = 0.07
    flaring: float = 0.25
    sigma_slope: float = 1.0
    gamma: float = 1.4
    alpha: float = 1e-2
    mstar: float = DEFAULT_MSTAR_MSUN
    r_p_au: float = 50.0
    mu: float = 2.34
    wavelength: float = 0.87e-3
    n_x: int = 320
    n_phi: int = 720
    x_min: float = 0.2
    x_max: float = 2.2
    profile_amp: float = 0.4
    profile_width: float = 0.95
    lobe_offset: float = -0.5
    lobe_width: float = 11.5
    m_eff_factor: float = 0.5
    near_planet: float = 4.0 / 3.0
    secondary: bool = False
    gap: bool = True
    nonlinear: bool = True
    n_eta: int = 2048
    cfl: float = 0.8

    def __post_init__(self):
        checks = {
            "h_p": 0 < self.h_p < 1,
            "flaring": -0.5 < self.flaring < 1.5,
            "gamma": self.gamma >= 1,
            "alpha": self.alpha > 0,
            "mstar": self.mstar > 0,
            "r_p_au": self.r_p_au > 0,
            "mu": self.mu > 0,
            "wavelength": self.wavelength > 0,
            "n_x": int(self.n_x) >= 4,
            "n_phi": int(self.n_phi) >= 8,
            "x_min": 0 < self.x_min < 1,
            "x_max": self.x_max > 1,
            "profile_amp": self.profile_amp >= 0,
            "profile_width": self.profile_width > 0,
            "lobe_width": self.lobe_width > 0,
            "m_eff_factor": self.m_eff_factor > 0,
            "near_planet": self.near_planet >= 0,
            "n_eta": int(self.n_eta) >= 64,
            "cfl": 0 < self.cfl <= 1,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            values = {k: getattr(self, k) for k in bad}
            raise InputError(f"invalid WakeSettings {values}: see the WakeSettings docstring for ranges")
        object.__setattr__(self, "n_x", int(self.n_x))
        object.__setattr__(self, "n_phi", int(self.n_phi))
        object.__setattr__(self, "n_eta", int(self.n_eta))

    @property
    def q(self) -> float:
        """Sound-speed slope: ``c_s ∝ r^{-q}``, ``q = 1/2 − flaring``."""
        return 0.5 - self.flaring

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x, phi)``: log-spaced radial cell centres and uniform azimuths ``2πk/n_phi``."""
        edges = np.geomspace(self.x_min, self.x_max, self.n_x + 1)
        x = np.sqrt(edges[1:] * edges[:-1])
        phi = TWO_PI * np.arange(self.n_phi) / self.n_phi
        return x, phi

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def key(self) -> str:
        """Short hash of the settings and :data:`.GENERATOR_VERSION` (cache key)."""
        blob = json.dumps({"v": GENERATOR_VERSION, **self.to_dict()}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


# ---------------------------------------------------------------------------- wake geometry
def _pow_minus_one_over(x, a):
    """``(x**a − 1)/a``, → ``ln x`` as ``a → 0``."""
    if abs(a) < 1e-12:
        return np.log(x)
    return (x**a - 1.0) / a


def wake_shape(x, h_p: float = 0.07, flaring: float = 0.25, hand: str = "R") -> np.ndarray:
    """Closed-form linear wake ridge ``φ_wake(x)`` [rad] (planet at φ = 0), isothermal waves.

    Rafikov (2002, eq. 44); Ogilvie & Lubow (2002); Muto et al. (2012), for ``c_s ∝ r^{-q}``,
    ``q = 1/2 − flaring``:

    ``φ_wake = s sgn(x − 1) B(x)/h_p``,
    ``B(x) = (x^{q−1/2} − 1)/(q − 1/2) − (x^{q+1} − 1)/(q + 1) ≤ 0``,

    with ``s = +1`` for hand R (anticlockwise orbit, trailing arms: ``φ_wake < 0`` outside the
    planet, ``> 0`` inside) and ``s = −1`` for L. Not wrapped into [0, 2π).
    E.g. ``h_p = 0.07, q = 1/4``: +28° at x = 0.8, +240° at 0.5, −117° at 1.5.
    """
    s = 1.0 if validate_hand(hand) == "R" else -1.0
    x = np.asarray(x, dtype=float)
    q = 0.5 - flaring
    B = _pow_minus_one_over(x, q - 0.5) - _pow_minus_one_over(x, q + 1.0)
    return s * np.sign(x - 1.0) * B / h_p


def _cumulative_from_one(integrand, x_targets, x_lo, x_hi):
    """``∫_1^x integrand(s) ds`` at ``x_targets`` (trapezoid on fine grids either side of 1)."""
    x_targets = np.asarray(x_targets, dtype=float)
    out = np.zeros_like(x_targets)
    for end in (min(x_lo, x_targets.min(initial=1.0)), max(x_hi, x_targets.max(initial=1.0))):
        if end == 1.0:
            continue
        s = np.linspace(1.0, end, _N_FINE)
        f = integrand(s)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(s))])
        sel = (x_targets < 1.0) if end < 1.0 else (x_targets > 1.0)
        if end < 1.0:  # np.interp needs increasing abscissae
            out[sel] = np.interp(x_targets[sel], s[::-1], cum[::-1])
        else:
            out[sel] = np.interp(x_targets[sel], s, cum)
    return out


def cooling_response(x, beta: float, h_p: float, gamma: float = 1.4, m_eff_factor: float = 0.5):
    """``(ω t_c, γ_eff, f_β)`` at ``x = r/r_p`` for thermal relaxation ``t_c = β/Ω``.

    Miranda & Rafikov (2020a); Zhang & Zhu (2020): ``ω ≈ m_eff |Ω − Ω_p|``,
    ``m_eff = m_eff_factor/h_p``, so ``ω t_c = β m_eff |1 − x^{3/2}|``;
    ``γ_eff = (1 + γ ω²t_c²)/(1 + ω²t_c²)``; ``f_β = ω t_c/√(1 + ω²t_c²)``, the magnitude of the
    temperature response ``δT/T = (γ − 1) [iωt_c/(1 + iωt_c)] δΣ/Σ``. β = 0: isothermal
    (γ_eff = 1, f_β = 0).
    """
    x = np.asarray(x, dtype=float)
    wt = beta * (m_eff_factor / h_p) * np.abs(1.0 - x**1.5)
    gamma_eff = (1.0 + gamma * wt**2) / (1.0 + wt**2)
    f_beta = wt / np.sqrt(1.0 + wt**2)
    return wt, gamma_eff, f_beta


def _gamma_eff_fn(beta, st: WakeSettings):
    if beta <= 0:
        return lambda s: np.ones_like(s)
    return lambda s: cooling_response(s, beta, st.h_p, st.gamma, st.m_eff_factor)[1]


def wake_phase(x, beta: float = 0.0, settings: WakeSettings | None = None) -> np.ndarray:
    """Wake ridge ``φ_wake(x)`` [rad] for hand R with the cooling-dependent sound speed.

    Integrates ``dφ/dx = −|x^{-3/2} − 1| x^{q} / (h_p √γ_eff(x))`` from the planet (Rafikov 2002
    with ``c_s → √γ_eff c_s``; Miranda & Rafikov 2020a). For β = 0 it equals :func:`wake_shape`.
    """
    st = settings or WakeSettings()
    q = st.q
    geff = _gamma_eff_fn(beta, st)

    def integrand(s):
        return np.abs(s**-1.5 - 1.0) * s**q / np.sqrt(geff(s))

    return -_cumulative_from_one(integrand, x, st.x_min, st.x_max) / st.h_p


def wave_time(x, beta: float = 0.0, settings: WakeSettings | None = None) -> np.ndarray:
    """Wave "time" ``t(x)`` of the Burgers problem (Goodman & Rafikov 2001; Rafikov 2002, eq. 29):

    ``t = (3/2^{5/4}) h_p^{-5/2} |∫_1^x |1 − s^{3/2}|^{3/2} s^{(5q+p)/2 − 11/4} γ_eff^{-5/4} ds|``

    (``h_p → √γ_eff h_p`` for non-isothermal waves). For h_p = 0.07, q = 1/4, p = 1, β = 0:
    t ≈ 48 at x = 0.7, 232 at 0.5, 28 at 1.3, 88 at 1.5, 382 at 2.
    """
    st = settings or WakeSettings()
    q, p = st.q, st.sigma_slope
    geff = _gamma_eff_fn(beta, st)
    expo = (5.0 * q + p) / 2.0 - 11.0 / 4.0

    def integrand(s):
        return np.abs(1.0 - s**1.5) ** 1.5 * s**expo * geff(s) ** -1.25

    cum = _cumulative_from_one(integrand, x, st.x_min, st.x_max)
    return 3.0 / 2.0**1.25 * st.h_p**-2.5 * np.abs(cum)


def g_factor(x, beta: float = 0.0, settings: WakeSettings | None = None) -> np.ndarray:
    """Amplitude conversion ``g(x) = 2^{1/4} (γ_eff^{1/2} h_p)^{1/2} x^{(1−p−3q)/2} |x^{-3/2} − 1|^{-1/2}``
    (Rafikov 2002, eq. 30; Bollati et al. 2021): ``δΣ/Σ = 2χ/((γ + 1) g)``. Infinite at x = 1."""
    st = settings or WakeSettings()
    x = np.asarray(x, dtype=float)
    geff = _gamma_eff_fn(beta, st)(x)
    with np.errstate(divide="ignore"):
        return (
            2.0**0.25 * np.sqrt(st.h_p * np.sqrt(geff)) * x ** ((1.0 - st.sigma_slope - 3.0 * st.q) / 2.0)
            * np.abs(x**-1.5 - 1.0) ** -0.5
        )


def gap_profile(x, mass: float, settings: WakeSettings | None = None) -> np.ndarray:
    """Gap ``Σ/Σ_0`` from Kanagawa et al. (2016): depth ``1/(1 + 0.04K)``, ``K = q_p² h_p⁻⁵ α⁻¹``;
    full width ``Δ = 0.41 r_p (q_p² h_p⁻³ α⁻¹)^{1/4}``; ``q_p = M_p/M_* = mass h_p³``.
    Profile ``1 − (1 − depth) 2^{−(|x−1|/(Δ/2))⁴}`` (half the depth at ``|x − 1| = Δ/2``)."""
    st = settings or WakeSettings()
    x = np.asarray(x, dtype=float)
    qp = mass * st.h_p**3
    K = qp**2 * st.h_p**-5 / st.alpha
    depth = 1.0 / (1.0 + 0.04 * K)
    width = 0.41 * (qp**2 * st.h_p**-3 / st.alpha) ** 0.25
    if width <= 0:
        return np.ones_like(x)
    return 1.0 - (1.0 - depth) * 2.0 ** (-((np.abs(x - 1.0) / (0.5 * width)) ** 4))


def linear_profile(eta, amp: float = 0.5, width: float = 0.8, lobe_offset: float = -2.5,
                   lobe_width: float = 1.5) -> np.ndarray:
    """Model of the linear wake profile Λ(η) for ``M_p = M_1`` (zero mean).

    A positive Gaussian of peak ``amp`` and width ``width`` centred on η = 0 (the linear ridge)
    plus a negative lobe (Gaussian of width ``lobe_width · width`` centred at
    ``lobe_offset · width``) of equal area, after the shape of the linear solutions of Goodman &
    Rafikov (2001, Fig. 1) and Rafikov (2002). Positive η is the side the wave propagates towards
    (where the shock forms). The defaults of :class:`WakeSettings` (0.4, 0.95, −0.5, 11.5) are
    fitted to the reference maps (module docstring, step 3); these arguments' defaults are the
    first version's narrow-lobe shape (``CHANGELOG.md``, History of earlier versions).
    """
    eta = np.asarray(eta, dtype=float)
    w2 = lobe_width * width
    pos = np.exp(-0.5 * (eta / width) ** 2)
    neg = (width / w2) * np.exp(-0.5 * ((eta - lobe_offset * width) / w2) ** 2)
    return amp * (pos - neg)


# ---------------------------------------------------------------------------- the wake map
def periodic_interp(table: np.ndarray, rows: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``table[rows[i], ·]`` at fractional periodic indices ``pos[i, j]``.

    Parameters
    ----------
    table : (n_rows, n) array
        Rows periodic in their second index.
    rows : (m,) int array
        Which row of ``table`` each output row reads.
    pos : (m, k) array
        Fractional indices along the period (any real value; wrapped modulo ``n``).

    Returns
    -------
    (m, k) array
    """
    n = table.shape[1]
    j0f = np.floor(pos)
    w = pos - j0f
    j0 = j0f.astype(np.int64) % n
    j1 = (j0 + 1) % n
    r = rows[:, None]
    return (1.0 - w) * table[r, j0] + w * table[r, j1]


@functools.lru_cache(maxsize=16)
def _cached_perturbation(mass: float, beta: float, st: WakeSettings):
    x, phi = st.grid()
    dsig = _primary_and_secondary(x, phi, mass, beta, st)
    dsig.setflags(write=False)
    return dsig


def surface_density_perturbation(mass: float, beta: float, settings: WakeSettings | None = None) -> np.ndarray:
    """``δΣ/Σ(x, φ)`` of the planet wake (hand R) on ``settings.grid()``, shape ``(n_x, n_phi)``.

    See the module docstring (steps 1–4); the gap is *not* included (see :func:`gap_profile`).
    The result is cached and read-only.
    """
    st = settings or WakeSettings()
    check_mass_beta(mass, beta)
    return _cached_perturbation(float(mass), float(beta), st)


def _primary_and_secondary(x, phi, mass, beta, st: WakeSettings) -> np.ndarray:
    h = st.h_p
    beta_p = 1.5 * mass  # M_p / M_1, M_1 = (2/3) h_p^3 M_* (Goodman & Rafikov 2001)
    # Burgers nonlinearity (gamma + 1): gamma_eff where |1 - x^{3/2}| = 1/2
    gamma_B = float(cooling_response(0.5 ** (2.0 / 3.0), beta, h, st.gamma, st.m_eff_factor)[1])
    phi_w = wake_phase(x, beta, st)
    t = wave_time(x, beta, st)
    g = g_factor(x, beta, st)
    if st.near_planet > 0:  # hold the amplitude within near_planet H_p of the planet (step 3)
        d = st.near_planet * h
        g_in, g_out = g_factor(np.array([1.0 - d, 1.0 + d]), beta, st)
        g = np.where(np.abs(x - 1.0) < d, np.where(x < 1.0, g_in, g_out), g)
    dx_start = 4.0 / 3.0 * h  # 2 l, l = (2/3) H_p (Bollati et al. 2021)
    t0_in, t0_out = wave_time(np.array([1.0 - dx_start, 1.0 + dx_start]), beta, st)
    t0 = np.where(x < 1.0, t0_in, t0_out)
    tau = np.clip(t - t0, 0.0, None) if st.nonlinear else np.zeros_like(t)

    L = 3.0 * np.pi / h  # η period: (3/(2h)) * 2π
    n_eta = st.n_eta
    d_eta = L / n_eta
    eta = -0.5 * L + d_eta * np.arange(n_eta)
    lam = linear_profile(eta, st.profile_amp, st.profile_width, st.lobe_offset, st.lobe_width)
    lam -= lam.mean()  # zero mean on the period, also when a wide lobe is cut by it
    chi0 = (gamma_B + 1.0) * beta_p * lam / 2.0**0.75
    chi = solve_burgers(chi0, d_eta, tau, st.cfl)  # row i ↔ radius i
    side = np.where(x < 1.0, -1.0, 1.0)
    scale = 2.0 / ((gamma_B + 1.0) * g)
    rows = np.arange(x.size)

    def primary(phis, sel=slice(None)):
        d = wrap_angle(phis[None, :] - phi_w[sel, None])
        pos = (side[sel, None] * (1.5 / h) * d + 0.5 * L) / d_eta
        return scale[sel, None] * periodic_interp(chi, rows[sel], pos)

    dsig = primary(phi)
    if st.secondary:
        w_mass = np.clip(np.log10(mass / 0.3) / np.log10(1.0 / 0.3), 0.0, 1.0)
        if w_mass > 0:
            s = np.clip((0.75 - x) / 0.25, 0.0, 1.0)
            w_x = s * s * (3.0 - 2.0 * s)  # smoothstep from x = 0.75 to 0.5
            sel = np.nonzero(w_x > 0)[0]
            if sel.size:
                qp = mass * h**3
                phi_sep = np.radians(102.0) * (qp / 1e-3) ** 0.2  # Fung & Dong (2015)
                dsig[sel] += (w_mass * w_x[sel])[:, None] * primary(phi - phi_sep, sel)
    return dsig
