"""The ``spiralbayes`` command: demo, simulate, axisym, scan, sample, limits, survey, forecast, compare, templates.

User errors (bad options, missing or bad input files, configuration values, missing optional
dependencies, a checkpoint for other inputs, an output that would replace a file without
``--overwrite``) are printed as one line, ``spiralbayes: error: ...``, with exit status 2;
``--debug`` shows the traceback instead. Numeric options are checked as they are parsed, so an
error names the option as typed, in its own units (``argument --inc: -5 is outside [0, 90) deg``).
``-v`` raises spiralbayes' own log level to DEBUG, not that of the libraries it uses. Ctrl-C exits
with status 130 (scans resume when rerun).

Why this module is long: it is the parser of ten commands, every option with its help, unit and
check beside it; split, an option and the validator that names it in errors would live apart.
"""

from __future__ import annotations

import argparse
import logging
import math
import re
import sys
import warnings
from pathlib import Path

from .exceptions import InputError

__all__ = ["main"]

log = logging.getLogger("spiralbayes")

DESCRIPTION = """Search ALMA visibilities for planet-driven dust spirals (Stevenson et al. 2024) and
turn the search into Bayesian inference. Commands: demo (an end-to-end example), simulate
(synthetic ALMA data), axisym (frank fit), scan (grid scan of spiral templates, verdict and
heatmaps), sample (emcee posterior), limits (exclusion limits and completeness), survey (many
discs on Dask, one table), forecast
(time on source a planet needs), compare (image-plane comparisons with CASA), templates (the
built-in template bank). Run
'spiralbayes COMMAND -h' for a command's options; 'spiralbayes scan --print-config' writes a
documented configuration file."""

USER_ERRORS = (ValueError, LookupError, OSError, ImportError)
"""Exceptions reported as one line (spiralbayes' own errors subclass these or SpiralbayesError)."""


def _cmd_demo(args) -> int:
    from .pipeline import run_demo
    from .pipeline.outputs import check_simulated_folder

    check_simulated_folder(args.out, args.overwrite)
    scheduler = _scheduler(args)
    demo = run_demo(args.out, seed=args.seed, progress=not args.quiet,
                    scheduler=scheduler)
    print(demo.verdict.summary())
    print(tests_line(demo.verdict))
    print("timings: " + ", ".join(f"{k} {v:.1f}" for k, v in demo.timings.items()))
    print(f"templates: {len(demo.scan.templates)} of the default bank (tau0 3, beta 10, H/r 0.07; every "
          "morphology: compromise, hydro, wakeflow; the whole bank spans 4 masses x 4 tau0 x 2 beta x 3 H/r x "
          "3 morphologies x 2 hands = 576): docs/templates.md")
    print("wrote:\n  " + "\n  ".join(str(f) for f in demo.files))
    return 0


def _scheduler(args) -> str | None:
    """``--scheduler``, or the value of its former spelling ``--dask`` with a FutureWarning."""
    if getattr(args, "dask_alias", None) is not None:
        warnings.warn("--dask is renamed --scheduler; give --scheduler " + (args.dask_alias or "''"),
                      FutureWarning, stacklevel=2)
        return args.scheduler or args.dask_alias
    return args.scheduler


def _refuse_existing(path, option: str, overwrite: bool) -> None:
    """An InputError naming ``option`` when ``path`` exists and ``overwrite`` was not asked for."""
    if Path(path).exists() and not overwrite:
        raise InputError(f"{option} {path} already exists: refusing to replace it; give another {option} "
                         "or add --overwrite")


def _pass(flag) -> str:
    return "not run" if flag is None else ("pass" if flag else "fail")


def tests_line(verdict) -> str:
    """One line with the verdict's ΔBIC and each test's outcome, test 3 named as it was decided
    (the demo runs the default thresholds)."""
    if verdict.test3_method == "nested":
        test3 = (f"test 3 (a spiral in addition to the best competing asymmetry models, nested Delta BIC "
                 f"{verdict.nested_delta_bic:.1f} > {verdict.nested_threshold:g})")
    elif verdict.test3_method is None:
        test3 = "test 3 (competing asymmetry models)"
    else:
        test3 = f"test 3 (the spiral beats the best competing asymmetry model by > {verdict.alternative_threshold:g})"
    return (f"Delta BIC = {verdict.delta_bic:.1f}; test 1 (Delta BIC > 10): {_pass(verdict.test1_passed)}; "
            f"test 2 (handedness and compactness): {_pass(verdict.test2_passed)}; "
            f"{test3}: {_pass(verdict.test3_passed)}; outcome: {verdict.outcome}")


def _cmd_simulate(args) -> int:
    from .geometry import DiscGeometry
    from .io import save_visibilities
    from .simulate import DiscModel, simulate_observation

    _refuse_existing(args.out, "--out", args.overwrite)
    perturbation = None
    if args.planet_mass is not None:
        from .templates import make_template

        perturbation = make_template(args.planet_mass, args.tau0, args.beta, args.hand)
    disc = DiscModel(distance=args.distance)
    r_p = None if args.planet_au is None else args.planet_au / args.distance
    vis = simulate_observation(args.preset, disc, DiscGeometry(args.inc, args.pa, args.dra, args.ddec),
                               perturbation, r_p=r_p, phi_p=_radians(args.planet_phi), seed=args.seed,
                               gains=_gain_errors(args))
    path = save_visibilities(vis, args.out)
    print(f"wrote {vis.n} visibilities of preset {args.preset!r} to {path}")
    return 0


def _gain_errors(args):
    """GainErrors from --phase-rms/--amp-rms/--gain-coherence, or None when neither rms is given."""
    if args.phase_rms is None and args.amp_rms is None:
        if args.gain_coherence is not None:
            raise InputError("--gain-coherence needs --phase-rms DEG or --amp-rms FRAC (the gain errors to simulate)")
        return None
    from .simulate import GainErrors

    given = {"phase_rms_deg": 0.0 if args.phase_rms is None else args.phase_rms,
             "amp_rms": 0.0 if args.amp_rms is None else args.amp_rms, "seed": args.seed}
    if args.gain_coherence is not None:
        given["coherence_s"] = args.gain_coherence
    return GainErrors(**given)


def _radians(deg):
    return None if deg is None else math.radians(deg)


def _cmd_axisym(args) -> int:
    from .geometry import DiscGeometry
    from .io import load_visibilities
    from ._hdf5 import require_file
    from ._provenance import data_hash
    from .pipeline import run_axisym
    from .pipeline.outputs import check_output_folder

    require_file(args.data, "visibility file")
    if (args.inc is None or args.pa is None) and not args.fit_geometry:
        raise InputError("axisym needs the disc geometry: give --inc and --pa [deg] (and --dra/--ddec [arcsec] "
                         "if off-centre), or --fit-geometry to fit it with frank")
    vis = load_visibilities(args.data)
    check_output_folder(args.out, data_hash(vis.u, vis.v, vis.V, vis.weights), args.overwrite,
                        filename="axisym_model.h5", option="--out")
    geometry = None if args.inc is None or args.pa is None else DiscGeometry(args.inc, args.pa, args.dra, args.ddec)
    model = run_axisym(vis, args.out, geometry, distance=args.distance,
                       fit_geometry="nonparametric" if args.fit_geometry else None, progress=not args.quiet)
    print(f"sky (projected) flux {model.total_flux * model.geometry.cos_inc:.4g} Jy, face-on (deprojected) flux "
          f"{model.total_flux:.4g} Jy, R_eff(95%) {model.R_eff():.3f} arcsec; outputs in {args.out}")
    return 0


def _cmd_scan(args) -> int:
    from .config import describe_config, load_config
    from .pipeline import run_scan

    if args.print_config:
        print(describe_config())
        return 0
    if not args.config:
        raise InputError("scan needs a CONFIG file: give one (write a documented one with --print-config)")
    run = run_scan(load_config(args.config), progress=not args.quiet, force_resume=args.force_resume,
                   overwrite=args.overwrite)
    print(run.verdict.summary())
    print(tests_line(run.verdict))
    if run.follow_up is not None:
        g = run.follow_up.geometry
        print(f"\nAfter refitting the geometry (inc {g.inc:.3f} deg, PA {g.PA:.3f} deg, dRA {1e3 * g.dRA:.2f} mas, "
              f"dDec {1e3 * g.dDec:.2f} mas) and scanning again:\n{run.follow_up.verdict.summary()}")
    print("wrote:\n  " + "\n  ".join(str(f) for f in run.files))
    return 0


def _cmd_sample(args) -> int:
    from .config import describe_config, load_config
    from .pipeline import run_sample_config

    if args.print_config:
        print(describe_config())
        return 0
    if not args.config:
        raise InputError("sample needs a CONFIG file: give one (write a documented one with --print-config)")
    config = load_config(args.config)
    result = run_sample_config(config, progress=not args.quiet)
    print(result.verdict)
    print(f"outputs in {Path(config['output']['dir']).resolve()} (chains under chains/)")
    return 0


def _cmd_compare(args) -> int:
    from .config import describe_config, load_config
    from .pipeline import run_compare_config

    if args.print_config:
        print(describe_config())
        return 0
    if not args.config:
        raise InputError("compare needs a CONFIG file: give one (write a documented one with --print-config)")
    from .exceptions import MissingDependencyError

    try:
        result = run_compare_config(load_config(args.config), progress=not args.quiet)
    except MissingDependencyError as exc:  # an ImportError, which main() does not catch
        log.error("%s", exc)
        return 2
    print(result.verdict.summary())
    print(Path(result.files[-2]).read_text(), end="")
    print("wrote:\n  " + "\n  ".join(str(f) for f in result.files))
    return 0


def _cmd_limits(args) -> int:
    from .config import describe_config, load_config
    from .pipeline import run_limits_config, run_limits_demo
    from .pipeline.outputs import check_simulated_folder

    if args.print_config:
        print(describe_config())
        return 0
    if args.demo:
        check_simulated_folder(args.out, args.overwrite)
        run = run_limits_demo(args.out, progress=not args.quiet)
    elif args.config:
        run = run_limits_config(load_config(args.config), progress=not args.quiet)
    else:
        raise InputError("limits needs a CONFIG file or --demo (write a documented config with "
                         "--print-config)")
    print(run.table)
    print("wrote:\n  " + "\n  ".join(str(f) for f in run.files))
    return 0


def _cmd_survey(args) -> int:
    from .pipeline.survey import run_survey, run_survey_demo

    if args.demo:
        run = run_survey_demo(args.out, scheduler=args.scheduler, n_workers=args.workers, progress=not args.quiet)
    elif args.survey:
        run = run_survey(args.survey, scheduler=args.scheduler, n_workers=args.workers, progress=not args.quiet)
    else:
        raise InputError("survey needs a SURVEY file or --demo (see examples/taurus_survey.toml)")
    print(Path(run.files[1]).read_text(), end="")
    print("wrote:\n  " + "\n  ".join(str(f) for f in run.files))
    if run.failed:  # after the table is written: the exit status tells a batch script that discs failed
        print(f"{len(run.failed)} disc(s) failed: {', '.join(run.failed)} (their error is in the table)",
              file=sys.stderr)
    return run.exit_code


def _cmd_forecast(args) -> int:
    from .pipeline import run_forecast
    from .simulate import get_preset

    wavelength = args.wavelength or get_preset(args.preset[0]).wavelength
    forecasts = run_forecast({"mass": args.mass, "tau0": args.tau0, "beta": args.beta, "hand": args.hand,
                              "wavelength": wavelength, "distance": args.distance, "disc_tau": args.disc_tau,
                              "inc": args.inc, "pa": args.pa, "r_au": args.r_au, "presets": args.preset,
                              "time": args.time, "sensitivity": args.sensitivity})
    for fc in forecasts:
        print(fc.summary(args.probability))
    return 0


def _cmd_templates(args) -> int:
    if args.fit_learned:
        return _fit_learned(args)
    from .templates import default_bank

    bank = default_bank(rebuild=args.rebuild)
    h_ps = sorted({float(t.h_p) for t in bank})
    morphologies = sorted({str(t.provenance.get("variant") or "compromise") for t in bank})
    print(f"{len(bank)} templates in the default bank (H/r = {', '.join(f'{h:g}' for h in h_ps)}; morphologies "
          f"{', '.join(morphologies)}: limits hold for every morphology); the single-morphology bank of the "
          "paper's comparisons is [templates] bank = \"compromise\"")
    if args.plot:
        from .pipeline import save_figure
        from .plotting.templates import plot_bank_overview

        save_figure(plot_bank_overview(bank), args.plot, dpi=120, bbox_inches="tight")
        print(f"wrote {args.plot}")
    return 0


def _fit_learned(args) -> int:
    from .templates.learned import LearnedTemplateModel, reference_files

    _refuse_existing(args.fit_learned, "--fit-learned", args.overwrite)
    paths = args.references or reference_files()
    model = LearnedTemplateModel.from_references(paths)
    model.save(args.fit_learned)
    bounds = ", ".join(f"{k} {lo:.3g}-{hi:.3g}" for k, (lo, hi) in model.bounds.items())
    print(f"wrote {args.fit_learned}: {len(model.run_names)} training runs; box {bounds}; use it with "
          f"[templates] bank = \"learned\", learned_model = \"{args.fit_learned}\"")
    return 0


def _geometry_args(p, required: bool = False):
    """--inc, --pa, --dra, --ddec; with ``required`` inc and PA have no default (the data's disc, not a guess)."""
    p.add_argument("--inc", type=_inclination, default=None if required else 30.0,
                   help="inclination [deg], in [0, 90)" + (" (required unless --fit-geometry)" if required else ""))
    p.add_argument("--pa", type=_finite, default=None if required else 60.0,
                   help="position angle, east of north [deg]"
                   + (" (required unless --fit-geometry)" if required else ""))
    p.add_argument("--dra", type=_finite, default=0.0, help="RA offset of the disc centre [arcsec]")
    p.add_argument("--ddec", type=_finite, default=0.0, help="Dec offset of the disc centre [arcsec]")


def _common_flags(p, default) -> None:
    """-v, --debug, -q: accepted before and after the command (``default=SUPPRESS`` keeps the first)."""
    p.add_argument("-v", "--verbose", action="store_true", default=default,
                   help="debug messages from spiralbayes (not from the libraries it uses)")
    p.add_argument("--debug", action="store_true", default=default, help="show the full traceback of errors")
    p.add_argument("-q", "--quiet", action="store_true", default=default, help="no progress bars, warnings only")


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number")
    return value


def _finite(text: str) -> float:
    """Any finite number (angles, offsets)."""
    return _number(text)


def _positive(text: str) -> float:
    """A finite number > 0 (distances, radii, masses, times)."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text} must be > 0")
    return value


def _non_negative(text: str) -> float:
    """A finite number >= 0 (0 meaning 'the default' where the help says so)."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text} must be >= 0")
    return value


def _amp_fraction(text: str) -> float:
    """A fractional amplitude error in [0, 0.3) (0.05 = 5 %)."""
    value = _number(text)
    if not 0 <= value < 0.3:
        raise argparse.ArgumentTypeError(f"{text} is not a fraction in [0, 0.3), e.g. 0.05 for 5 %")
    return value


def _inclination(text: str) -> float:
    value = _number(text)
    if not 0 <= value < 90:
        raise argparse.ArgumentTypeError(f"{text} is outside [0, 90) deg: give the inclination in degrees "
                                         "(0 = face on; an edge-on disc cannot be deprojected)")
    return value


def _whole_number(minimum: int, meaning: str = ""):
    """An argparse type: a whole number >= ``minimum`` (``meaning`` says what it is in the message)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{text} must be >= {minimum}{meaning}")
        return value
    return parse


_count = _whole_number(1)  # worker counts
_seed = _whole_number(0, " (a random seed)")


def _probability(text: str) -> float:
    value = _number(text)
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"{text} is not a probability in (0, 1), e.g. 0.9")
    return value


def _preset_names() -> list[str]:
    from .simulate import PRESETS

    return list(PRESETS)


class _Parser(argparse.ArgumentParser):
    """Defaults shown in --help, -v/--debug/-q accepted after the command, errors on one line (exit 2)."""

    def __init__(self, *args, common_flags: bool = True, **kwargs):
        super().__init__(*args, **kwargs)
        if common_flags:
            _common_flags(self, argparse.SUPPRESS)

    def add_argument(self, *args, **kwargs):
        default = kwargs.get("default")
        shown = args and args[0].startswith("-") and default not in (None, False, "", argparse.SUPPRESS)
        help_text = kwargs.get("help")
        if shown and help_text is not argparse.SUPPRESS and "%(default)" not in (help_text or ""):
            kwargs["help"] = f"{help_text or ''} (default: %(default)s)".strip()
        return super().add_argument(*args, **kwargs)

    def error(self, message):
        """One line naming the option as typed, and where the options are listed; exit status 2."""
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see '{self.prog} -h')\n")


SCHEDULER_HELP = ("Dask engine of the template scan: 'serial', 'local' (a LocalCluster on this machine) or "
                  "tcp://HOST:PORT of a running scheduler (none: serial)")


def build_parser() -> argparse.ArgumentParser:
    from ._version import __version__
    from .settings import DEFAULT_DISTANCE_PC
    from .simulate.gains import GainErrors

    parser = _Parser(prog="spiralbayes", description=DESCRIPTION, common_flags=False)
    _common_flags(parser, False)
    parser.add_argument("--version", action="version", version=f"spiralbayes {__version__}",
                        help="print the version and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser, metavar="COMMAND",
                                help="one of the commands below ('spiralbayes COMMAND -h' for its options)")

    p = sub.add_parser("demo", help="simulate a planet, fit frank, scan, decide, plot (a few minutes)")
    p.add_argument("--out", default="spiralbayes-demo", help="output folder")
    p.add_argument("--seed", type=_seed, default=1, help="random seed of the simulated noise")
    p.add_argument("--overwrite", action="store_true", help="replace the scan of real data in --out")
    p.add_argument("--scheduler", default=None, help=SCHEDULER_HELP)
    p.add_argument("--dask", dest="dask_alias", default=None, help=argparse.SUPPRESS)  # former name of --scheduler
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("simulate", help="synthetic ALMA observation of a disc (preset of Stevenson et al. 2024)")
    p.add_argument("--preset", default="fiducial", choices=_preset_names(), help="set-up of Table 1")
    p.add_argument("--out", required=True,
                   help="output file (.txt/.npz uvtable, .h5, or .ms); an existing one is kept unless --overwrite")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--seed", type=_seed, default=0, help="random seed of the noise and of any gain errors")
    p.add_argument("--distance", type=_positive, default=DEFAULT_DISTANCE_PC, help="distance [pc]")
    _geometry_args(p)
    p.add_argument("--planet-mass", type=_positive, default=None,
                   help="M_p/M_th of a planted planet (none: no planet)")
    p.add_argument("--tau0", type=_positive, default=3.0, help="optical depth of the planted template at its radius")
    p.add_argument("--beta", type=_positive, default=10.0, help="cooling time of the planted template [orbits]")
    p.add_argument("--hand", default="R", choices=["R", "L"], help="handedness of the planted spiral")
    p.add_argument("--planet-au", type=_positive, default=50.0, help="planet radius [au]")
    p.add_argument("--planet-phi", type=_finite, default=0.0, help="planet azimuth [deg]")
    p.add_argument("--phase-rms", type=_non_negative, default=None, metavar="DEG",
                   help="rms of residual antenna-based phase errors [deg] (none: no gain errors)")
    p.add_argument("--amp-rms", type=_amp_fraction, default=None, metavar="FRAC",
                   help="rms of residual antenna-based fractional amplitude errors, e.g. 0.05 (none: no gain errors)")
    p.add_argument("--gain-coherence", type=_positive, default=None, metavar="S",
                   help=f"coherence time of the gain errors [s] (none: {GainErrors.coherence_s:g} s)")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("axisym", help="fit the axisymmetric profile with frank and plot it")
    p.add_argument("data", help="visibility file (uvtable, .npz, .h5 or Measurement Set)")
    p.add_argument("--out", default="spiralbayes-axisym", help="output folder")
    p.add_argument("--overwrite", action="store_true", help="replace a fit of other data in --out")
    p.add_argument("--distance", type=_positive, default=None, help="distance [pc], for an au axis")
    p.add_argument("--fit-geometry", action="store_true",
                   help="fit inc, PA and offsets with frank (started from --inc/--pa when given)")
    _geometry_args(p, required=True)
    p.set_defaults(func=_cmd_axisym)

    config_help = ("TOML configuration file (write a documented one with --print-config); relative paths in it "
                   "are taken relative to its folder")
    p = sub.add_parser("scan", help="grid scan of a template bank over planet positions (TOML config)",
                       description="Grid scan of spiral templates over planet positions, then the verdict "
                                   "(Delta BIC and the handedness test) and heatmaps. An interrupted scan "
                                   "resumes from OUTPUT/scan_checkpoint.h5 when run again with the same inputs.")
    p.add_argument("config", nargs="?", metavar="CONFIG", help=config_help)
    p.add_argument("--print-config", action="store_true", help="print the documented default config")
    p.add_argument("--force-resume", action="store_true",
                   help="resume the checkpoint even if it was written for other inputs (data, frank model, "
                        "templates, geometry, quadrature); its completed templates are kept as they are")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of a scan of other data in [output] dir")
    p.set_defaults(func=_cmd_scan)

    p = sub.add_parser("sample", help="emcee posterior over planet position and geometry (TOML config)")
    p.add_argument("config", nargs="?", metavar="CONFIG",
                   help="TOML configuration file (the scan's, with [sample] and [priors]; --print-config "
                        "writes a documented one)")
    p.add_argument("--print-config", action="store_true", help="print the documented default config")
    p.set_defaults(func=_cmd_sample)

    p = sub.add_parser("compare", help="the scan beside CLEAN residuals and gap depth (needs the casa extra)")
    p.add_argument("config", nargs="?", metavar="CONFIG", help=config_help)
    p.add_argument("--print-config", action="store_true", help="print the documented default config")
    p.set_defaults(func=_cmd_compare)

    p = sub.add_parser("limits", help="exclusion limits, completeness and the paper's Table 3 (TOML config)")
    p.add_argument("config", nargs="?", metavar="CONFIG",
                   help=config_help + "; its [output] dir holds the scan to reuse (not needed with --demo)")
    p.add_argument("--print-config", action="store_true", help="print the documented default config")
    p.add_argument("--demo", action="store_true", help="Table 3 for a synthetic Taurus-comparison disc")
    p.add_argument("--out", default="spiralbayes-limits-demo", help="output folder of --demo")
    p.add_argument("--overwrite", action="store_true", help="with --demo: replace the scan of real data in --out")
    p.set_defaults(func=_cmd_limits)

    p = sub.add_parser("survey", help="many discs in one command: search, verdict, limits, one table (Dask)",
                       description="Run the scan, verdict (tests 1-3), limits and (for candidates) the posterior "
                                   "over the discs of a survey file on dask.distributed; writes one table (ECSV, "
                                   "Markdown), figures and provenance, and each disc's usual outputs. A rerun "
                                   "skips finished stages.")
    p.add_argument("survey", nargs="?", metavar="SURVEY", help="survey TOML file (see examples/taurus_survey.toml)")
    p.add_argument("--demo", action="store_true", help="the six synthetic Taurus discs of examples/taurus_survey.toml")
    p.add_argument("--out", default="spiralbayes-survey-demo", help="output folder of --demo")
    p.add_argument("--scheduler", default=None,
                   help="tcp://HOST:PORT of a running Dask scheduler, 'local', 'slurm', 'pbs' or 'serial' "
                        "(none: [survey] scheduler, else a LocalCluster sized to the machine)")
    p.add_argument("--workers", type=_count, default=None,
                   help="LocalCluster worker processes (none: one per available core)")
    p.set_defaults(func=_cmd_survey)

    p = sub.add_parser("forecast", help="expected Delta chi^2, detection probability and time needed for a planet")
    p.add_argument("--preset", nargs="+", default=["fiducial"], choices=_preset_names(), metavar="PRESET",
                   help=f"one or more set-ups of Table 1: {', '.join(_preset_names())}")
    p.add_argument("--mass", type=_positive, default=1.0, help="planet mass M_p/M_th")
    p.add_argument("--tau0", type=_positive, default=3.0, help="optical depth of the template at the planet")
    p.add_argument("--beta", type=_positive, default=10.0, help="cooling time of the template [orbits]")
    p.add_argument("--hand", default="R", choices=["R", "L"], help="handedness of the spiral")
    p.add_argument("--r-au", type=_positive, default=50.0, help="planet radius [au]")
    p.add_argument("--distance", type=_positive, default=DEFAULT_DISTANCE_PC, help="distance [pc]")
    p.add_argument("--disc-tau", type=_non_negative, default=0.0,
                   help="disc optical depth at 50 au (0: the template's tau0)")
    p.add_argument("--inc", type=_inclination, default=30.0, help="inclination [deg], in [0, 90)")
    p.add_argument("--pa", type=_finite, default=60.0, help="position angle [deg]")
    p.add_argument("--time", type=_positive, default=None, help="total time on source [min] (none: the preset's)")
    p.add_argument("--sensitivity", type=_positive, default=None,
                   help="image noise [Jy/beam] (none: the preset's, scaled as t^-1/2)")
    p.add_argument("--wavelength", type=_non_negative, default=0.0,
                   help="template wavelength [m] (0: the first preset's)")
    p.add_argument("--probability", type=_probability, default=0.9,
                   help="detection probability for the time estimate, in (0, 1)")
    p.set_defaults(func=_cmd_forecast)

    p = sub.add_parser("templates", help="build (or load) the default template bank")
    p.add_argument("--rebuild", action="store_true", help="compute the bank again instead of loading the cached one")
    p.add_argument("--plot", default="", help="write a bank overview PNG here")
    p.add_argument("--fit-learned", default="", metavar="FILE",
                   help="instead: fit the learned template model (continuous in disc physics) to reduced FARGO3D "
                        "runs and save it here, for [templates] bank = \"learned\" (a minute)")
    p.add_argument("--references", nargs="+", default=None, metavar="H5",
                   help="with --fit-learned: the reduced FARGO3D files (default: the repository's "
                        "tests/data/references training files)")
    p.add_argument("--overwrite", action="store_true", help="with --fit-learned: replace an existing FILE")
    p.set_defaults(func=_cmd_templates)
    return parser


_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _join_negative_numbers(argv: list[str]) -> list[str]:
    """``--dra -1.9e-3`` -> ``--dra=-1.9e-3`` (argparse takes '-1.9e-3' for an option, not a number)."""
    out: list[str] = []
    for token in argv:
        if out and _NUMBER.match(token) and out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(_join_negative_numbers(argv))
    level = logging.DEBUG if args.verbose else (logging.WARNING if args.quiet else logging.INFO)
    # the root stays at WARNING: -v is for our messages, not matplotlib's or distributed's debug lines
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    previous_level = log.level
    log.setLevel(level)
    formatwarning = warnings.formatwarning
    if not args.debug:  # a warning is one line of ours, not a source line of whichever module raised it
        warnings.formatwarning = _one_line_warning
    try:
        return args.func(args)
    except KeyboardInterrupt:
        if args.debug:
            raise
        print("spiralbayes: interrupted (a scan resumes from its checkpoint when run again)", file=sys.stderr)
        return 130
    except Exception as exc:
        from .exceptions import SpiralbayesError

        if args.debug or not isinstance(exc, (SpiralbayesError, *USER_ERRORS)):
            raise
        print(f"spiralbayes: error: {_message(exc)} (--debug shows the traceback)", file=sys.stderr)
        return 2
    finally:
        warnings.formatwarning = formatwarning
        log.setLevel(previous_level)


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """``spiralbayes: warning: Category: message`` (``--debug`` shows the file, line and source)."""
    return f"spiralbayes: warning: {category.__name__}: {' '.join(str(message).split())}\n"


def _message(exc: Exception) -> str:
    """One line: KeyError's quotes removed, newlines folded."""
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
    text = " ".join(str(text).split())
    return text or exc.__class__.__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
