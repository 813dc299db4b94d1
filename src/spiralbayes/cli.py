"""The ``spiralbayes`` command: demo, simulate, axisym, scan, sample, templates."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

__all__ = ["main"]

log = logging.getLogger("spiralbayes")


def _cmd_demo(args) -> int:
    from .pipeline import run_demo

    demo = run_demo(args.out, seed=args.seed, progress=not args.quiet, dask=args.dask or None)
    print(demo.verdict.summary())
    print(f"Delta BIC = {demo.verdict.delta_bic:.1f}; test 1 (Delta BIC > 10): "
          f"{'pass' if demo.verdict.test1_passed else 'fail'}; test 2 (handedness and compactness): "
          f"{'pass' if demo.verdict.test2_passed else 'fail'}")
    print("timings: " + ", ".join(f"{k} {v:.1f}" for k, v in demo.timings.items()))
    print("wrote:\n  " + "\n  ".join(str(f) for f in demo.files))
    return 0


def _cmd_simulate(args) -> int:
    from .geometry import DiscGeometry
    from .io import save_visibilities
    from .simulate import DiscModel, simulate_observation

    perturbation = None
    if args.planet_mass is not None:
        from .templates import make_template

        perturbation = make_template(args.planet_mass, args.tau0, args.beta, args.hand)
    disc = DiscModel(distance=args.distance)
    r_p = None if args.planet_au is None else args.planet_au / args.distance
    vis = simulate_observation(args.preset, disc, DiscGeometry(args.inc, args.pa, args.dra, args.ddec),
                               perturbation, r_p=r_p, phi_p=_radians(args.planet_phi), seed=args.seed)
    path = save_visibilities(vis, args.out)
    print(f"wrote {vis.n} visibilities of preset {args.preset!r} to {path}")
    return 0


def _radians(deg):
    import math

    return None if deg is None else math.radians(deg)


def _cmd_axisym(args) -> int:
    from .geometry import DiscGeometry
    from .io import load_visibilities
    from .pipeline import run_axisym

    vis = load_visibilities(args.data)
    geometry = DiscGeometry(args.inc, args.pa, args.dra, args.ddec)
    model = run_axisym(vis, args.out, geometry, distance=args.distance,
                       fit_geometry="nonparametric" if args.fit_geometry else None, progress=not args.quiet)
    print(f"total flux {model.total_flux:.4g} Jy, R_eff(95%) {model.R_eff():.3f} arcsec; outputs in {args.out}")
    return 0


def _cmd_scan(args) -> int:
    from .config import describe_config, load_config
    from .pipeline import run_scan_config

    if args.print_config:
        print(describe_config())
        return 0
    if not args.config:
        raise SystemExit("spiralbayes scan: give a CONFIG file (write a documented one with --print-config)")
    verdict, _, files = run_scan_config(load_config(args.config), progress=not args.quiet)
    print(verdict.summary())
    print("wrote:\n  " + "\n  ".join(str(f) for f in files))
    return 0


def _cmd_sample(args) -> int:
    from .config import describe_config, load_config
    from .pipeline import run_sample_config

    if args.print_config:
        print(describe_config())
        return 0
    if not args.config:
        raise SystemExit("spiralbayes sample: give a CONFIG file (write a documented one with --print-config)")
    config = load_config(args.config)
    result = run_sample_config(config, progress=not args.quiet)
    print(result.verdict)
    print(f"outputs in {Path(config['output']['dir']).resolve()} (chains under chains/)")
    return 0


def _cmd_templates(args) -> int:
    from .templates import default_bank

    bank = default_bank(rebuild=args.rebuild)
    print(f"{len(bank)} templates in the default bank")
    if args.plot:
        from .plotting.templates import plot_bank_overview

        plot_bank_overview(bank).savefig(args.plot, dpi=120, bbox_inches="tight")
        print(f"wrote {args.plot}")
    return 0


def _geometry_args(p):
    p.add_argument("--inc", type=float, default=30.0, help="inclination [deg]")
    p.add_argument("--pa", type=float, default=60.0, help="position angle, east of north [deg]")
    p.add_argument("--dra", type=float, default=0.0, help="RA offset of the disc centre [arcsec]")
    p.add_argument("--ddec", type=float, default=0.0, help="Dec offset of the disc centre [arcsec]")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="spiralbayes", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars, warnings only")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="simulate a planet, fit frank, scan, decide, plot (a few minutes)")
    p.add_argument("--out", default="spiralbayes-demo", help="output folder")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--dask", default="", help="'local' or a scheduler address to scan templates in parallel")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("simulate", help="synthetic ALMA observation of a disc (preset of Stevenson et al. 2024)")
    p.add_argument("--preset", default="fiducial")
    p.add_argument("--out", required=True, help="output file (.txt/.npz uvtable, .h5, or .ms)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--distance", type=float, default=140.0, help="[pc]")
    _geometry_args(p)
    p.add_argument("--planet-mass", type=float, default=None, help="M_p/M_th of a planted planet (none: no planet)")
    p.add_argument("--tau0", type=float, default=3.0)
    p.add_argument("--beta", type=float, default=10.0)
    p.add_argument("--hand", default="R", choices=["R", "L"])
    p.add_argument("--planet-au", type=float, default=50.0, help="planet radius [au]")
    p.add_argument("--planet-phi", type=float, default=0.0, help="planet azimuth [deg]")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("axisym", help="fit the axisymmetric profile with frank and plot it")
    p.add_argument("data", help="visibility file (uvtable, .npz, .h5 or Measurement Set)")
    p.add_argument("--out", default="spiralbayes-axisym")
    p.add_argument("--distance", type=float, default=None, help="[pc], for an au axis")
    p.add_argument("--fit-geometry", action="store_true", help="fit inc, PA and offsets with frank")
    _geometry_args(p)
    p.set_defaults(func=_cmd_axisym)

    p = sub.add_parser("scan", help="grid scan of a template bank over planet positions (TOML config)")
    p.add_argument("config", nargs="?")
    p.add_argument("--print-config", action="store_true", help="print the documented default config")
    p.set_defaults(func=_cmd_scan)

    p = sub.add_parser("sample", help="emcee posterior over planet position and geometry (TOML config)")
    p.add_argument("config", nargs="?")
    p.add_argument("--print-config", action="store_true", help="print the documented default config")
    p.set_defaults(func=_cmd_sample)

    p = sub.add_parser("templates", help="build (or load) the default template bank")
    p.add_argument("--rebuild", action="store_true")
    p.add_argument("--plot", default="", help="write a bank overview PNG here")
    p.set_defaults(func=_cmd_templates)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    level = logging.DEBUG if args.verbose else (logging.WARNING if args.quiet else logging.INFO)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        log.error("%s", exc)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
