#!/usr/bin/env python
"""Run and reduce the FARGO3D hydrodynamic reference library of issue 21.

::

    # build the three setups (CPU) and run the cases in turn, niced, restartable (hours)
    python tools/make_fargo3d_library.py --run [--cases NAME ...]
    # reduce finished (or running: latest output, marked) runs into tests/data/references/
    python tools/make_fargo3d_library.py --reduce

The cases, their parameter files and the setups are in ``tools/fargo3d_library_cases.py`` and
``tools/fargo3d/setups/``; raw outputs go to ``--runs-dir`` (default /work/fargo_runs, outside git).
A run whose directory already holds outputs is restarted from its last one (FARGO3D ``-S``); a run
with an ``.end`` stamp in ``runs-dir/logs`` is skipped. Reduction: ``tools/fargo3d_library_reduce.py``.
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fargo3d_library_cases as lib

HERE = Path(__file__).resolve().parent
FARGO3D_SOURCE = "/work/.mirror/FARGO3D+fargo3d/repo"   # or https://github.com/FARGO3D/fargo3d
FARGO3D_COMMIT = "f359328107f0f3ec6a8e99e623582485276f6bff"
OUR_SETUPS = ("spiral_beta", "spiral_dust")
log = logging.getLogger("fargo3d_library")


def clone_fargo3d(fargo_dir: Path, source: str) -> None:
    """Clone FARGO3D at :data:`FARGO3D_COMMIT` and patch ``scripts/make.py`` for Python 3."""
    if not fargo_dir.exists():
        subprocess.run(["git", "clone", "-q", source, str(fargo_dir)], check=True)
        subprocess.run(["git", "-C", str(fargo_dir), "checkout", "-q", FARGO3D_COMMIT], check=True)
    make_py = fargo_dir / "scripts/make.py"
    text = make_py.read_text()
    fixed = text.replace("for key in params.keys():", "for key in list(params.keys()):")
    if fixed != text:  # Python 3: a dict cannot change size while it is iterated
        make_py.write_text(fixed)


def build(fargo_dir: Path, setup: str) -> Path:
    """Build ``setup`` (CPU, sequential) and return its executable, kept as ``bin_<setup>/fargo3d``."""
    exe = fargo_dir / f"bin_{setup}" / "fargo3d"
    if setup in OUR_SETUPS:
        src = HERE / "fargo3d" / "setups" / setup
        if exe.exists() and exe.stat().st_mtime > max(p.stat().st_mtime for p in src.iterdir()):
            return exe  # built from the current setup files
        dest = fargo_dir / "setups" / setup
        shutil.rmtree(dest, ignore_errors=True)
        shutil.copytree(HERE / "fargo3d" / "setups" / setup, dest)
    elif exe.exists():
        return exe
    logf = fargo_dir / f"build_{setup}.log"
    with open(logf, "w") as fh:
        subprocess.run(["make", f"SETUP={setup}", "PARALLEL=0", "GPU=0"], cwd=fargo_dir, check=True,
                       stdout=fh, stderr=subprocess.STDOUT)
    exe.parent.mkdir(exist_ok=True)
    shutil.copy2(fargo_dir / "fargo3d", exe)
    log.info("built %s -> %s", setup, exe)
    return exe


def outputs(run: Path) -> list[int]:
    """Output numbers present in ``run`` (from ``gasdens<n>.dat``)."""
    return sorted(int(m.group(1)) for p in run.glob("gasdens*.dat")
                  if (m := re.fullmatch(r"gasdens(\d+)\.dat", p.name)))


def run_case(case: lib.Case, exe: Path, runs_dir: Path, nice: int) -> None:
    """Run ``case`` to its end (restarting from its last output if any); stamps in ``runs_dir/logs``.

    ``logs/<name>.start`` holds one ``epoch first_output`` line per (re)start, ``.end`` the epoch at
    the end; ``.lock`` holds the id of the driver running it, so that two drivers (two streams on
    an idle machine) never run one case at once.
    """
    logs = runs_dir / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    if (logs / f"{case.name}.end").exists():
        log.info("%s: finished already", case.name)
        return
    lock = logs / f"{case.name}.lock"
    if lock.exists() and Path(f"/proc/{lock.read_text().strip()}").exists():
        log.info("%s: being run by process %s; skipped", case.name, lock.read_text().strip())
        return
    lock.write_text(f"{os.getpid()}\n")
    try:
        _run_unlocked(case, exe, runs_dir, nice)
    finally:
        lock.unlink(missing_ok=True)


def _run_unlocked(case: lib.Case, exe: Path, runs_dir: Path, nice: int) -> None:
    logs = runs_dir / "logs"
    out = runs_dir / case.name
    if case.continues and not outputs(out):
        base = runs_dir / case.continues
        if not (logs / f"{case.continues}.end").exists():
            raise RuntimeError(f"{case.name} continues {case.continues}, which has not finished; run it first")
        shutil.rmtree(out, ignore_errors=True)   # an empty directory of an aborted start
        shutil.copytree(base, out)
        log.info("%s: continues %s from its output %d", case.name, case.continues, outputs(out)[-1])
    out.mkdir(exist_ok=True)
    cfg = logs / f"{case.name}.cfg"
    cfg.write_text(lib.planet_text(case))
    par = logs / f"{case.name}.par"
    par.write_text(lib.par_text(case, str(out), str(cfg)))
    done = outputs(out)
    n_final = lib.n_outputs(case)
    if done and done[-1] >= n_final:  # finished, e.g. by an earlier driver that was stopped
        stamp = int((out / f"gasdens{done[-1]}.dat").stat().st_mtime)
        (logs / f"{case.name}.end").write_text(f"{stamp}\n")
        log.info("%s: all %d outputs present; stamped finished", case.name, n_final)
        return
    cmd = ["nice", "-n", str(nice), str(exe), "-m"]
    if done and done[-1] > 0:
        cmd += ["-S", str(done[-1])]
    with open(logs / f"{case.name}.start", "a") as fh:
        fh.write(f"{int(time.time())} {done[-1] if done else 0}\n")
    log.info("%s: %s", case.name, " ".join(cmd + [str(par)]))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        with open(logs / f"{case.name}.log", "a") as fh:
            subprocess.run(cmd + [str(par)], cwd=exe.parent.parent, stdout=fh, stderr=subprocess.STDOUT,
                           check=True)
    finally:
        # CPU seconds of this (re)start, one line each: the run's cost whatever else the machine ran
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(logs / f"{case.name}.cpu", "a") as fh:
            fh.write(f"{after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime:.1f} "
                     f"{done[-1] if done else 0}\n")
    (logs / f"{case.name}.end").write_text(f"{int(time.time())}\n")


def wait_for(pid: int, poll_s: float = 10.0) -> None:
    """Block until process ``pid`` has exited (so that one simulation runs at a time)."""
    while Path(f"/proc/{pid}").exists():
        time.sleep(poll_s)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", action="store_true", help="build and run the cases (in table order)")
    ap.add_argument("--reduce", action="store_true", help="reduce the runs into the reference file")
    ap.add_argument("--cases", nargs="*", default=None, help="case names (default: every case, or --batch's)")
    ap.add_argument("--batch", default=None, help="only the cases of this run set, e.g. continuum")
    ap.add_argument("--fargo-dir", type=Path, default=Path("/work/fargo3d"))
    ap.add_argument("--fargo-source", default=FARGO3D_SOURCE)
    ap.add_argument("--runs-dir", type=Path, default=Path("/work/fargo_runs"))
    ap.add_argument("--nice", type=int, default=5)
    ap.add_argument("--after", type=int, default=None, help="first wait for this process id to exit")
    args, rest = ap.parse_known_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    if args.cases is None:
        args.cases = [c.name for c in lib.CASES if args.batch is None or c.batch == args.batch]
    unknown = [n for n in args.cases if n not in lib.BY_NAME]
    if unknown:
        raise SystemExit(f"--cases: unknown {unknown}; known: {list(lib.BY_NAME)}")
    if args.after:
        wait_for(args.after)
    if args.run:
        clone_fargo3d(args.fargo_dir, args.fargo_source)
        for name in args.cases:
            case = lib.BY_NAME[name]
            run_case(case, build(args.fargo_dir, case.setup), args.runs_dir, args.nice)
    if args.reduce:
        import fargo3d_library_reduce as red

        red.main(["--runs-dir", str(args.runs_dir), "--fargo-dir", str(args.fargo_dir), "--cases", *args.cases, *rest])


if __name__ == "__main__":
    main()
