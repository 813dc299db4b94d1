"""Leave-one-source-out check of limits robust over a learned bank's discs (docs/limits.md §4d).

The variants' check (:mod:`.robust_calibration`, ``loso_table``) asks how often every morphology
excludes a held-out reference map's true mass at the planted instance. The same question for the
learned bank (``[templates] bank = "learned"``): the robust set is the bank's nine default discs
(:data:`~spiralbayes.templates.learned.bank.DEFAULT_SLOPES` × :data:`~spiralbayes.templates.learned.bank.DEFAULT_ALPHAS`
at :data:`~spiralbayes.templates.learned.bank.DEFAULT_ORBITS`), each predicted at the map's true mass,
H/r and τ0, by a model refitted without the training runs of the map's source
(:func:`tests.templates.variant_fit.calibration_source`; sources the model never trains on — wakeflow,
β = 10, dust — use the model of every run, and the ``continuum`` design is a source of its own).

Each map of the variants' check (the acceptance references and the ``physics`` run set) and each
continuum run, at τ0 0.3 and 3, is planted noise-free in the fiducial observation
(:func:`tests.templates.variant_fit.truth_products`), the noise scaled so that the compromise template
of the true mass has ``Σ w|ΔV|² = power`` (100 or 400), as the variants' check does. A template ``d``
excludes the truth when ``A_up = Â + z σ_A < 1``; with ``μ = f<S, T_d>`` and ``P = f<T_d, T_d>`` that is
``Φ((P − z√P − μ)/√P)`` exactly. A robust limit excludes only where every disc does, so the rate of the
disc that excludes least bounds the robust limit's wrong-exclusion rate from above (the variants' check
draws the joint rate; this bound needs no cross terms between discs). Allowed: 5 % + 2 binomial σ of
1000 draws, as there (6.4 %).

    PYTHONPATH=src:. python -m tests.inference.validation.learned_calibration [OUT.json [MARGIN]]
"""

from __future__ import annotations

import json
import logging
import sys
from pathlib import Path

import numpy as np
from scipy.stats import norm

from tests.templates import fidelity as F
from tests.templates import variant_fit as VF

log = logging.getLogger(__name__)

POWERS = (100.0, 400.0)
TAUS = (0.3, 3.0)
ALLOWED = 0.05 + 2 * np.sqrt(0.05 * 0.95 / 1000)
CONTINUUM = "continuum"


def _key(path, group: str) -> tuple[str, str]:
    return str(Path(path).resolve()), str(group)


def planted_cases() -> list:
    """The variants' check's maps (acceptance references, ``physics`` set) and the continuum runs."""
    continuum = [c for c in F.reference_cases([F.REF_DIR / "continuum" / "fargo3d_continuum.h5"]) if c.is_reference]
    return F.acceptance_cases() + F.physics_cases() + continuum


def source_of(case) -> str:
    if "continuum" in str(case.file):
        return CONTINUUM
    return VF.calibration_source(case)


def run_sources(runs) -> dict:
    """``{training run name: its source}`` (:func:`source_of` of the reference case it is; a continuum run
    is ``continuum``)."""
    case_source = {_key(F.REF_DIR / c.file, c.group): source_of(c) for c in planted_cases()}
    return {r.name: case_source.get(_key(r.file, r.group), CONTINUUM if "continuum" in r.file else "other")
            for r in runs}


def learned_robust_rates(g_cross, g_power, power: float, margin: float = 1.0, z: float = VF.Z95) -> np.ndarray:
    """Each template's probability of ``A_up < 1`` at the truth (the module docstring); ``g_cross`` and
    ``g_power`` are ``<S, T>`` and ``<T, T>`` noise-free, the first template the compromise that sets the
    noise (its ``Σ w|ΔV|² = power``). ``margin`` scales every template but the compromise (``m T``: a
    margin below 1 asks the data for ``Â ≥ 1/m`` before a mass is excluded, as the variants' 0.8 does)."""
    g_cross, g_power = np.asarray(g_cross, float), np.asarray(g_power, float)
    scale = np.r_[1.0, np.full(g_cross.size - 1, margin)]
    f = power / g_power[0]
    mu, p = f * scale * g_cross, f * scale**2 * g_power
    return norm.cdf((p - z * np.sqrt(p) - mu) / np.sqrt(p))


def learned_loso_table(powers=POWERS, taus=TAUS) -> list[dict]:
    from spiralbayes.templates.learned import (DEFAULT_ALPHAS, DEFAULT_ORBITS, DEFAULT_SLOPES, LearnedTemplateModel,
                                               read_training_runs, reference_files)

    runs = read_training_runs(reference_files())
    cases = planted_cases()
    run_source = run_sources(runs)
    discs = [(p, a, o) for p in DEFAULT_SLOPES for a in DEFAULT_ALPHAS for o in DEFAULT_ORBITS]
    models: dict = {}
    out = []
    for case in cases:
        source = source_of(case)
        if source not in models:
            train = [r for r in runs if run_source[r.name] != source]
            models[source] = LearnedTemplateModel.fit(train)
            log.info("%s: model of %d runs (%d held out)", source, len(train), len(runs) - len(train))
        model = models[source]
        for tau0 in taus:
            if not any(np.isclose(tau0, t) for t in case.taus):
                continue
            ref = F.reference_template(case, tau0)
            compromise = F.generator_template(case.mu, tau0, case.h_p)
            learned = [model.predict(case.mu, case.h_p, p, a, o, tau0, extrapolate=True) for p, a, o in discs]
            cross, pw = VF.truth_products(ref, [compromise, *learned], tau0)
            for power in powers:
                out.append({"source": source, "case": case.label, "tau0": tau0, "power": power,
                            "cross": [float(c) for c in cross[1:]], "template_power": [float(q) for q in pw[1:]],
                            **_rates(cross[1:], pw[1:], power, 1.0)})
        log.info("%s %s done", source, case.label)
    return out


def _rates(cross, power_t, power: float, margin: float) -> dict:
    rates = learned_robust_rates(cross, power_t, power, margin)
    return {"compromise": float(rates[0]), "robust_bound": float(np.min(rates[1:])),
            "worst_disc": float(np.max(rates[1:]))}


def with_margin(rows, margin: float) -> list[dict]:
    """``rows`` re-rated with the learned templates scaled by ``margin``."""
    return [{**r, **_rates(r["cross"], r["template_power"], r["power"], margin)} for r in rows]


MARGINS = tuple(float(m) for m in np.round(np.arange(1.0, 0.29, -0.05), 2))
"""The margins :func:`smallest_passing_margin` tries, 1 down to 0.3 in steps of 0.05."""


def smallest_passing_margin(rows, margins=MARGINS) -> dict:
    """Per source, the largest margin (least conservative) at which no map's bound exceeds 6.4 %."""
    out = {}
    for source in dict.fromkeys(r["source"] for r in rows):
        rs = [r for r in rows if r["source"] == source]
        out[source] = next((float(m) for m in margins if all(x["robust_bound"] <= ALLOWED
                                                              for x in with_margin(rs, m))), None)
    return out


def format_table(rows) -> str:
    lines = ["| held-out source | bank power | maps | compromise alone: maps over 6.4 % (worst) | "
             "robust over the learned discs: maps over 6.4 % (worst bound) |", "|---|---|---|---|---|"]
    for source in dict.fromkeys(r["source"] for r in rows):
        for power in POWERS:
            rs = [r for r in rows if r["source"] == source and r["power"] == power]
            if not rs:
                continue
            worst_c = max(rs, key=lambda r: r["compromise"])
            worst_r = max(rs, key=lambda r: r["robust_bound"])
            lines.append(f"| {source} | {power:g} | {len(rs)} | {sum(r['compromise'] > ALLOWED for r in rs)} "
                         f"({worst_c['compromise']:.0%}) | {sum(r['robust_bound'] > ALLOWED for r in rs)} "
                         f"({worst_r['robust_bound']:.1%}; {worst_r['case']} τ0 {worst_r['tau0']:g}) |")
    return "\n".join(lines)


def main(out: str = "", margin: str = "") -> None:
    """``out``: the rows' JSON (read back instead of recomputed when it exists); ``margin``: also the table
    with the learned templates scaled by it."""
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("spiralbayes").setLevel(logging.ERROR)
    if out and Path(out).exists():
        rows = json.loads(Path(out).read_text())
    else:
        rows = learned_loso_table()
        if out:
            Path(out).write_text(json.dumps(rows, indent=1))
    print(format_table(rows))
    print("largest margin at which every map of the source passes:", smallest_passing_margin(rows))
    if margin:
        print(f"\nwith margin {margin}:")
        print(format_table(with_margin(rows, float(margin))))


if __name__ == "__main__":
    main(*sys.argv[1:])
