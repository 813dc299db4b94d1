"""Leave-one-source-out calibration of the robust limits over morphology variants (issue 22).

Shared by ``test_robust_calibration.py`` and the slow table of docs/limits.md §4d. The set-up is
§4c's (``tests/_support/limits_setup``: ALMA C-4, ~1e4 visibilities, 140 pc, inclination 30°,
true axisymmetric disc, planet at r_p = 0.3″ on the azimuth grid), with the disc's τ0 set to the
planted spiral's and the noise scaled so that the bank's (compromise) template of the true mass
has ``Σ w |ΔV|² = power`` at the planet (100 or 400: a planet the data rule out firmly when it
is absent). The family is the morphology set — the compromise plus the variants refitted without
the held-out source (``tests/templates/variant_fit.py``) — over the bank masses next to the truth
and both hands; the limit is the robust one (every variant must exclude), and the compromise's own
limit from the same realisations is the single-template "before".
"""

from __future__ import annotations

import functools

import numpy as np

from spiralbayes import AxisymmetricModel
from spiralbayes.inference.scan.engine import ScanContext, scan_template
from spiralbayes.inference.validation.planted import planted_exclusion_rate
from spiralbayes.simulate import DiscModel, observe
from spiralbayes.templates.variants import Variant, variant_template
from spiralbayes.templates.wake import PAPER_MASSES
from tests._support import limits_setup as L
from tests.templates import fidelity as F
from tests.templates import variant_fit as VF

CL = 0.95
R_P, PHI_P = 0.3, 2 * np.pi * 10 / L.N_PHI
F_INC = 30.0  # the fiducial set-up's inclination [deg] (variant_fit.INC)


def loso_variants(held_out: str) -> list[Variant]:
    """The compromise plus the variants refitted to every reference but those of ``held_out``."""
    rows = [r for r in VF.reference_rows() if VF.calibration_source(r[0]) != held_out]
    out = [Variant("compromise")]
    for name, f in VF.fit_variants(rows).items():
        out.append(Variant(name, scale=f["scale_final"], scale_slope=f["scale_slope"], blob=f["blob_final"],
                           blob_slope=f["slope"], broad=f["broad_final"], broad_width=VF.BROAD_WIDTH,
                           mass_factors=tuple(f["mass_factors"].items()),
                           note=f"refitted without {held_out}; binding {f['binding']}"))
    return out


def neighbour_masses(mu: float) -> tuple:
    """The bank masses next to ``mu`` (and ``mu``): the limit is interpolated between them."""
    masses = np.asarray(PAPER_MASSES)
    k = int(np.argmin(np.abs(masses - mu)))
    return tuple(float(m) for m in masses[max(k - 1, 0):k + 2])


def family(variants, mu: float, tau0: float, beta: float, h_p: float, hands: str = "both") -> list:
    out = []
    for v in variants:
        for m in neighbour_masses(mu):
            right = variant_template(m, tau0, beta, "R", v, h_p=h_p, **L.GRID)
            out += [right, right.mirror()] if hands == "both" else [right]
    return out


@functools.cache
def disc_model(tau0: float) -> AxisymmetricModel:
    disc = DiscModel(distance=L.DISTANCE, tau_ref=tau0)
    return AxisymmetricModel.from_profile(disc.profile(L.WAVELENGTH), L.GEOMETRY)


def observation(tau0: float, bank_template, power: float):
    """Noise scaled so that ``bank_template`` at (R_P, PHI_P) has ``Σ w |ΔV|² = power``."""
    model, cov = disc_model(tau0), L.coverage()
    clean = model.visibilities(cov.u, cov.v, L.GEOMETRY)
    probe = observe(clean, cov, sensitivity=35e-6, seed=0)
    ctx = ScanContext.build(probe, model, L.GEOMETRY, [R_P], L.N_PHI)
    p35 = float(scan_template(ctx, bank_template)[1].mean())
    return observe(clean, cov, sensitivity=35e-6 * np.sqrt(p35 / power), seed=0)


def calibrate(case: F.Case, tau0: float, power: float, variants, n: int, seed: int = 50, control: bool = True,
              hand: str = "R"):
    """(planted reference, control) :class:`PlantedExclusion` of one case (control: the bank's own
    compromise template of the true mass, planted instead; None when ``control`` is false).

    ``hand="R"`` (the planted hand) by default: excluding then needs only the right-handed
    templates to exclude, which is at least as strict as ``"both"`` (the mirror templates overlap a
    right-handed spiral at the truth little and exclude it anyway) and halves the cost."""
    fam = family(variants, case.mu, tau0, case.beta, case.h_p, hands=hand)
    bank = variant_template(case.mu, tau0, case.beta, "R", "compromise", h_p=case.h_p, **L.GRID)
    vis = observation(tau0, bank, power)
    ref = F.reference_template(case, tau0)
    kw = dict(n_realisations=n, cl=CL, n_phi_p=L.N_PHI, seed=seed, robust=True, hand=hand)
    planted = planted_exclusion_rate(vis, disc_model(tau0), fam, ref, R_P, PHI_P, case.mu, **kw)
    ctrl = planted_exclusion_rate(vis, disc_model(tau0), fam, bank, R_P, PHI_P, case.mu, **kw) if control else None
    return planted, ctrl


def single_rate(out, variant: str = "compromise") -> float:
    """Wrong-exclusion rate of one variant's family alone, from the same realisations."""
    for label, m_lim in out.details["m_lim_by_family"].items():
        if f"variant={variant}" in label:
            return float(np.mean(np.nan_to_num(m_lim, nan=np.inf) <= out.true_mass * (1 + 1e-9)))
    raise KeyError(variant)


def allowed_wrong(n: int, cl: float = CL) -> float:
    """The nominal rate plus two binomial standard errors."""
    p = 1 - cl
    return p + 2 * np.sqrt(p * (1 - p) / n)


# ---------------------------------------------------------------------- fiducial set-up, at the truth
def truth_instance_rates(g: dict, amplitudes, power: float, n: int, seed: int = 0, control: bool = False):
    """Wrong-exclusion rates at the truth instance in the fiducial set-up (``variant_fit``'s
    observation, where the variants were fitted), from the noise-free inner products ``g``.

    The noise is scaled so that the compromise template has ``Σ w |ΔV|² = power``; the cross terms
    of the variants' true-mass templates ``V_i = s_i T + b_i B + w_i W`` (``amplitudes``: one
    ``(s_i, b_i[, w_i])`` each, the compromise ``(1, 0)`` first) are then jointly Gaussian with mean ``f <S, V_i>`` and
    covariance ``f <V_i, V_j>`` (``f = power / <T, T>``), so ``n`` realisations are exact draws.
    A realisation wrongly excludes when every variant's ``A_up < 1`` at the truth — necessary for
    ``M_lim <= M_true`` (which also needs every azimuth and the heavier masses to exclude), so the
    rate bounds the limit's wrong-exclusion rate from above. ``control``: plant the compromise
    template itself (S = T). Returns ``(robust rate, compromise-alone rate)``.
    """
    from tests.templates.variant_fit import Z95

    amp = np.zeros((len(amplitudes), len(VF.BLOCKS)))
    for i, a in enumerate(amplitudes):
        amp[i, :len(a)] = a
    f = power / g["TT"]
    mean = f * amp @ VF.cross_vector(g, control)
    cov = f * amp @ VF.gram_matrix(g) @ amp.T
    rng = np.random.default_rng(seed)
    cross = rng.multivariate_normal(mean, cov, size=n, method="eigh")
    pw = np.diag(cov)
    a_up = cross / pw + Z95 / np.sqrt(pw)
    excluded = a_up < 1.0
    return float(np.mean(np.all(excluded, axis=1))), float(np.mean(excluded[:, 0]))


def loso_fits(held_out: str, rows=None) -> dict:
    """:func:`tests.templates.variant_fit.fit_variants` without ``held_out``'s rows."""
    rows = VF.reference_rows() if rows is None else rows
    return VF.fit_variants([r for r in rows if VF.calibration_source(r[0]) != held_out])


def loso_table(powers=(100.0, 400.0), n: int = 1000, seed: int = 0, taus=(0.3, 3.0),
               sources=VF.SOURCES + VF.HELD_OUT_SOURCES, gap: bool = False) -> list[dict]:
    """Every source held out in turn: each of its maps (τ0 in ``taus``) planted, robust and
    compromise-alone rates at the truth instance (fiducial set-up), and the control. The sources of
    ``VF.HELD_OUT_SOURCES`` are never in a fit, so their variants are those fitted to every reference.
    ``gap``: the maps planted in discs holding their runs' gaps (the variants fitted as shipped)."""
    rows = VF.reference_rows()
    planted = [(c, t, VF.case_gram(c, t, gap=True)) for c, t, _ in rows] if gap else rows
    if set(sources) & set(VF.HELD_OUT_SOURCES):
        planted = planted + [(c, t, VF.case_gram(c, t, gap=gap)) for c in F.physics_cases() for t in c.taus
                             if any(np.isclose(t, x) for x in taus)]
    out = []
    for source in sources:
        fits = loso_fits(source, rows)
        for case, tau0, g in planted:
            if VF.calibration_source(case) != source or not any(np.isclose(tau0, t) for t in taus):
                continue
            amps = [(1.0, 0.0)] + [VF.fitted_amplitudes(f, case.mu) for f in fits.values()]
            for power in powers:
                robust, single = truth_instance_rates(g, amps, power, n, seed)
                c_robust, c_single = truth_instance_rates(g, amps, power, n, seed + 1, control=True)
                out.append(dict(source=source, case=case.label, tau0=tau0, power=power, n=n, robust=robust,
                                single=single, control_robust=c_robust, control_single=c_single,
                                variants=["compromise", *fits]))
    return out


def inner_template(template, half_width: float):
    """``template`` with its arms kept within about ``half_width`` [r_p] of the orbit,
    ``δ exp(−((x − 1)/half_width)⁴)``, as a morphology of its own (``<variant>_inner``): a limit
    template whose outer arms, which wind by an angle ∝ 1/(H/r), cannot miss a planet between the
    bank's aspect ratios (docs/limits.md §4d)."""
    from dataclasses import replace

    window = np.exp(-(((np.asarray(template.x, float) - 1.0) / half_width) ** 4))[:, None]
    variant = f"{template.provenance.get('variant', 'compromise')}_inner"
    return replace(template, delta=(np.asarray(template.delta, float) * window).astype(template.delta.dtype),
                   brightness=None, name=f"inner_{template.name}",
                   provenance={**template.provenance, "variant": variant, "inner_half_width": half_width})


def calibrate_fiducial(case: F.Case, tau0: float, power: float, variants, n: int, seed: int = 50,
                       control: bool = False, hand: str = "R", h_ps: tuple | None = None, planted=None,
                       inner: float | None = None, gap: bool = False):
    """:func:`calibrate` in the fiducial set-up (``variant_fit``'s observation: 36k visibilities,
    beam 0.061″, planet at 50 au = 0.357″ = 5.9 beams, φ_p = 40° on the 90-azimuth grid) — resolved,
    unlike §4c's C-4 set-up, whose r_p = 0.3″ lies inside its 0.34″ beam (``compute_limits`` flags
    it "unresolved" unless told ``resolution=0``). The weights are scaled so that the compromise
    template of the true mass has ``Σ w |ΔV|² = power`` at the planet. ``h_ps``: the aspect ratios of
    the limit's families (default the case's own; the bank's neighbours for a run between them).
    ``planted``: a template planted instead of the case's map (the case then gives mass, H/r and β).
    ``inner``: each variant's family also truncated to that half-width [r_p] (:func:`inner_template`),
    a morphology of its own in the robust set. ``gap``: the disc holds the case's run's gap
    (:class:`tests.templates.fidelity.GappedDisc`)."""
    from spiralbayes import DiscGeometry
    from spiralbayes.simulate import simulate_observation

    geometry = DiscGeometry(F_INC, 60.0)
    disc = F.planting_disc(case, tau0, gap)
    cov = F._coverage()
    vis0 = simulate_observation("fiducial", disc, geometry, coverage=cov, add_noise=False)
    axisym = (disc.profile(cov.wavelength), vis0.V)
    r_p, phi_p = F.R_P_AU / F.DISTANCE, np.radians(40.0)
    fam = []
    for v in variants:
        for h_p in (case.h_p,) if h_ps is None else h_ps:
            for m in neighbour_masses(case.mu):
                right = variant_template(m, tau0, case.beta, "R", v, h_p=h_p)
                for t in (right,) if inner is None else (right, inner_template(right, inner)):
                    fam += [t, t.mirror()] if hand == "both" else [t]
    bank = variant_template(case.mu, tau0, case.beta, "R", "compromise", h_p=case.h_p)
    ctx = ScanContext.build(vis0.standardised(), axisym, geometry, [r_p], 90)
    p0 = float(scan_template(ctx, bank)[1][0, 10])
    vis = vis0.with_weights(vis0.weights * power / p0, note=f"scaled to bank power {power:g}")
    if planted is None:
        planted = bank if control else F.reference_template(case, tau0)
    return planted_exclusion_rate(vis, axisym, fam, planted, r_p, phi_p, case.mu, n_realisations=n, cl=CL,
                                  n_phi_p=90, geometry=geometry, seed=seed, robust=True, hand=hand)


def between_aspect_ratios(wakeflow_file=None, n: int = 100, taus=(0.3, 3.0)):
    """Wrong-exclusion rates of spirals planted at H/r between the bank's (docs/limits.md §4d), one
    dict per case, printed as JSON lines: the physics run set's 0.5 M_th (H/r 0.06) and 2 M_th (H/r
    0.08) runs, the hydro and wakeflow variants' own templates at H/r 0.06 and 0.085 (0.3, 1 and
    3 M_th: the variants are lower envelopes, so this is the harshest case), and optionally the maps
    of ``wakeflow_file`` (``tools/make_wakeflow_references.py --h-ps 0.06 0.085 --mus 0.3 1``), with
    limit families at the bank's neighbouring H/r and at the five ``H_NODES``; bank power 400."""
    import json
    from dataclasses import replace

    from spiralbayes.templates.bank import DEFAULT_H_PS
    from spiralbayes.templates.family import H_NODES

    def neighbours(h):
        bank = sorted(DEFAULT_H_PS)
        return tuple(b for b in bank if b < h)[-1:] + tuple(b for b in bank if b > h)[:1]

    held_out = {"shipped": loso_variants("physics"), "wakeflow held out": loso_variants("wakeflow")}
    physics = {c.label: c for c in F.physics_cases()}
    jobs = [(physics[label], t, None, "shipped") for label in ("fargo3dlib:h0.06_mu0.5", "fargo3dlib:h0.08_mu2")
            for t in taus]
    base = physics["fargo3dlib:h0.06_mu0.5"]
    for v in ("hydro", "wakeflow"):
        for mu in (0.3, 1.0, 3.0):
            for h in (0.06, 0.085):
                for t in taus:
                    case = replace(base, source=f"{v}_variant", mu=mu, h_p=h, group=f"h{h:g}_mu{mu:g}")
                    jobs.append((case, t, variant_template(mu, t, 0.0, "R", v, h_p=h), "shipped"))
    if wakeflow_file is not None:
        for case in F.reference_cases([wakeflow_file]):
            jobs += [(case, t, None, which) for t in taus if any(np.isclose(t, x) for x in case.taus)
                     for which in held_out]
    out = []
    for case, tau0, planted, which in jobs:
        for label, h_ps in (("bank", neighbours(case.h_p)), ("H_NODES", tuple(H_NODES))):
            res = calibrate_fiducial(case, tau0, 400.0, held_out[which], n, h_ps=h_ps, planted=planted)
            row = dict(case=case.label, tau0=tau0, variants=which, families=label, h_ps=list(h_ps), rate=res.rate)
            print(json.dumps(row), flush=True)
            out.append(row)
    return out


def inner_families(half_width: float = 0.3, wakeflow_file=None, n: int = 100, tau0: float = 3.0):
    """Wrong-exclusion rates and median limits with the shipped variants' families and with their
    truncated copies beside them (``inner``), as JSON lines: the spirals between the bank's aspect
    ratios of :func:`between_aspect_ratios` (families at the bank's neighbouring H/r) and planted maps
    at the bank's H/r (the cost: how much weaker the limit gets); bank power 400."""
    import json
    from dataclasses import replace

    shipped = loso_variants("physics")
    cases = {c.label: c for c in F.physics_cases() + F.acceptance_cases()}
    jobs = [(cases["fargo3dlib:h0.06_mu0.5"], (0.05, 0.07), None), (cases["fargo3dlib:h0.08_mu2"], (0.07, 0.10), None)]
    if wakeflow_file is not None:
        jobs += [(c, (0.05, 0.07) if c.h_p < 0.07 else (0.07, 0.10), None) for c in F.reference_cases([wakeflow_file])]
    base = cases["fargo3dlib:h0.06_mu0.5"]
    for v in ("hydro", "wakeflow"):
        for mu in (0.3, 1.0, 3.0):
            for h in (0.06, 0.085):
                case = replace(base, source=f"{v}_variant", mu=mu, h_p=h, group=f"h{h:g}_mu{mu:g}")
                jobs.append((case, (0.05, 0.07) if h < 0.07 else (0.07, 0.10), variant_template(mu, tau0, 0.0, "R", v,
                                                                                                 h_p=h)))
    jobs += [(cases[label], None, None) for label in (
        "fargo3dlib:h0.05_mu1", "fargo3dlib:h0.07_mu1", "fargo3dlib:h0.10_mu1", "fargo3dlib:h0.07_mu0.3",
        "fargo3dlib:h0.07_mu3", "fargo3dlib:h0.07_mu1_orbits500", "wakeflow:h0.05_mu0.3", "wakeflow:h0.07_mu1")]
    out = []
    for case, h_ps, planted in jobs:
        for label, width in (("shipped", None), ("+inner", half_width)):
            res = calibrate_fiducial(case, tau0, 400.0, shipped, n, h_ps=h_ps, planted=planted, inner=width)
            m = np.asarray(res.m_lim, float)
            row = dict(case=case.label, tau0=tau0, h_ps=None if h_ps is None else list(h_ps), families=label,
                       rate=res.rate, limits=int(np.isfinite(m).sum()),
                       median_m_lim=float(np.nanmedian(m)) if np.isfinite(m).any() else None)
            print(json.dumps(row), flush=True)
            out.append(row)
    return out


if __name__ == "__main__":
    import sys

    if len(sys.argv) > 1 and sys.argv[1] == "--inner":
        inner_families(float(sys.argv[2]), sys.argv[3] if len(sys.argv) > 3 else None)
    else:
        between_aspect_ratios(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] else None,
                              taus=tuple(float(t) for t in sys.argv[2:]) or (0.3, 3.0))
