"""Scan-level inner products of reference spirals with the variant building blocks (issue 22).

Shared by ``tests/templates/test_variants.py`` and ``tools/fit_variants.py``. For a reference
case (``tests/templates/fidelity.py``) planted noise-free in the fiducial observation at 50 au
(inclination 30°, PA 60°, φ_p = 40°, on the 4° azimuth grid) the scan gives, at the truth,
``cross = <S, T>`` and ``power = <T, T>`` for any template T (visibility-weighted inner products;
templates enter ΔV linearly). From these the amplitude fit ``A_hat = <S,T>/<T,T>``, its error
``1/sqrt(<T,T>)`` and the noise-free upper limit ``A_up = A_hat + z_95 sigma_A`` follow, for any
linear combination of templates as well.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from tests.templates import fidelity as F

INC, PHI_P_DEG = 30.0, 40.0
Z95 = 1.6448536269514722


def truth_products(planted, templates, tau0: float) -> tuple[np.ndarray, np.ndarray]:
    """``(cross, power)`` of ``templates`` at the truth with ``planted`` in the data (noise-free)."""
    result, i, j = F.observe_and_scan(planted, list(templates), tau0, INC, PHI_P_DEG, n_rp=1)
    return np.asarray(result.cross[:, i, j], float), np.asarray(result.power[:, i, j], float)


SETUPS = ("fiducial", "c4")
"""The observations the variants must cover: ``fiducial`` (this module's docstring: the fiducial
synthetic observation, 50 au, beam 0.061″) and ``c4`` (docs/limits.md §4c: ALMA C-4 alone, planet at
0.3″ = 42 au, ``tests/_support/limits_setup``), whose coarser beam weighs the building blocks
differently — a variant fitted on one only need not cover a reference on the other."""


def _disk_key(case: F.Case, tau0: float, setup: str = "fiducial") -> str:
    from spiralbayes.templates.wake import GENERATOR_VERSION, WakeSettings

    st = (F.REF_DIR / case.file).stat()
    key = f"{case.file}:{case.group}|{tau0:g}|{st.st_size}-{st.st_mtime_ns}|v{GENERATOR_VERSION}|{WakeSettings().key()}"
    return key if setup == "fiducial" else f"{key}|{setup}"


def case_gram(case: F.Case, tau0: float, setup: str = "fiducial") -> dict:
    """:func:`compute_case_gram`, kept on disk (the user cache dir, ``reference_grams.json``; the key
    holds the reference file's size and time and the generator's version and settings)."""
    import hashlib
    import json
    import os

    from spiralbayes.templates.bank import default_cache_dir

    key = hashlib.sha256(_disk_key(case, tau0, setup).encode()).hexdigest()[:24]
    path = default_cache_dir() / "reference_grams.json"
    try:
        store = json.loads(path.read_text())
    except (OSError, ValueError):
        store = {}
    if key not in store:
        compute = compute_case_gram if setup == "fiducial" else compute_c4_gram
        store[key] = {k: float(v) for k, v in compute(case, tau0).items()}
        try:  # re-read: another process may have added entries meanwhile
            store = {**json.loads(path.read_text()), key: store[key]}
        except (OSError, ValueError):
            pass
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps(store))
            os.replace(tmp, path)
        except OSError:
            pass
    return dict(store[key])


@lru_cache(maxsize=None)
def compute_case_gram(case: F.Case, tau0: float) -> dict:
    """Inner products of the reference S with the variant blocks (T: the compromise template of the
    case's mass, h_p and β — the β = 10 generator for the β = 10 runs; B: the near-planet blob), and
    among them: keys ``SS, ST, SB, TT, BB, TB``."""
    from spiralbayes.templates.variants import blob_template, variant_template

    beta = case.beta
    ref = F.reference_template(case, tau0)
    t = variant_template(case.mu, tau0, beta, "R", "compromise", h_p=case.h_p)
    b = blob_template(case.mu, tau0, beta, "R", h_p=case.h_p)
    cross, power = truth_products(ref, [t, b], tau0)
    tb, _ = truth_products(t, [b], tau0)
    return {"SS": power[0], "ST": cross[1], "SB": cross[2], "TT": power[1], "BB": power[2], "TB": tb[1]}


@lru_cache(maxsize=None)
def compute_c4_gram(case: F.Case, tau0: float) -> dict:
    """:func:`compute_case_gram` in the ``c4`` set-up (:data:`SETUPS`; templates on the calibration's
    coarser grid ``limits_setup.GRID``), from the scan engine's cross and power terms at the truth."""
    from spiralbayes import AxisymmetricModel
    from spiralbayes.inference.scan.engine import ScanContext, cross_template, scan_template, with_residual
    from spiralbayes.model import perturbation_visibilities
    from spiralbayes.simulate import DiscModel
    from spiralbayes.templates.variants import blob_template, variant_template
    from tests._support import limits_setup as L

    r_p, i_phi = 0.3, 10
    model = AxisymmetricModel.from_profile(DiscModel(distance=L.DISTANCE, tau_ref=tau0).profile(L.WAVELENGTH),
                                           L.GEOMETRY)
    cov = L.coverage()
    vis = L.observe(model.visibilities(cov.u, cov.v, L.GEOMETRY), cov, sensitivity=35e-6, seed=0).standardised()
    ctx = ScanContext.build(vis, model, L.GEOMETRY, [r_p], L.N_PHI)
    phi_p = 2 * np.pi * i_phi / L.N_PHI
    ref = F.reference_template(case, tau0)
    t = variant_template(case.mu, tau0, case.beta, "R", "compromise", h_p=case.h_p, **L.GRID)
    b = blob_template(case.mu, tau0, case.beta, "R", h_p=case.h_p, **L.GRID)

    def dv(planted):
        return perturbation_visibilities(vis.u, vis.v, L.GEOMETRY, ctx.profile, planted, r_p, phi_p,
                                         cell_factor=ctx.cell_factor)

    def cross(planted, template):
        return float(cross_template(with_residual(ctx, dv(planted)), template)[0, i_phi])

    def power(template):
        return float(scan_template(ctx, template)[1][0, i_phi])

    ss = float(np.sum(vis.weights * np.abs(dv(ref)) ** 2))  # the reference reaches beyond the scan's grid
    return {"SS": ss, "ST": cross(ref, t), "SB": cross(ref, b), "TT": power(t), "BB": power(b),
            "TB": cross(t, b)}


def upper_limit(g: dict, scale: float, blob: float) -> tuple[float, float]:
    """``(A_hat, A_up)`` at the truth of the template ``scale T + blob B``."""
    st = scale * g["ST"] + blob * g["SB"]
    tt = scale**2 * g["TT"] + blob**2 * g["BB"] + 2 * scale * blob * g["TB"]
    a_hat = st / tt
    return float(a_hat), float(a_hat + Z95 / np.sqrt(tt))


MARGIN = 0.9
"""A variant fitted to a source has A_hat >= 1/MARGIN on every map of that source."""

BLOB_SLOPES = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
SCALE_SLOPES = tuple(np.round(np.arange(-0.8, 0.01, 0.05), 2))
"""The grids of the two powers of M_p/M_th (blob and scale) the fit chooses from."""


def _blocks(case, g, scale_slope, blob_slope):
    fs, fb = case.mu**scale_slope, case.mu**blob_slope
    gram = np.array([[fs * fs * g["TT"], fs * fb * g["TB"]], [fs * fb * g["TB"], fb * fb * g["BB"]]])
    return gram, np.array([fs * g["ST"], fb * g["SB"]]), fs, fb


def residual(g: dict, scale: float, blob: float) -> float:
    """``|S − scale T − blob B|² / |S|²`` (visibility-weighted)."""
    return float((g["SS"] - 2 * (scale * g["ST"] + blob * g["SB"]) + scale**2 * g["TT"] + blob**2 * g["BB"]
                  + 2 * scale * blob * g["TB"]) / g["SS"])


def fit_source(rows, slopes=BLOB_SLOPES, scale_slopes=(0.0,), margin: float = MARGIN) -> dict:
    """rows: (case, tau0, gram). For each pair of powers, least squares of (scale, blob) with the
    weights ``1/|S|²`` (every map counts alike), then the largest shrink ``k <= margin`` that leaves
    every map with ``A_hat >= 1/margin``; the pair whose shrunk variant has the smallest mean
    residual is kept. Returns the constants (``scale_final``, ``blob_final`` after the shrink), the
    shrink ``k`` and the binding map."""
    best = None
    for a in scale_slopes:
        for c in slopes:
            gram, y = np.zeros((2, 2)), np.zeros(2)
            for case, _, g in rows:
                gg, yy, _, _ = _blocks(case, g, a, c)
                gram += gg / g["SS"]
                y += yy / g["SS"]
            scale, blob = np.linalg.solve(gram, y)
            a_hats = [upper_limit(g, scale * case.mu**a, blob * case.mu**c)[0] for case, _, g in rows]
            k = min(margin, margin * min(a_hats))
            loss = float(np.mean([residual(g, k * scale * case.mu**a, k * blob * case.mu**c) for case, _, g in rows]))
            if best is None or loss < best["loss"]:
                binding = rows[int(np.argmin(a_hats))]
                best = {"scale": float(scale), "scale_slope": float(a), "blob": float(blob), "slope": float(c),
                        "k": float(k), "loss": loss, "scale_final": float(k * scale), "blob_final": float(k * blob),
                        "binding": f"{binding[0].label} tau0={binding[1]:g}"}
    return best


def fitted_amplitudes(fit: dict, mu: float) -> tuple[float, float]:
    """(scale, blob) of a :func:`fit_source` variant at ``mu = M_p/M_th``."""
    return fit["scale_final"] * mu ** fit.get("scale_slope", 0.0), fit["blob_final"] * mu ** fit["slope"]


def variant_amplitudes(variant, mu: float) -> tuple[float, float]:
    """(scale, blob) of a :class:`~spiralbayes.templates.variants.Variant` at ``mu``."""
    return variant.scale_at(mu), variant.blob_amplitude(mu)


SOURCES = ("wakeflow", "fargo3d_isothermal", "library_gas", "library_beta10", "library_dust")
"""The calibration sources of the leave-one-source-out test (docs/limits.md §4d): each is one
code or one physics the others do not have — wakeflow (semi-analytic wakes); the two older
40-orbit FARGO3D runs (inner edge 0.27 r_p, 16 cells per H); the library's isothermal gas runs
(the mass and H/r grid); its β = 10 runs (another thermodynamics, another generator family); its
gas + dust run (the dust's response)."""


def calibration_source(case) -> str:
    """The :data:`SOURCES` entry of a reference case."""
    if case.source == "wakeflow":
        return "wakeflow"
    if case.source == "fargo3d":
        return "fargo3d_isothermal"
    if case.beta > 0:
        return "library_beta10"
    if "_st" in case.group:
        return "library_dust"
    return "library_gas"


def reference_rows(cases=None) -> list:
    """(case, tau0, gram) for every acceptance case × each τ0 it was reduced for."""
    return [(c, t, case_gram(c, t)) for c in (cases if cases is not None else F.acceptance_cases()) for t in c.taus]


def fit_variants(rows) -> dict:
    """The refitted variants from ``rows``: ``hydro`` from every non-wakeflow row (scale slope
    fitted), ``wakeflow`` from the wakeflow rows (one scale); a source without rows gives none."""
    out = {}
    hydro = [r for r in rows if r[0].source != "wakeflow"]
    wake = [r for r in rows if r[0].source == "wakeflow"]
    if hydro:
        out["hydro"] = fit_source(hydro, scale_slopes=SCALE_SLOPES)
    if wake:
        out["wakeflow"] = fit_source(wake, slopes=(0.0, 0.5, 1.0))
    return out
