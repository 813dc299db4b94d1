"""How much of a dust run's signal a co-orbital building block would recover (a measurement, not a template).

The library's dust maps (St 0.03 and 0.1) hold an m = 1 structure in the planet's co-orbital
region that no template of the bank has: dust piled up trailing the planet and depleted ahead of it
(hand R: the planet moves towards +φ). This script plants a reference map as the detection table
does (:mod:`tests.inference.detection.reference_detection`: fiducial observation, 50 au, φ_p 40°,
the true disc as the axisymmetric model) and compares, at the true planet position, the Δχ² that
weighted linear least squares (free amplitudes) gains with

* the reference map itself ("own"),
* the bank template that fits best at the truth ("bank"),
* that template plus a co-orbital block ``D(x, Δφ) = exp(-(x - 1)^2 / 2 w^2) g(Δφ)`` (each row's
  azimuthal mean removed), with ``g = -sin Δφ`` (``sin``) or ``g`` the co-orbital band
  (``|x - 1| < 2.5 w``, averaged over x) of *another* run (``other``: leave-one-run-out),
* the block alone.

Usage (PYTHONPATH=src:.)::

    python tools/coorbital_block.py fargo3dlib:h0.07_mu1_st0.1@0.3@h0.07_mu1_st0.1_orbits200 ...

Each argument is ``label@tau0@group of the other run`` (groups of ``fargo3d_library.h5``). Prints
one JSON line per case.
"""

from __future__ import annotations

import argparse
import json
import logging

import h5py
import numpy as np

from spiralbayes.inference.scan.engine import ScanContext
from spiralbayes.model import perturbation_visibilities
from spiralbayes.templates import SpiralTemplate
from tests.inference.detection import reference_detection as rd

log = logging.getLogger("coorbital_block")


def block(x: np.ndarray, phi: np.ndarray, width: float, profile: np.ndarray | None = None) -> np.ndarray:
    """The co-orbital block δ(x, φ): a Gaussian band of ``width`` [r_p] at x = 1 times ``profile``
    (per azimuth; default ``-sin φ``), each row with zero azimuthal mean."""
    g = -np.sin(phi) if profile is None else profile
    d = np.exp(-0.5 * ((x - 1.0) / width) ** 2)[:, None] * g[None, :]
    return d - d.mean(axis=1, keepdims=True)


def gain(residual: np.ndarray, weights: np.ndarray, columns: list[np.ndarray]) -> float:
    """Δχ² of the weighted linear least-squares fit of ``columns`` (free real amplitudes) to ``residual``."""
    sw = np.sqrt(weights)
    a = np.stack([np.concatenate([(sw * c).real, (sw * c).imag]) for c in columns], axis=1)
    b = np.concatenate([(sw * residual).real, (sw * residual).imag])
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    return float(b @ b - np.sum((b - a @ coef) ** 2))


def measure(label: str, tau0: float, other_group: str, widths=(0.05, 0.08)) -> dict:
    case = next(c for c in rd.detection_cases() if c.label == label)
    vis, axisym, geometry, _, bank, templates = rd.plant_and_scan(case, tau0)
    vis = vis.standardised()
    r_true, phi_true = rd.R_P_AU / rd.DISTANCE, np.radians(rd.PHI_P_DEG)
    ref = rd.reference_template(case, tau0)
    ctx = ScanContext.build(vis, axisym, geometry, [r_true], 8, x_max=float(ref.x[-1]))
    residual = vis.V - axisym.visibilities(vis.u, vis.v, geometry)

    def visibilities(t):
        return perturbation_visibilities(vis.u, vis.v, geometry, ctx.profile, t, r_true, phi_true,
                                         quad=ctx.quadrature(t, r_true))

    i_rp = int(np.argmin(np.abs(bank.r_p - r_true)))
    i_phi = int(np.argmin(np.abs(np.angle(np.exp(1j * (bank.phi_p - phi_true))))))
    best = templates[int(np.argmax(bank.delta_chi2()[:, i_rp, i_phi]))]
    s_bank = visibilities(best)
    out = {"case": label, "tau0": tau0, "bank_template": best.name,
           "own": gain(residual, vis.weights, [visibilities(ref)]), "bank": gain(residual, vis.weights, [s_bank])}
    with h5py.File(rd.REF_DIR / "fargo3d_library.h5", "r") as f:
        other = f[f"{other_group}/delta_tau{tau0:g}"][()]
    for width in widths:
        band = np.abs(ref.x - 1.0) < 2.5 * width
        for kind, profile in (("sin", None), ("other", other[band].mean(axis=0))):
            d = SpiralTemplate(x=ref.x, phi=ref.phi, delta=block(ref.x, ref.phi, width, profile), mass=case.mu,
                               tau0=tau0, beta=0.0, h_p=case.h_p, name=f"coorbital_{kind}")
            s_d = visibilities(d)
            out[f"bank+block[{kind}, w={width:g}]"] = gain(residual, vis.weights, [s_bank, s_d])
            out[f"block alone[{kind}, w={width:g}]"] = gain(residual, vis.weights, [s_d])
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", help="label@tau0@other run's group")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    for item in args.cases:
        label, tau0, other = item.split("@")
        row = measure(label, float(tau0), other)
        print(json.dumps({k: round(v, 1) if isinstance(v, float) else v for k, v in row.items()}), flush=True)


if __name__ == "__main__":
    main()
