"""Calibration of the nested test 3: planet-free, impostor and gain-error datasets (docs/verdict.md).

Shared by ``test_false_alarms.py`` (slow) and ``python -m tests.inference.detection.false_alarms``
(prints the table of the largest nested ΔBIC per kind and writes the rows as JSON).

Each dataset is the *reduced fiducial* observation of :mod:`.planet_free` (every 4th visibility of
the fiducial preset, 140 pc, inc 30°, PA 60°, τ_ref 3) with one of :data:`KINDS`, its parameters
drawn from the dataset's seed: nothing; a vortex-like arc; a lopsided disc; an eccentric ring; a
two-armed (m = 2) logarithmic pattern or bar; an error of the assumed geometry (phase centre up to
10 mas, inclination and PA up to 1°); antenna gain errors (:class:`spiralbayes.GainErrors`, 3–30°
phase rms, up to 10 % amplitude rms). The axisymmetric model is the true disc's azimuthal average
(:class:`~spiralbayes.simulate.asymmetric.ExactAxisymmetric`, what a perfect frank fit gives) at the
nominal geometry; the scan is :mod:`.planet_free`'s (24 templates × 13 radii × 90 azimuths). Every
dataset gets the five alternatives and the nested test (:func:`~spiralbayes.inference.detection.nested.nested_test`,
the best two alternatives) *whatever tests 1 and 2 say*, so the nested ΔBIC of the scan's best
peak is measured on all of them; the verdict is :func:`~spiralbayes.inference.detection.detect_with_planet_peak`
with the calibration diagnostic of the data.
"""

from __future__ import annotations

import json
import logging
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np

from tests.inference.detection import planet_free
from spiralbayes._provenance import atomic_path

log = logging.getLogger(__name__)

KINDS = ("planet_free", "arc", "lopsided", "eccentric_ring", "m2", "geometry", "gains")
N_PER_KIND = 50
"""Datasets per kind in the full set (7 × 50 = 350 ≥ 300)."""
SEED0 = 5000
WAVELENGTH = 0.87e-3


def _m2_pattern(amplitude: float, phi_0: float, kappa: float, r_c: float, width: float):
    """``delta = amplitude W(r) cos 2(phi - phi_0 - kappa ln(r / r_c))``, W a Gaussian of ``width``."""

    def delta(r, phi):
        r = np.maximum(r, 1e-6)
        return amplitude * np.exp(-0.5 * ((r - r_c) / width) ** 2) * np.cos(2 * (phi - phi_0 - kappa * np.log(r / r_c)))

    return delta


def draw(kind: str, seed: int) -> dict:
    """The impostor's parameters for one dataset (uniform draws from the seed)."""
    rng = np.random.default_rng(seed)
    u = rng.uniform
    if kind == "planet_free":
        return {}
    if kind == "arc":
        return {"r_c": u(0.15, 0.45), "phi_c": u(0, 2 * np.pi), "width_r": u(0.02, 0.04), "width_phi": u(0.2, 0.6),
                "contrast": u(0.05, 0.3)}
    if kind == "lopsided":
        return {"amplitude": u(0.005, 0.03), "phi_0": u(0, 2 * np.pi), "r_c": u(0.2, 0.45), "width": u(0.05, 0.3)}
    if kind == "eccentric_ring":
        return {"r_0": u(0.25, 0.45), "width": u(0.02, 0.04), "e": u(0.02, 0.08), "omega": u(0, 2 * np.pi),
                "contrast": u(0.1, 0.4)}
    if kind == "m2":
        return {"amplitude": u(0.01, 0.05), "phi_0": u(0, np.pi), "kappa": u(-2, 2), "r_c": u(0.2, 0.4),
                "width": u(0.05, 0.15)}
    if kind == "geometry":
        return {"dRA": u(-0.010, 0.010), "dDec": u(-0.010, 0.010), "d_inc": u(-1, 1), "d_PA": u(-1, 1)}
    if kind == "gains":
        return {"phase_rms_deg": u(3, 30), "amp_rms": u(0, 0.1), "coherence_s": u(60, 600)}
    raise ValueError(f"unknown kind {kind!r}")


def dataset(kind: str, seed: int):
    """``(vis, axisymmetric, geometry, params)`` of one dataset (module docstring)."""
    from spiralbayes import DiscGeometry, GainErrors
    from spiralbayes.simulate import DiscModel, simulate_observation
    from spiralbayes.simulate.asymmetric import ExactAxisymmetric, eccentric_ring, lopsided_disc, vortex_arc

    geometry = DiscGeometry(30.0, 60.0)
    disc = DiscModel(distance=planet_free.DISTANCE, tau_ref=3.0)
    p = draw(kind, seed)
    true_geometry, delta, extra = geometry, None, {}
    if kind == "arc":
        delta = vortex_arc(disc.profile(WAVELENGTH), p["r_c"], p["phi_c"], p["width_r"], p["width_phi"], p["contrast"])
    elif kind == "lopsided":
        delta = lopsided_disc(p["amplitude"], p["phi_0"], p["r_c"], p["width"])
    elif kind == "eccentric_ring":
        delta = eccentric_ring(p["r_0"], p["width"], p["e"], p["omega"], p["contrast"])
    elif kind == "m2":
        delta = _m2_pattern(p["amplitude"], p["phi_0"], p["kappa"], p["r_c"], p["width"])
    elif kind == "geometry":
        true_geometry = geometry.replace(dRA=p["dRA"], dDec=p["dDec"], inc=geometry.inc + p["d_inc"],
                                         PA=geometry.PA + p["d_PA"])
    elif kind == "gains":
        extra["gains"] = GainErrors(p["phase_rms_deg"], p["amp_rms"], p["coherence_s"], seed=seed)
    vis = simulate_observation("fiducial", disc, true_geometry, delta, seed=seed, coverage=planet_free._coverage(),
                               **extra)
    vis = vis.subset(np.arange(0, vis.V.size, planet_free.STRIDE))
    return vis, ExactAxisymmetric(disc, WAVELENGTH, geometry, delta), geometry, p


def map_templates() -> tuple:
    """Every reference map the detection table's map bank draws from, at τ0 3 and β 0, both hands
    (:func:`~tests.inference.detection.reference_detection.map_bank` with no source held out)."""
    from tests.inference.detection.reference_detection import _map_bank

    return _map_bank("", 3.0, 0.0)


@lru_cache(maxsize=1)
def learned_templates() -> tuple:
    """The learned bank in the set's disc and optical depth: the learned model fitted to every training run
    (:func:`~spiralbayes.templates.learned.reference_files`), predicted at the bank's masses, H/r 0.07 and τ0 3
    for the default slopes, viscosities and age of ``[templates] bank = "learned"`` (9 discs), both hands:
    72 templates, in place of the variants' 24."""
    from spiralbayes.templates.learned import (DEFAULT_ALPHAS, DEFAULT_ORBITS, DEFAULT_SLOPES, LearnedTemplateModel,
                                               learned_bank, reference_files)
    from spiralbayes.templates.wake import PAPER_MASSES

    model = LearnedTemplateModel.from_references(reference_files())
    return tuple(learned_bank(model, PAPER_MASSES, planet_free.BANK["h_ps"], DEFAULT_SLOPES, DEFAULT_ALPHAS,
                              DEFAULT_ORBITS, planet_free.BANK["taus"]))


BANKS = ("variants", "maps", "learned")
"""The banks the set is run with: the variants (24 templates), the variants and the reference maps, the
learned bank (:func:`learned_templates`)."""


def bank_templates(bank: str) -> tuple:
    if bank == "learned":
        return learned_templates()
    return planet_free.bank_templates() + (map_templates() if bank == "maps" else ())


def evaluate(kind: str, seed: int, maps: bool = False, bank: str | None = None) -> dict:
    """The nested test's and the verdict's numbers for one dataset; ``maps``: the bank also holds
    :func:`map_templates`; ``bank`` (one of :data:`BANKS`) overrides ``maps``."""
    from spiralbayes.calibration import diagnose_calibration
    from spiralbayes.inference.detection import detect_with_planet_peak, fit_alternatives
    from spiralbayes.inference.detection.nested import best_nested_test
    from spiralbayes.inference.scan.run import scan

    vis, axisym, geometry, params = dataset(kind, seed)
    bank = bank or ("maps" if maps else "variants")
    templates = bank_templates(bank)
    result = scan(vis, axisym, list(templates), geometry, r_p=planet_free.R_GRID, distance=planet_free.DISTANCE,
                  progress=False)
    alts = fit_alternatives(vis, axisym, geometry, progress=False)
    # the verdict's statistic: the best of the nested candidates (one template unless the bank mixes kinds)
    fits = best_nested_test(result, vis, axisym, templates, alts, geometry, result.best.template, 2)[2]
    calibration = diagnose_calibration(vis, axisym)
    verdict = detect_with_planet_peak(result, vis, axisym, templates, geometry, alternatives=alts,
                                      calibration=calibration)
    binding = min(fits, key=lambda f: f.delta_bic)
    return {"kind": kind, "seed": seed, "params": params, "n_vis": int(vis.V.size), "delta_bic": verdict.delta_bic,
            "template": verdict.template, "test1": verdict.test1_passed, "test2": verdict.test2_passed,
            "best_alternative": alts.best.name, "alternative_delta_bic": float(alts.best.delta_bic(alts.n_data)),
            "nested_delta_bic": binding.delta_bic, "nested_vs": binding.alternative,
            "nested_hypothesis": binding.hypothesis,
            "nested_each": {f.alternative: {"delta_bic": f.delta_bic, "joint": f.delta_bic_joint,
                                            "spiral_alone": f.delta_bic_spiral_alone} for f in fits},
            "phase_rms_deg": calibration.phase_rms_deg, "calibration_warns": calibration.warning is not None,
            "detected": verdict.detected, "explanation": verdict.explanation, "maps": bank == "maps", "bank": bank,
            "nested_template": verdict.nested_template, "outcome": verdict.outcome,
            "compact_source": verdict.compact_source, "verdict": verdict.to_dict()}


def diagnose(kind: str, seed: int) -> dict:
    """The calibration diagnostic of one dataset against its true disc (no scan: seconds per dataset)."""
    from spiralbayes.calibration import diagnose_calibration

    vis, axisym, _, params = dataset(kind, seed)
    d = diagnose_calibration(vis, axisym)
    return {"kind": kind, "seed": seed, "params": params, "phase_rms_deg": d.phase_rms_deg, "amp_rms": d.amp_rms,
            "phase_significance": d.phase_significance, "amp_significance": d.amp_significance,
            "warns": d.warning is not None}


def format_table(rows) -> str:
    """Markdown: per kind, datasets, largest nested ΔBIC (with its seed and alternative), tests 1+2 passed,
    detections."""
    lines = ["| kind | datasets | largest nested ΔBIC (seed, vs) | median | tests 1+2 passed | planets claimed |",
             "| --- | --- | --- | --- | --- | --- |"]
    for kind in KINDS:
        rs = [r for r in rows if r["kind"] == kind]
        if not rs:
            continue
        top = max(rs, key=lambda r: r["nested_delta_bic"])
        lines.append(f"| {kind} | {len(rs)} | {top['nested_delta_bic']:.1f} ({top['seed']}, {top['nested_vs']}) | "
                     f"{np.median([r['nested_delta_bic'] for r in rs]):.1f} | "
                     f"{sum(r['test1'] and r['test2'] for r in rs)} | {sum(r['detected'] for r in rs)} |")
    return "\n".join(lines)


def passes_test3_at(row: dict, threshold: float) -> bool:
    """Would the verdict's test 3 pass with ``nested_threshold = threshold``? Tests 1 and 2 pass, the
    statistic exceeds it, and no geometry error survives beside the spiral (the geometry rule)."""
    v = row["verdict"]
    geometry_survives = any(f["alternative"] == "geometry" and f.get("survives") for f in v.get("nested") or [])
    return bool(row["test1"] and row["test2"] and v.get("nested_delta_bic") is not None
                and v["nested_delta_bic"] > threshold and not geometry_survives)


def threshold_table(rows, thresholds=(0.0, 5.0, 10.0, 15.0, 20.0, 30.0)) -> str:
    """Markdown: for each ``nested_threshold``, the datasets whose test 3 would pass (tests 1 and 2 passed),
    without and with gain errors, and the rate's 95 % upper bound (a planet would be claimed in these unless the
    calibration diagnostic withholds it: with gain errors it does, docs/verdict.md)."""
    from scipy.stats import beta

    plain = [r for r in rows if r["kind"] != "gains"]
    gains = [r for r in rows if r["kind"] == "gains"]
    lines = ["| nested_threshold | would pass test 3: no gain errors | rate (95 % upper bound) | with gain errors |",
             "| --- | --- | --- | --- |"]
    for t in thresholds:
        k = sum(passes_test3_at(r, t) for r in plain)
        upper = float(beta.ppf(0.95, k + 1, len(plain) - k)) if plain else float("nan")
        g = sum(passes_test3_at(r, t) for r in gains)
        rate = k / max(len(plain), 1)
        lines.append(f"| {t:g} | {k} of {len(plain)} | {rate:.2%} ({upper:.2%}) | {g} of {len(gains)} |")
    return "\n".join(lines)


def seeds(kind: str, n: int = N_PER_KIND) -> list[int]:
    return [SEED0 + 1000 * KINDS.index(kind) + i for i in range(n)]


def main(out: str = "false_alarms.json", n: str = str(N_PER_KIND), start: str = "0", bank: str = "variants",
         step: str = "1") -> None:
    """Round-robin over the kinds, ``n`` datasets each from index ``start`` (every ``step``-th: two processes
    share a set with ``start`` 0 and 1, ``step`` 2, and different ``out``); rows appended to ``out``;
    ``bank``: ``maps`` adds :func:`map_templates` to the scan, ``learned`` scans :func:`learned_templates`
    instead of the variants."""
    if bank not in BANKS:
        raise SystemExit(f"the fourth argument is one of {', '.join(BANKS)}, not {bank!r}")
    logging.basicConfig(level=logging.INFO)
    path = Path(out)
    rows = json.loads(path.read_text()) if path.exists() else []
    done = {(r["kind"], r["seed"]) for r in rows}
    for i in range(int(start), int(n), int(step)):
        for kind in KINDS:
            seed = seeds(kind, int(n))[i]
            if (kind, seed) in done:
                continue
            rows.append(evaluate(kind, seed, bank=bank))
            log.info("%s", {k: v for k, v in rows[-1].items() if k != "params"})
            with atomic_path(path) as tmp:  # a run stopped mid-write keeps the rows it had
                tmp.write_text(json.dumps(rows, indent=1, default=float))
    print(format_table(rows))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--thresholds"]:  # --thresholds OUT.json [OUT2.json ...]: test 3's rate per threshold
        print(threshold_table([r for f in sys.argv[2:] for r in json.loads(Path(f).read_text())]))
    else:
        main(*sys.argv[1:])
