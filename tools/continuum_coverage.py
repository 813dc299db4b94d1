#!/usr/bin/env python
"""The coverage table of the ``continuum`` run set (docs/templates.md) from its reduced file.

    python tools/continuum_coverage.py [tests/data/references/continuum/fargo3d_continuum.h5]

One Markdown row per reduced run, in design order, with the cost FARGO3D recorded (wall time on
the machine that ran it, and CPU seconds per orbit where the driver recorded them) and the run's
arm RMS; a last line names the design's points not in the file (still running, still to run, or run
but not reduced: the file cannot tell which).
"""

from __future__ import annotations

import sys
from pathlib import Path

import h5py

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fargo3d_library_cases as lib

DEFAULT = Path(__file__).resolve().parents[1] / "tests/data/references/continuum/fargo3d_continuum.h5"


def rows(path: Path) -> tuple[list[str], list[str]]:
    """Markdown rows of the reduced runs and the names of the design's runs not in ``path``."""
    with h5py.File(path, "r") as f:
        by_run = {f[g].attrs["run"]: dict(f[g].attrs) for g in f if isinstance(f[g], h5py.Group)}
    out, missing = [], []
    for case in lib.CASES:
        if case.batch != "continuum":
            continue
        a = by_run.get(case.name)
        if a is None:
            missing.append(case.name)
            continue
        out.append(f"| {case.name.split('_')[0]} | {a['mu_Mth']:g} | {lib.h_text(a['h_p'])} | {a['p_sigma']:g} "
                   f"| {a['alpha_at_rp']:.1e} | {a['nx_phi']} × {a['ny_r']} ({a['cells_per_H']:.1f} per H) "
                   f"| {a['orbits']:g} | {a['wall_time_s']} ({a['wall_time_per_orbit_s']:.0f} per orbit) "
                   f"| {_cpu(a)} | {a['arm_rms']:.3f} |")
    return out, missing


def _cpu(a: dict) -> str:
    """CPU seconds per orbit (when the driver recorded them): the cost whatever else the machine ran."""
    return f"{a['cpu_time_per_orbit_s']:.1f}" if "cpu_time_per_orbit_s" in a else "–"


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    found, missing = rows(Path(argv[0]) if argv else DEFAULT)
    print("| point | M_p [M_th] | H/r | p | α at r_p | cells (φ × r) | orbits | wall time [s] | CPU s per orbit "
          "| arm RMS δΣ/Σ |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    print("\n".join(found))
    print(f"\n{len(found)} runs reduced; {len(missing)} of the design not reduced: {', '.join(missing) or 'none'}")


if __name__ == "__main__":
    main()
