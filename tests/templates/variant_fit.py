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


@lru_cache(maxsize=None)
def case_gram(case: F.Case, tau0: float, beta: float = 0.0) -> dict:
    """Inner products of the reference S with the variant blocks (T: the compromise template of the
    case's mass and h_p; B: the near-planet blob), and among them: keys ``SS, ST, SB, TT, BB, TB``."""
    from spiralbayes.templates.variants import blob_template, variant_template

    ref = F.reference_template(case, tau0)
    t = variant_template(case.mu, tau0, beta, "R", "compromise", h_p=case.h_p)
    b = blob_template(case.mu, tau0, beta, "R", h_p=case.h_p)
    cross, power = truth_products(ref, [t, b], tau0)
    tb, _ = truth_products(t, [b], tau0)
    return {"SS": power[0], "ST": cross[1], "SB": cross[2], "TT": power[1], "BB": power[2], "TB": tb[1]}


def upper_limit(g: dict, scale: float, blob: float) -> tuple[float, float]:
    """``(A_hat, A_up)`` at the truth of the template ``scale T + blob B``."""
    st = scale * g["ST"] + blob * g["SB"]
    tt = scale**2 * g["TT"] + blob**2 * g["BB"] + 2 * scale * blob * g["TB"]
    a_hat = st / tt
    return float(a_hat), float(a_hat + Z95 / np.sqrt(tt))


MARGIN = 0.9
"""A variant fitted to a source has A_hat >= 1/MARGIN on every map of that source."""


def fit_source(rows, slopes=(0.0, 0.5, 1.0), margin: float = MARGIN) -> dict:
    """rows: (case, tau0, gram). Least squares of (scale, blob) per slope; best slope; shrink."""
    best = None
    for slope in slopes:
        a = np.zeros((2, 2))
        y = np.zeros(2)
        for case, _, g in rows:
            f = case.mu**slope
            w = 1.0 / g["SS"]
            a += w * np.array([[g["TT"], f * g["TB"]], [f * g["TB"], f * f * g["BB"]]])
            y += w * np.array([g["ST"], f * g["SB"]])
        scale, blob = np.linalg.solve(a, y)
        loss = sum((g["SS"] - 2 * (scale * g["ST"] + blob * case.mu**slope * g["SB"])
                    + scale**2 * g["TT"] + (blob * case.mu**slope) ** 2 * g["BB"]
                    + 2 * scale * blob * case.mu**slope * g["TB"]) / g["SS"] for case, _, g in rows)
        if best is None or loss < best["loss"]:
            best = {"scale": float(scale), "blob": float(blob), "slope": slope, "loss": float(loss)}
    # A_hat of each case; shrink so that the smallest is >= 1/margin
    a_hats = [upper_limit(g, best["scale"], best["blob"] * case.mu**best["slope"])[0] for case, _, g in rows]
    k = min(margin, margin * min(a_hats))
    binding = rows[int(np.argmin(a_hats))]
    best.update(k=float(k), scale_final=best["scale"] * k, blob_final=best["blob"] * k,
                binding=f"{binding[0].label} tau0={binding[1]:g}")
    return best
