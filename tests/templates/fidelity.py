"""Template fidelity against the committed reference maps (issue 9): shared by the tests and by
``python benchmarks/bench_templates.py --fidelity``.

Reference cases: every group of ``tests/data/references/*.h5`` (wakeflow 1.4.0: H/r ∈ {0.05, 0.07,
0.10} × M_p ∈ {0.1, 0.3, 1} M_th; FARGO3D: H/r = 0.07 × M_p ∈ {0.3, 1} M_th; see tools/README.md).
For each case and τ0 ∈ {0.3, 3} the reference δ map becomes a :class:`SpiralTemplate` and is
compared with the built-in generator's template at the same (M_p, H/r, τ0), β = 0, hand R:

* map level (cheap): area- and brightness-weighted normalised cross-correlation of the two δ maps
  and the ratio of their RMS (generator / reference), over the fiducial disc's extent;
* observation level (the issue's criteria): the reference spiral is injected into the fiducial
  synthetic observation (planet at 50 au, 140 pc) face-on or at 30° inclination (no noise and
  the true axisymmetric disc by default: expectation values; see :func:`observe_and_scan`), and
  :func:`spiralbayes.inference.scan.run.scan` scans the reference template and the generator's templates
  of every bank mass near the truth (5 radii one paper grid step apart, the full 90 azimuths).
  Recovery = generator's Δχ² at the truth / reference's Δχ² at the truth;
  position error of the true-mass template's best fit; best mass = the bank mass with the
  highest peak Δχ².
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from spiralbayes.simulate import DiscModel

VERSION1 = dict(profile_amp=0.5, profile_width=0.8, lobe_offset=-2.5, lobe_width=1.5, alpha=1e-3,
                secondary=True, near_planet=0.0)
"""Generator options that reproduce GENERATOR_VERSION 1 (before the issue-9 calibration), but
for the side of the optional secondary arm (φ_wake − φ_sep in version 1, + since), which changes
the 1 M_th maps inside 0.75 r_p only; the issue-9 report's "before" table ran version 1 itself."""

REF_DIR = Path(__file__).resolve().parents[1] / "data" / "references"
PHYSICS_FILE = REF_DIR / "physics" / "fargo3d_library.h5"
"""The ``physics`` run set (another surface-density slope or viscosity, masses and H/r between the
bank's, a longer run), reduced beside the library: references of disc physics the library holds fixed,
kept out of the library's file (and so out of the variant fit)."""
SOURCE_LABELS = {"fargo3d_library": "fargo3dlib"}
"""Case-label source of a file (default: its name up to the first '_'); the issue-21 library
(``fargo3d_library.h5``) gets its own so that its labels differ from ``fargo3d_isothermal.h5``'s."""
TAUS = (0.3, 3.0)
BANK_MASSES = (0.1, 0.3, 1.0, 3.0)
DISTANCE = 140.0  # pc
R_P_AU = 50.0
RP_STEP = 0.02  # arcsec: the paper's r_p grid step (25 radii from 0.02 to 0.5 arcsec)
X_RANGE = (10.0 / R_P_AU, 110.0 / R_P_AU)  # the fiducial disc (10-110 au) in r/r_p


@dataclass(frozen=True)
class Case:
    """One reference map: file, group, source, ``h_p`` and ``mu = M_p/M_th``."""

    file: str
    group: str
    source: str
    h_p: float
    mu: float
    beta: float = 0.0
    role: str = "library"
    run_state: str = "finished"
    taus: tuple = TAUS
    batch: str = ""
    change_5_orbits: float = 0.0

    @property
    def label(self) -> str:
        return f"{self.source}:{self.group}"

    @property
    def is_reference(self) -> bool:
        """A reference of the variant fit and acceptance (issue 22): a finished run of the library's
        own role or of its long evolution (``orbits200``: the 1 and 3 M_th planets after 200 orbits
        instead of 20 — the same physics later, closer to the paper's 1500-orbit templates; the two
        times disagree, docs/templates.md, and the variants must hold for both). Not: checks of one
        numerical setting (``soft0.35``, ``res14``: the library groups' ``variant`` attribute), runs
        stored before their planned orbits (``run_state = running``) and maps that are not a
        quasi-steady spiral: RMS change of δΣ/Σ over the last 5 orbits above :data:`MAX_CHANGE`
        (the library's ``steadiness``). The fidelity report still shows them."""
        return ((self.role in REFERENCE_ROLES or self.role.startswith(PHYSICS_ROLES))
                and not self.run_state.startswith("running")
                and self.change_5_orbits <= MAX_CHANGE)


REFERENCE_ROLES = ("library", "orbits200")
"""Library roles whose finished runs are references (:attr:`Case.is_reference`)."""
PHYSICS_ROLES = ("slope", "nu", "orbits500")
"""Role prefixes of the ``physics`` run set (another surface-density slope or viscosity, a longer run):
references too, of disc physics the rest of the library holds fixed."""
MAX_CHANGE = 0.5
"""Largest RMS change of a reference's δΣ/Σ over its last 5 orbits. The library's runs change by
0.1-7 % (3 M_th: 27 % at H/r 0.07 after 20 orbits, 12 % after 200); the H/r 0.10 3 M_th run by
93 %: vortices at its gap edges dominate the map (NCC with every template <= 0.23,
docs/templates.md), a transient no spiral template stands for — test 3's asymmetry models are
what such a disc meets (docs/limits.md §4d)."""


def reference_cases(files=None) -> list[Case]:
    """Every case of every committed reference file, wakeflow first; or of the reduced reference
    ``files`` given (paths, e.g. runs reduced outside the repository with ``--out``)."""
    import h5py

    cases = []
    paths = sorted(REF_DIR.glob("*.h5"), reverse=True) if files is None else [Path(p).resolve() for p in files]
    for path in paths:  # committed: wakeflow_, then fargo3d_
        with h5py.File(path, "r") as f:
            source = SOURCE_LABELS.get(path.stem, path.stem.split("_")[0])
            for g in sorted(f):
                if isinstance(f[g], h5py.Group):
                    a = f[g].attrs
                    taus = tuple(sorted(float(k.removeprefix("delta_tau")) for k in f[g] if k.startswith("delta_tau")))
                    cases.append(Case(path.name if path.parent == REF_DIR.resolve() else str(path), g, source,
                                      float(a["h_p"]), float(a["mu_Mth"]),
                                      float(a.get("beta", 0.0)), _role(g),
                                      str(a.get("run_state", "finished")), taus, str(a.get("batch", "")),
                                      _last_change(a)))
    return cases


def _last_change(attrs) -> float:
    """RMS relative change of δΣ/Σ over the last 5 orbits (the library's ``steadiness``; 0 without): the
    rule the learned model trains by, so that the references and its training runs agree."""
    from spiralbayes.templates.learned.training import _last_change as steadiness_rule

    return steadiness_rule(attrs)


def _role(group: str) -> str:
    """The library's role of a group from its name (tools/fargo3d_library_cases.py: ``h<h>_mu<m>``,
    then ``_beta<b>`` / ``_st<St>`` for the physics, then ``_<role>`` for a check of one setting)."""
    extra = [t for t in group.split("_")[2:] if not (t.startswith("beta") or t.startswith("st"))]
    return "_".join(extra) or "library"


def physics_cases() -> list[Case]:
    """The reference cases of the ``physics`` run set (:data:`PHYSICS_FILE`): planted by the checks,
    never fitted by the variants."""
    return [c for c in reference_cases([PHYSICS_FILE]) if c.is_reference]


def acceptance_cases() -> list[Case]:
    """The reference cases of the variant fit and its acceptance (:attr:`Case.is_reference`)."""
    return [c for c in reference_cases() if c.is_reference]


@lru_cache(maxsize=64)
def reference_template(case: Case, tau0: float):
    """The reference δ map for ``tau0`` as a right-handed :class:`SpiralTemplate`."""
    import h5py

    from spiralbayes.templates import SpiralTemplate

    with h5py.File(REF_DIR / case.file, "r") as f:
        x, phi = f["x"][()], f["phi"][()]
        delta = f[f"{case.group}/delta_tau{tau0:g}"][()].astype(float)
    return SpiralTemplate(x=x, phi=phi, delta=delta, mass=case.mu, tau0=tau0, beta=case.beta, h_p=case.h_p,
                          name=f"ref_{case.source}_{case.group}_tau{tau0:g}",
                          provenance={"reference": f"tests/data/references/{case.file}:{case.group}"})


def generator_template(mass: float, tau0: float, h_p: float, beta: float = 0.0, **options):
    """The built-in generator's template (hand R) at these parameters (β = 0: isothermal)."""
    from spiralbayes.templates import make_template

    return make_template(mass, tau0, beta, "R", h_p=h_p, **options)


# ------------------------------------------------------------------------------- map level
def _weights(x: np.ndarray, tau0: float) -> np.ndarray:
    """Per-radius weight ``x² dln x · I_axi(x)²`` inside the fiducial disc: the visibilities see
    δ·I_axi over the disc area. I_axi ∝ x^{-1/2}(1 − e^{-τ0/x}) (T ∝ r^{-1/2}, Σ ∝ r^{-1},
    Rayleigh–Jeans is enough for a weight)."""
    inside = (x >= X_RANGE[0]) & (x <= X_RANGE[1])
    intensity = x**-0.5 * (1.0 - np.exp(-tau0 / x))
    return np.where(inside, x**2 * intensity**2, 0.0)


def map_metrics(ref, gen) -> dict:
    """Normalised cross-correlation and RMS ratio (gen / ref) of two templates on ref's grid."""
    X, P = np.meshgrid(ref.x, ref.phi, indexing="ij")
    a = ref.delta.astype(float)
    b = gen.evaluate(X, P, r_p=1.0)
    w = _weights(ref.x, ref.tau0)[:, None]
    saa, sbb, sab = np.sum(w * a * a), np.sum(w * b * b), np.sum(w * a * b)
    return {"ncc": float(sab / np.sqrt(saa * sbb)), "rms_ratio": float(np.sqrt(sbb / saa)),
            "proxy_recovery": float((2 * sab - sbb) / saa)}


BEAM_FWHM = 0.061 * DISTANCE / R_P_AU  # the fiducial beam (0.061 arcsec) in r/r_p


@lru_cache(maxsize=1)
def _image_grid(n: int = 200, half: float = 2.3):
    ax = np.linspace(-half, half, n)
    X, Y = np.meshgrid(ax, ax, indexing="ij")
    k = np.fft.fftfreq(n, ax[1] - ax[0])
    KX, KY = np.meshgrid(k, k, indexing="ij")
    sigma = BEAM_FWHM / np.sqrt(8.0 * np.log(2.0))
    return np.hypot(X, Y), np.arctan2(Y, X), np.exp(-2.0 * np.pi**2 * sigma**2 * (KX**2 + KY**2))


def smoothed_image(template, tau0: float) -> np.ndarray:
    """Face-on image of ``δ · I_axi`` (planet at (1, 0), fiducial disc extent) convolved with the
    fiducial beam: what the visibilities see of a template, up to the uv weighting."""
    R, PH, beam = _image_grid()
    inside = (X_RANGE[0] <= R) & (X_RANGE[1] >= R)
    intensity = np.where(inside, np.maximum(R, 1e-3) ** -0.5 * (1.0 - np.exp(-tau0 / np.maximum(R, 1e-3))), 0.0)
    img = template.evaluate(R, PH, r_p=1.0) * intensity
    return np.real(np.fft.ifft2(np.fft.fft2(img) * beam))


def beam_metrics(ref, gen) -> dict:
    """Beam-smoothed image-plane metrics: ``beam_ncc``, ``beam_rms_ratio`` (gen / ref) and
    ``beam_recovery`` = (2⟨S,T⟩ − ⟨T,T⟩)/⟨S,S⟩, the recovery an observation with uniform uv
    weights and a Gaussian beam would give (the calibration's objective)."""
    a, b = smoothed_image(ref, ref.tau0), smoothed_image(gen, ref.tau0)
    saa, sbb, sab = np.sum(a * a), np.sum(b * b), np.sum(a * b)
    return {"beam_ncc": float(sab / np.sqrt(saa * sbb)), "beam_rms_ratio": float(np.sqrt(sbb / saa)),
            "beam_recovery": float((2 * sab - sbb) / saa)}


# ------------------------------------------------------------------------------- scan level
@lru_cache(maxsize=2)
def _coverage():
    from spiralbayes.simulate.presets import get_preset

    return get_preset("fiducial").coverage()


def run_gap(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """The run's azimuthally averaged surface density over its initial one, ``(x, ⟨Σ⟩_φ / Σ_init)``
    (the planet's gap and its edges; 1 where the reference file marks the map invalid). FARGO3D:
    ``sigma_axisym`` (normalised at r_p) times ``x^p_sigma``; wakeflow: ``1 + mean_offset``."""
    import h5py

    with h5py.File(REF_DIR / case.file, "r") as f:
        g = f[case.group]
        x = f["x"][()]
        valid = g["valid"][()].astype(bool) if "valid" in g else np.ones(x.size, bool)
        if "sigma_axisym" in g:
            ratio = g["sigma_axisym"][()] * x ** float(g.attrs.get("p_sigma", 1.0))
        elif "mean_offset" in g:
            ratio = 1.0 + g["mean_offset"][()]
        else:
            ratio = np.ones(x.size)
    return x, np.where(valid, ratio, 1.0)


@dataclass(frozen=True)
class GappedDisc(DiscModel):
    """The planting's power-law disc with a planet's gap: the optical depth times ``⟨Σ⟩_φ / Σ_init``
    at ``r / r_p`` (:func:`run_gap`), through the same isothermal transfer, so that the planted
    perturbation ``I (1 + δ)`` multiplies the run's own azimuthal mean, as δ = I/⟨I⟩_φ − 1 is defined."""

    gap_x: tuple = ()
    gap_ratio: tuple = ()

    def optical_depth(self, x) -> np.ndarray:
        return super().optical_depth(x) * np.interp(x, self.gap_x, self.gap_ratio, left=1.0, right=1.0)


def planting_disc(case: Case, tau0: float, gap: bool = True) -> DiscModel:
    """The fiducial power-law disc (τ0 at the planet's 50 au), holding ``case``'s gap if ``gap``."""
    if not gap:
        return DiscModel(distance=DISTANCE, r_ref=R_P_AU, tau_ref=tau0)
    x, ratio = run_gap(case)
    return GappedDisc(distance=DISTANCE, r_ref=R_P_AU, tau_ref=tau0, gap_x=tuple(x), gap_ratio=tuple(ratio))


def observe_and_scan(ref, templates, tau0: float, inc: float, phi_p_deg: float, seed: int = 1, n_rp: int = 5,
                     noise: bool = False, frank: bool = False, disc=None):
    """Inject ``ref`` at (50 au, ``phi_p_deg``) into the fiducial observation and scan
    ``[ref] + templates`` over ``n_rp`` radii centred on the truth (paper step) and 90 azimuths.

    By default the observation has no thermal noise (the weights are still the fiducial
    set-up's) and the scan uses the true axisymmetric disc: the Δχ² are then their expectation
    values and measure the template alone, not one noise draw nor frank's residuals (at the
    fiducial sensitivity a 0.1 M_th reference gives Δχ² ≈ 2, where either would dominate).
    ``noise=True`` adds the preset's noise (``seed``); ``frank=True`` fits frank instead. ``disc``:
    the disc planted and modelled (default: the power-law disc with τ0 at the planet; a
    :class:`GappedDisc` holds the reference run's own gap).

    Returns ``(result, i_rp, i_phi)``: the :class:`ScanResult` and the truth's grid indices.
    """
    from spiralbayes import DiscGeometry
    from spiralbayes.axisymmetric import fit_axisymmetric
    from spiralbayes.inference.scan.run import scan
    from spiralbayes.simulate import simulate_observation

    geometry = DiscGeometry(inc, 60.0)
    r_true = R_P_AU / DISTANCE
    phi_true = np.radians(phi_p_deg)
    disc = DiscModel(distance=DISTANCE, r_ref=R_P_AU, tau_ref=tau0) if disc is None else disc
    cov = _coverage()
    vis = simulate_observation("fiducial", disc, geometry, ref, r_p=r_true, phi_p=phi_true, seed=seed,
                               coverage=cov, add_noise=noise)
    half = n_rp // 2
    r_p = r_true + RP_STEP * np.arange(-half, half + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free data: chi2 far below 2N is expected
        if frank:
            axisym = fit_axisymmetric(vis, geometry, progress=False)
        else:
            smooth = simulate_observation("fiducial", disc, geometry, coverage=cov, add_noise=False)
            axisym = (disc.profile(cov.wavelength), smooth.V)
        result = scan(vis, axisym, [ref, *templates], geometry, r_p=r_p, progress=False)
    i_phi = int(np.argmin(np.abs(np.angle(np.exp(1j * (result.phi_p - phi_true))))))
    return result, half, i_phi


def scan_metrics(result, i_rp: int, i_phi: int, masses, true_mass: float) -> dict:
    """Recovery, position error and best mass from :func:`observe_and_scan`'s result
    (template 0 is the reference, then one generator template per mass in ``masses``)."""
    d = result.delta_chi2()  # (template, r_p, phi_p)
    ref_truth = float(d[0, i_rp, i_phi])
    k_true = 1 + int(np.argmin(np.abs(np.asarray(masses) - true_mass)))
    best = result.peak(k_true)
    peaks = [float(d[1 + k].max()) for k in range(len(masses))]
    dphi = np.degrees(abs(np.angle(np.exp(1j * (best.phi_p - result.phi_p[i_phi])))))
    return {
        "ref_dchi2": ref_truth,
        "gen_dchi2": float(d[k_true, i_rp, i_phi]),
        "recovery": float(d[k_true, i_rp, i_phi]) / ref_truth,
        "dr_steps": float(abs(best.r_p - result.r_p[i_rp]) / RP_STEP),
        "dphi_deg": float(dphi),
        "best_mass": float(masses[int(np.argmax(peaks))]),
        "peaks": peaks,
    }


def evaluate_case(case: Case, tau0: float, inc: float, phi_p_deg: float = 0.0, seed: int = 1,
                  masses=BANK_MASSES, noise: bool = False, frank: bool = False, **options) -> dict:
    """Map-level and scan-level fidelity of the generator for one reference case."""
    ref = reference_template(case, tau0)
    gens = [generator_template(m, tau0, case.h_p, case.beta, **options) for m in masses]
    k = int(np.argmin(np.abs(np.asarray(masses) - case.mu)))
    out = {"case": case.label, "mu": case.mu, "h_p": case.h_p, "tau0": tau0, "inc": inc, "phi_p_deg": phi_p_deg,
           **map_metrics(ref, gens[k]), **beam_metrics(ref, gens[k])}
    result, i_rp, i_phi = observe_and_scan(ref, gens, tau0, inc, phi_p_deg, seed, noise=noise, frank=frank)
    out.update(scan_metrics(result, i_rp, i_phi, masses, case.mu))
    return out


SETUPS = ((0.0, 0.0), (30.0, 132.0))
"""(inclination [deg], φ_p [deg]) of the two fiducial observations: face-on with the planet at
0°, and inclined 30° (PA 60°) with the planet at 132° (on the 4° grid, off the major axis)."""


def fidelity_table(cases=None, taus=TAUS, setups=SETUPS, **options) -> list[dict]:
    """:func:`evaluate_case` for every case × τ0 × set-up (``options`` go to the generator)."""
    rows = []
    for case in cases or reference_cases():
        for tau0 in taus:
            for inc, phi_p in setups:
                rows.append(evaluate_case(case, tau0, inc, phi_p, **options))
    return rows


def format_table(rows, scan: bool = True) -> str:
    """The fidelity table as text (one line per case × τ0 × set-up); ``scan=False``: map level only."""
    head = f"{'case':32s} {'tau0':>4s} {'ncc':>5s} {'rms':>5s} {'b_ncc':>5s} {'b_rms':>5s} {'b_rec':>6s}"
    if scan:
        head += f" {'inc':>3s} {'recov':>6s} {'dr':>4s} {'dphi':>5s} {'mass':>5s} {'true':>5s} {'ref_dchi2':>9s} pass"
    lines = [head, "-" * len(head)]
    for r in rows:
        line = (f"{r['case']:32s} {r['tau0']:4g} {r['ncc']:5.2f} {r['rms_ratio']:5.2f} {r['beam_ncc']:5.2f} "
                f"{r['beam_rms_ratio']:5.2f} {r['beam_recovery']:6.2f}")
        if scan:
            line += (f" {r['inc']:3.0f} {r['recovery']:6.2f} {r['dr_steps']:4.1f} {r['dphi_deg']:5.1f} "
                     f"{r['best_mass']:5g} {r['mu']:5g} {r['ref_dchi2']:9.1f} {'yes' if passes(r) else 'no'}")
        lines.append(line)
    if scan:
        n = sum(passes(r) for r in rows)
        lines.append(f"{n}/{len(rows)} pass (recovery >= 0.85, |dr| <= 1 step, |dphi| <= 4 deg, best mass = true)")
    return "\n".join(lines)


def map_table(cases=None, taus=TAUS, **options) -> list[dict]:
    """Map-level metrics only (seconds): every case × τ0."""
    rows = []
    for case in cases or reference_cases():
        for tau0 in taus:
            ref = reference_template(case, tau0)
            gen = generator_template(case.mu, tau0, case.h_p, case.beta, **options)
            rows.append({"case": case.label, "mu": case.mu, "h_p": case.h_p, "tau0": tau0,
                         **map_metrics(ref, gen), **beam_metrics(ref, gen)})
    return rows


def passes(row: dict) -> bool:
    """The issue's thresholds: recovery ≥ 0.85, ≤ 1 grid step in r_p, ≤ 4° in φ_p, right mass."""
    return (row["recovery"] >= 0.85 and row["dr_steps"] <= 1.0 + 1e-9 and row["dphi_deg"] <= 4.0 + 1e-9
            and bool(np.isclose(row["best_mass"], row["mu"])))
