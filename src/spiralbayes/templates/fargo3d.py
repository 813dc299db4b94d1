"""Read 2-D FARGO3D outputs (Benítez-Llambay & Masset 2016) into a :class:`SpiralTemplate`.

Output layout (FARGO3D ``src/output.c``, ``src/split.c``):

* fields ``{fluid}{dens|energy|vx|vy}{n}.dat`` — raw float64, no header, ghost cells removed,
  shape ``(NZ, NY, NX)`` in C order with X = azimuth and Y = radius in cylindrical runs;
* unmerged runs write one file per MPI rank, ``{fluid}dens{n}_{rank}.dat``, each holding the
  rank's block of radii (``grid{rank:03d}.inf`` lists Y0/YN; otherwise FARGO3D's round-robin
  split is assumed: the first ``NY mod ncpu`` ranks get one extra row);
* ``domain_x.dat``: NX + 1 azimuth edges; ``domain_y.dat``: NY + 1 radial edges plus 3 ghost
  edges at each end (dropped here); centres are the means of neighbouring edges;
* ``variables.par``: ``KEY value`` lines (NX, NY, NZ, ASPECTRATIO, FLARINGINDEX, SIGMA0,
  SIGMASLOPE, ...); ``planet0.dat``: ``output x y z vx vy vz mass time omegaframe`` per output.
* Some forks name dust fields ``dustdens1_{n}.dat``; both spellings are accepted, and
  ``pattern=`` takes any other (e.g. ``"mydust_{n}.dat"``).

The map is rotated so the planet sits at φ = 0 (an integer roll of cells plus linear
interpolation for the sub-cell remainder), then passed through the same S22 radiative transfer as
the built-in generator (:func:`~spiralbayes.templates.radiative.template_from_perturbation`).
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ..exceptions import InputError, MissingFileError
from ..settings import DEFAULT_MSTAR_MSUN
from ..units import TWO_PI
from .radiative import template_from_perturbation
from .template import SpiralTemplate, validate_hand

__all__ = ["read_fargo3d", "read_variables", "read_field", "read_planet", "read_domain"]

log = logging.getLogger(__name__)

NGHY = 3  # ghost cells at each radial end of domain_y.dat


def _need(path: Path, what: str) -> Path:
    if not path.exists():
        raise MissingFileError(
            f"FARGO3D {what} {path.name!r} not found in {path.parent}: point `directory` at the run's "
            "output directory (OUTPUTDIR, which holds variables.par, domain_x.dat, domain_y.dat and "
            "the field files)"
        )
    return path


def read_variables(directory) -> dict:
    """Parse ``variables.par`` into ``{KEY: value}`` (keys upper-case; numbers converted)."""
    path = _need(Path(directory) / "variables.par", "parameter file")
    out: dict[str, int | float | str] = {}
    for line in path.read_text().splitlines():
        parts = line.split(None, 1)
        if len(parts) < 2 or parts[0].startswith("#"):
            continue
        key, value = parts[0].upper(), parts[1].strip()
        for conv in (int, float):
            try:
                out[key] = conv(value)
                break
            except ValueError:
                continue
        else:
            out[key] = value
    return out


def read_domain(directory, params: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(phi_edges, r_edges)`` from ``domain_x.dat`` and ``domain_y.dat`` (radial ghosts dropped)."""
    directory = Path(directory)
    params = params if params is not None else read_variables(directory)
    phi_e = np.loadtxt(_need(directory / "domain_x.dat", "azimuthal grid"), ndmin=1)
    r_all = np.loadtxt(_need(directory / "domain_y.dat", "radial grid"), ndmin=1)
    nx = int(params.get("NX", phi_e.size - 1))
    ny = int(params.get("NY", r_all.size - 1 - 2 * NGHY))
    if phi_e.size != nx + 1:
        raise InputError(f"domain_x.dat has {phi_e.size} edges, expected NX + 1 = {nx + 1} (variables.par)")
    if r_all.size != ny + 1 + 2 * NGHY:
        raise InputError(
            f"domain_y.dat has {r_all.size} edges, expected NY + 1 + 2*{NGHY} = {ny + 1 + 2 * NGHY} "
            "(FARGO3D writes 3 ghost edges at each end)"
        )
    return phi_e, r_all[NGHY: NGHY + ny + 1]


def _field_names(fluid: str, field: str, n: int, pattern: str | None):
    """Candidate merged-file names for ``fluid``'s ``field`` at output ``n``."""
    if pattern:
        return [pattern.format(fluid=fluid, field=field, n=n)]
    names = [f"{fluid}{field}{n}.dat"]
    m = re.fullmatch(r"([A-Za-z]+?)(\d+)", fluid)
    if m:  # fork style: dustdens1_{n}.dat
        names.append(f"{m.group(1)}{field}{m.group(2)}_{n}.dat")
    return names


def _rank_blocks(directory: Path, ncpu: int, ny: int, nz: int):
    """(y0, ny_local) per rank, from grid{rank:03d}.inf or FARGO3D's round-robin split."""
    blocks = []
    for rank in range(ncpu):
        inf = directory / f"grid{rank:03d}.inf"
        if inf.exists():
            vals = np.loadtxt(inf, skiprows=1, ndmin=1)
            y0, yn = int(vals[1]), int(vals[2])
            blocks.append((y0, yn - y0 + 1))
        else:
            if nz != 1:
                raise InputError(
                    f"per-rank output of a 3-D run needs {inf.name} (written by FARGO3D) to place the blocks"
                )
            rest, base = ny % ncpu, ny // ncpu
            if rank < rest:
                blocks.append((rank * (base + 1), base + 1))
            else:
                blocks.append((rank * base + rest, base))
    return blocks


def read_field(directory, fluid: str, field: str, n: int, params: dict | None = None,
               pattern: str | None = None) -> np.ndarray:
    """A FARGO3D field as an ``(NY, NX)`` array (radius × azimuth), merged or per-rank files.

    Raises ``FileNotFoundError`` naming the files looked for.
    """
    directory = Path(directory)
    params = params if params is not None else read_variables(directory)
    try:
        nx, ny, nz = int(params["NX"]), int(params["NY"]), int(params.get("NZ", 1))
    except KeyError as exc:
        raise InputError(f"variables.par in {directory} lacks {exc.args[0]}; is it a FARGO3D output?") from None
    if nz != 1:
        raise InputError(f"NZ = {nz}: only 2-D (r, φ) FARGO3D runs are supported; take a 2-D run")
    names = _field_names(fluid, field, n, pattern)
    for name in names:
        path = directory / name
        if path.exists():
            data = np.fromfile(path, dtype=np.float64)
            if data.size != nx * ny * nz:
                raise InputError(
                    f"{path} holds {data.size} values, expected NX*NY*NZ = {nx * ny * nz}; "
                    "is it from this run (check variables.par)?"
                )
            return data.reshape(nz, ny, nx)[0]
    # per-rank files
    for name in names:
        stem = name[:-4]
        ranks = sorted(directory.glob(f"{stem}_*.dat"), key=lambda p: int(p.stem.rsplit("_", 1)[1])
                       if p.stem.rsplit("_", 1)[1].isdigit() else -1)
        ranks = [p for p in ranks if p.stem.rsplit("_", 1)[1].isdigit()]
        if not ranks:
            continue
        ids = [int(p.stem.rsplit("_", 1)[1]) for p in ranks]
        if ids != list(range(len(ids))):
            raise MissingFileError(f"per-rank files {stem}_*.dat are incomplete: found ranks {ids}")
        out = np.empty((ny, nx))
        for p, (y0, nyl) in zip(ranks, _rank_blocks(directory, len(ranks), ny, nz)):
            block = np.fromfile(p, dtype=np.float64)
            if block.size != nyl * nx:
                raise InputError(
                    f"{p.name} holds {block.size} values, expected {nyl} radii x NX = {nyl * nx} "
                    f"for {len(ranks)} ranks; add the run's grid*.inf files or merge the outputs"
                )
            out[y0: y0 + nyl] = block.reshape(nyl, nx)
        return out
    looked = ", ".join(names + [n[:-4] + "_<rank>.dat" for n in names])
    raise MissingFileError(
        f"FARGO3D field {field!r} of fluid {fluid!r} at output {n} not found in {directory} "
        f"(looked for {looked}); check `fluid` (e.g. 'gas', 'dust1'), the output number, or pass "
        "`pattern=` with the file naming of your run"
    )


def read_planet(directory, n: int, planet: int = 0) -> dict:
    """Planet state at output ``n`` from ``planet{planet}.dat``: ``r, phi, mass`` (code units)."""
    path = _need(Path(directory) / f"planet{planet}.dat", "planet file")
    rows = np.loadtxt(path, ndmin=2)
    match = rows[rows[:, 0].astype(int) == int(n)]
    if match.size == 0:
        raise InputError(f"{path.name} has no row for output {n} (outputs {rows[0, 0]:g}–{rows[-1, 0]:g})")
    row = match[-1]
    x, y = row[1], row[2]
    return {"r": float(np.hypot(x, y)), "phi": float(np.arctan2(y, x)),
            "mass": float(row[7]) if row.size > 7 else float("nan")}


def _rotate_to_planet(field: np.ndarray, phi_centres: np.ndarray, phi_p: float):
    """Resample ``field(r, φ)`` onto ``φ_k = 2πk/NX`` measured from the planet (periodic-linear)."""
    nx = phi_centres.size
    dphi = TWO_PI / nx
    phi_new = TWO_PI * np.arange(nx) / nx
    pos = ((phi_p + phi_new - phi_centres[0]) / dphi) % nx
    j0 = np.floor(pos).astype(np.int64) % nx
    w = pos - np.floor(pos)
    if np.all(w < 1e-9):
        return field[:, j0], phi_new
    return (1.0 - w) * field[:, j0] + w * field[:, (j0 + 1) % nx], phi_new


def _azimuthal_mean_at(field: np.ndarray, r: np.ndarray, r0: float) -> float:
    return float(np.interp(r0, r, field.mean(axis=1)))


def read_fargo3d(
    directory,
    output: int,
    tau0: float,
    *,
    fluid: str = "dust1",
    pattern: str | None = None,
    sigma_ref: float | None = None,
    use_energy: bool = True,
    eos: str = "auto",
    hand: str = "R",
    x_range: tuple[float, float] | None = (0.2, 2.2),
    wavelength: float = 0.87e-3,
    mstar: float = DEFAULT_MSTAR_MSUN,
    r_p_au: float = 50.0,
    mu: float = 2.34,
    beta: float = float("nan"),
    name: str | None = None,
) -> SpiralTemplate:
    """Read a 2-D FARGO3D output and turn it into a :class:`SpiralTemplate` (S22 radiative transfer).

    Parameters
    ----------
    directory : path
        The run's output directory.
    output : int
        Output number ``n``.
    tau0 : float
        Initial dust optical depth at the planet: ``τ = τ0 Σ_d / Σ_d,0(r_p)``.
    fluid : str
        Fluid whose density gives τ: ``'dust1'`` (default), ``'gas'``, ... (dust follows gas for
        St ≲ 0.1 if you pass ``'gas'``).
    pattern : str, optional
        File-name pattern for the density, e.g. ``"{fluid}dens{n}.dat"`` (``{field}`` also allowed).
    sigma_ref : float, optional
        ``Σ_d,0(r_p)`` in code units. Default: the azimuthal mean of output 0 at ``r_p`` if that
        file exists, else ``SIGMA0 (r_p/R0)^{-SIGMASLOPE}`` (times ``DUST_TO_GAS`` for dust) from
        variables.par.
    use_energy : bool
        Use ``gasenergy{n}.dat`` (if present) for the temperature perturbation.
    eos : {'auto', 'isothermal', 'adiabatic'}
        How to read the energy field: isothermal runs store ``c_s`` (``T ∝ c_s²``), adiabatic
        runs the internal energy density ``e`` (``T ∝ e/Σ_gas``). ``'auto'`` treats an
        azimuthally uniform field as isothermal and otherwise as adiabatic.
    hand : {'R', 'L'}
        Hand of the run as stored (FARGO3D rotates towards +φ: 'R'); 'L' mirrors the map.
    x_range : (float, float) or None
        Keep radii with ``x = r/r_p`` in this range (None: all).
    wavelength, mstar, r_p_au, mu : float
        Observing wavelength [m] and the physical scale of the temperature (see
        :func:`~spiralbayes.templates.radiative.midplane_temperature`); the axisymmetric
        temperature follows the run's ASPECTRATIO and FLARINGINDEX, the perturbation comes from
        the energy field.
    beta : float
        Cooling time recorded in the metadata (FARGO3D has no standard parameter for it).
    name : str, optional
        Template name (default ``fargo3d_<run folder>_<fluid>_<output>_tau<tau0>_<hand>``, so that
        the maps of several runs and optical depths can share a
        :class:`~spiralbayes.templates.bank.TemplateBank`).

    Returns
    -------
    SpiralTemplate
        Planet at φ = 0; ``mass`` in M_th from the planet file (``q_p / h_p³``).
    """
    hand = validate_hand(hand)
    directory = Path(directory)
    if not directory.is_dir():
        raise MissingFileError(f"FARGO3D output directory {directory} does not exist")
    params = read_variables(directory)
    phi_e, r_e = read_domain(directory, params)
    phi_c = 0.5 * (phi_e[1:] + phi_e[:-1])
    r_c = 0.5 * (r_e[1:] + r_e[:-1])
    if not np.allclose(np.diff(phi_e), TWO_PI / phi_c.size, rtol=1e-6):
        raise InputError("domain_x.dat is not a uniform full circle in azimuth; only such runs are supported")
    sigma = read_field(directory, fluid, "dens", output, params, pattern)
    planet = read_planet(directory, output)
    r_p, phi_p = planet["r"], planet["phi"]

    # reference density Σ_d,0(r_p)
    if sigma_ref is None:
        try:
            sigma0 = read_field(directory, fluid, "dens", 0, params, pattern)
            sigma_ref = _azimuthal_mean_at(sigma0, r_c, r_p)
        except FileNotFoundError:
            if "SIGMA0" not in params:
                raise InputError(
                    "cannot set Σ_d,0(r_p) for τ0: no output 0 and no SIGMA0 in variables.par; pass sigma_ref="
                ) from None
            r0 = float(params.get("R0", 1.0))
            sigma_ref = float(params["SIGMA0"]) * (r_p / r0) ** -float(params.get("SIGMASLOPE", 0.0))
            if fluid != "gas":
                if "DUST_TO_GAS" not in params:
                    raise InputError(
                        f"fluid {fluid!r}: no output 0 and no DUST_TO_GAS in variables.par to scale SIGMA0; "
                        "pass sigma_ref="
                    ) from None
                sigma_ref *= float(params["DUST_TO_GAS"])
    if not np.isfinite(sigma_ref) or sigma_ref <= 0:
        raise InputError(f"Σ_d,0(r_p) = {sigma_ref!r} is not positive; pass sigma_ref=")

    # temperature perturbation
    tfield = None
    if use_energy:
        try:
            energy = read_field(directory, "gas", "energy", output, params)
        except FileNotFoundError:
            log.info("no gasenergy%d.dat: isothermal temperature", output)
        else:
            mode = eos.lower()
            if mode == "auto":
                spread = np.max(np.ptp(energy, axis=1) / np.abs(energy).mean(axis=1).clip(1e-300))
                mode = "isothermal" if spread < 1e-8 else "adiabatic"
            if mode == "isothermal":
                tfield = energy**2
            elif mode == "adiabatic":
                gas = sigma if fluid == "gas" else read_field(directory, "gas", "dens", output, params)
                tfield = energy / gas
            else:
                raise InputError(f"unknown eos {eos!r}: use 'auto', 'isothermal' or 'adiabatic'")

    sigma_rot, phi = _rotate_to_planet(sigma, phi_c, phi_p)
    x = r_c / r_p
    keep = np.ones(x.size, bool) if x_range is None else (x >= x_range[0]) & (x <= x_range[1])
    if keep.sum() < 2:
        raise InputError(f"x_range {x_range} keeps fewer than 2 radii of the run (x = {x.min():.3g}–{x.max():.3g})")
    x, sigma_rot = x[keep], sigma_rot[keep]
    mean = sigma_rot.mean(axis=1)
    if np.any(mean <= 0):
        raise InputError(f"{fluid} density has non-positive azimuthal means; check the field")
    tfac = None
    if tfield is not None:
        t_rot = _rotate_to_planet(tfield, phi_c, phi_p)[0][keep]
        tfac = t_rot / t_rot.mean(axis=1, keepdims=True)

    h0 = float(params.get("ASPECTRATIO", 0.07))
    flaring = float(params.get("FLARINGINDEX", 0.25))
    r0 = float(params.get("R0", 1.0))
    h_p = h0 * (r_p / r0) ** flaring
    mass = planet["mass"] / h_p**3 if np.isfinite(planet["mass"]) else float("nan")
    tmpl = template_from_perturbation(
        x, phi, sigma_rot / mean[:, None] - 1.0, tau0, temperature_factor=tfac,
        sigma_axisym=mean / sigma_ref, hand="R", mass=mass, beta=beta, h_p=h_p, flaring=flaring,
        wavelength=wavelength, mstar=mstar, r_p_au=r_p_au, mu=mu,
        # the run's folder and tau0 in the name: maps of several runs or depths then fit in one bank
        name=name or f"fargo3d_{directory.resolve().name}_{fluid}_{output}_tau{tau0:g}_R",
        provenance={"reader": "spiralbayes.templates.fargo3d", "directory": str(directory.resolve()),
                    "output": int(output), "fluid": fluid, "planet": planet, "sigma_ref": sigma_ref,
                    "tau0": tau0},
    )
    return tmpl if hand == "R" else tmpl.mirror()
