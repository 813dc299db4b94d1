"""CASA's simulator as a second backend of :func:`~spiralbayes.simulate.simulate_observation`.

``simulate_observation(..., backend="casa")`` observes the same sky with CASA's ``simobserve``
(optional extra: ``pip install "spiralbayes[casa]"``): the same antenna configurations (the
package's layouts, written as CASA antenna lists in local coordinates about CASA's ``ALMA``
observatory position), integration time, hour-angle range, declination and frequency, and a sky
model that is the package's model disc (plus planet) rendered as a FITS image. What differs is
how each backend predicts visibilities and adds noise:

==================  ===========================================  ===========================================
                    package (``backend="package"``)              CASA (``backend="casa"``)
==================  ===========================================  ===========================================
visibilities        exact Hankel transform of the disc + NUFFT   FFT of the FITS model (``pixel_size``,
                    of the rendered perturbation (pixel window   default 4 mas, 3 x 3 sub-samples per
                    divided out)                                 pixel) degridded at the baselines, times
                                                                 the 12-m primary beam (0.995 at 0.8")
noise               Gaussian, sigma per Re/Im of Stokes I set    ``thermalnoise="tsys-atm"``: Tsys from
                    by the preset's image sensitivity            CASA's ATM model (``pwv`` mm, T_ground
                    (sigma_img sqrt(N)), equal for all rows      270 K), CASA's dish/correlator
                                                                 efficiencies; per correlation and row
weights             ``1 / sigma^2`` (exact)                      simobserve writes WEIGHT = SIGMA = 1 (not
                                                                 the noise it adds): set here to
                                                                 ``2 / s^2`` with ``s`` the RMS of noisy -
                                                                 noise-free DATA (Re, Im, XX, YY pooled)
                                                                 per configuration, i.e. the statistical
                                                                 weight of Stokes I = (XX + YY) / 2
uv coverage         TMS eqs. 4.1/4.15 at latitude -23.0234       CASA measures at -23.0229 (its ALMA
                                                                 position), epoch ``refdate`` 2000-01-01
==================  ===========================================  ===========================================

simobserve's ``hourangle`` is not the hour angle of the mean sidereal time: at refdate 2000/01/01
and RA 240 deg its integrations are centred 69 s early. The first configuration is therefore
observed twice: once to measure the offset (from the ``TIME`` column, with the sidereal time of
:mod:`spiralbayes.io.ms_writer`), once with the centre moved by it; the offsets left (< 1 s) are
in the provenance. simobserve runs in a child Python process: in a process where
python-casacore has written a table (:func:`~spiralbayes.io.write_ms`), CASA 6.7's simulator
crashes (segmentation fault in ``sm.setdata``).

Measured for the fiducial preset (``tests/simulate/test_casa_backend.py`` and
``benchmarks/bench_casa.py``, marker ``casa``): the rows match one to one, CASA's UVW = minus
the package's (u, v) to 1.7e-5 of the baseline (CASA stores ``uvw(ANTENNA1) - uvw(ANTENNA2)``);
the noise-free visibilities differ by 0.27 % RMS (0.06 % low at the shortest baselines: the
primary beam; 0.26 % low beyond 2 Mlambda: the 4-mas model pixels); CASA's noise at PWV 0.9 mm
is 6.4 % above the preset's (Stokes I 7.08 vs 6.65 mJy per visibility, 37.2 vs 35.0 uJy/beam).

Units: as :mod:`spiralbayes.simulate` (arcsec, deg, m, s, Jy).
"""

from __future__ import annotations

import logging
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from .._casa import INSTALL_HINT, casa_available
from ..exceptions import InputError, MissingDependencyError
from ..fourier import image_axes
from ..geometry import DiscGeometry
from ..io.ms_writer import gmst_deg
from ..units import ARCSEC, C_LIGHT
from ..visibilities import Visibilities
from .coverage import SIDEREAL_RATE, load_configuration
from .discs import DiscModel, _describe_perturbation, _perturbation_function

__all__ = ["CASA_BANDWIDTH", "simulate_casa", "sky_image", "write_fits_model"]

log = logging.getLogger(__name__)

CASA_BANDWIDTH = 7.5e9
"""Continuum bandwidth [Hz] given to simobserve (``inwidth``; the noise scales as its -1/2 power)."""
_RA_DEG = 240.0
_CASA_ALMA_LONGITUDE = -67.754929
"""Longitude [deg] of CASA's ``ALMA`` observatory, about which simobserve places the antenna lists."""


def sky_image(disc: DiscModel, geometry: DiscGeometry, wavelength: float, *, perturbation=None, r_p=None,
              phi_p=None, pixel_size: float = 0.004, supersample: int = 3):
    """The model sky [Jy/pixel] as ``image[iy north, ix west]`` (PA, offsets applied), and its axes.

    Each pixel is the mean of ``supersample^2`` point samples of ``I(r) (1 + delta(r, phi))`` at
    the disc-plane positions of the sub-samples (:meth:`.DiscGeometry.sky_to_disc`), times the
    pixel's solid angle. The image is square, odd-free (even size, centre pixel ``n // 2``) and
    covers the disc with a 10 % margin.
    """
    delta = _perturbation_function(perturbation, r_p, phi_p)
    reach = 1.1 * (disc.r_max + max(abs(geometry.dRA), abs(geometry.dDec)))
    n = 2 * int(np.ceil(reach / pixel_size)) + 2
    K = int(supersample)
    sub = ((np.arange(K) + 0.5) / K - 0.5) * pixel_size
    l, m = image_axes((n, n), pixel_size)
    ll, mm = np.meshgrid((l[:, None] - sub[None, :]).ravel(), (m[:, None] + sub[None, :]).ravel())
    r, phi = geometry.sky_to_disc(ll, mm)
    fine = disc.brightness(r, wavelength)
    if delta is not None:
        fine = fine * (1.0 + np.asarray(delta(r, phi), dtype=float))
    image = fine.reshape(n, K, n, K).mean(axis=(1, 3)) * (pixel_size * ARCSEC) ** 2
    return image, pixel_size


def write_fits_model(image, pixel_size: float, path, *, frequency: float, ra_deg: float, dec_deg: float,
                     bandwidth: float = CASA_BANDWIDTH) -> Path:
    """A FITS image [Jy/pixel] CASA reads as a sky model: ``RA---SIN``/``DEC--SIN``, ``CDELT1 < 0``.

    ``image[iy, ix]`` in the package's orientation is already FITS order (x grows westwards
    with ``CDELT1 < 0``); the reference pixel is the centre ``n // 2`` (FITS counts from 1).
    """
    from astropy.io import fits

    ny, nx = np.shape(image)
    header = fits.Header()
    header.update(CTYPE1="RA---SIN", CRVAL1=ra_deg, CDELT1=-pixel_size / 3600.0, CRPIX1=nx // 2 + 1, CUNIT1="deg",
                  CTYPE2="DEC--SIN", CRVAL2=dec_deg, CDELT2=pixel_size / 3600.0, CRPIX2=ny // 2 + 1, CUNIT2="deg",
                  CTYPE3="FREQ", CRVAL3=frequency, CDELT3=bandwidth, CRPIX3=1.0, CUNIT3="Hz",
                  CTYPE4="STOKES", CRVAL4=1.0, CDELT4=1.0, CRPIX4=1.0, BUNIT="Jy/pixel", EQUINOX=2000.0,
                  RADESYS="FK5")
    path = Path(path)
    fits.writeto(path, np.asarray(image, dtype=np.float32)[None, None], header, overwrite=True)
    return path


def _antenna_list(config, cycle: int, path: Path) -> Path:
    """A simobserve antenna list: the package's layout in local coordinates about CASA's ALMA position."""
    pos = load_configuration(config, cycle)
    lines = ["# observatory=ALMA", "# coordsys=LOC (local tangent plane)", "# x y z diam pad#"]
    lines += [f"{x:.9f} {y:.9f} {z:.9f} 12. P{k:03d}" for k, (x, y, z) in enumerate(pos)]
    path.write_text("\n".join(lines) + "\n")
    return path


# simobserve runs in a child process: in a process where python-casacore has written a table
# (e.g. write_ms), CASA 6.7's simulator crashes with a segmentation fault in sm.setdata.
_WORKER = """
import json, sys, time
from spiralbayes._casa import import_casa
_, casatasks = import_casa(logfile=sys.argv[2])
walls = []
for kwargs in json.load(open(sys.argv[1])):
    t0 = time.perf_counter()
    casatasks.simobserve(**kwargs)
    walls.append(time.perf_counter() - t0)
print("SIMOBSERVE_WALL_S", json.dumps(walls))
"""


def _simobserve_kwargs(k: int, config, hours, preset, fits_path: Path, pixel: float, frequency: float, dec: float,
                       seed: int, thermalnoise: str, pwv: float, workdir: Path, shift_s: float) -> dict:
    """simobserve's arguments for configuration ``k``; ``shift_s`` [s] moves the centre hour angle."""
    step_h = preset.integration_time * SIDEREAL_RATE / 3600.0
    n_int = int(np.floor((hours[1] - hours[0]) / step_h + 1e-9))
    centre_h = 0.5 * (hours[0] + hours[1]) + shift_s / 3600.0
    antennas = _antenna_list(config, preset.cycle, workdir / f"config{k}.cfg")
    return dict(
        project=f"config{k}", skymodel=str(fits_path), inbright="", indirection=f"J2000 {_RA_DEG}deg {dec}deg",
        incell=f"{pixel}arcsec", incenter=f"{frequency}Hz", inwidth=f"{CASA_BANDWIDTH}Hz",
        setpointings=True, integration=f"{preset.integration_time}s", direction=f"J2000 {_RA_DEG}deg {dec}deg",
        obsmode="int", refdate="2000/01/01", hourangle=f"{centre_h:.9f}h",
        totaltime=f"{n_int * preset.integration_time}s", antennalist=str(antennas), thermalnoise=thermalnoise,
        user_pwv=pwv, seed=int(seed) + k, graphics="none", verbose=False, overwrite=True)


def _run_simobserve(jobs: list, workdir: Path) -> list:
    """Run simobserve for each argument dict in a child Python; its wall times [s]."""
    import json
    import subprocess
    import sys

    spec = workdir / "simobserve_jobs.json"
    spec.write_text(json.dumps(jobs))
    done = subprocess.run([sys.executable, "-c", _WORKER, str(spec), str(workdir / "casa.log")], cwd=workdir,
                          capture_output=True, text=True)
    walls = [line.split(" ", 1)[1] for line in done.stdout.splitlines() if line.startswith("SIMOBSERVE_WALL_S")]
    if done.returncode != 0 or not walls:
        raise InputError(f"simobserve failed (exit {done.returncode}): {done.stderr.strip()[-800:]} "
                         f"(CASA log: {workdir / 'casa.log'})")
    return json.loads(walls[0])


def _read_run(k: int, hours, workdir: Path) -> dict:
    """DATA of the noise-free and noisy sets of configuration ``k``, UVW, and simobserve's hour-angle offset."""
    import casacore.tables as tables

    stem = workdir / f"config{k}" / f"config{k}.config{k}"
    clean_ms, noisy_ms = Path(f"{stem}.ms"), Path(f"{stem}.noisy.ms")
    if not clean_ms.exists():
        raise InputError(f"simobserve wrote no {clean_ms}: see the CASA log in {workdir / 'casa.log'}")
    with tables.table(str(clean_ms), ack=False) as t:
        cross = t.getcol("ANTENNA1") != t.getcol("ANTENNA2")
        out = {"uvw": t.getcol("UVW")[cross], "clean": t.getcol("DATA")[cross].astype(complex)}
        times = np.unique(t.getcol("TIME"))
    out["noisy"] = out["clean"]
    if noisy_ms.exists():
        with tables.table(str(noisy_ms), ack=False) as t:
            out["noisy"] = t.getcol("DATA")[cross].astype(complex)
    hour_angle = ((gmst_deg(times / 86400.0) + _CASA_ALMA_LONGITUDE - _RA_DEG + 180.0) % 360.0 - 180.0) / 15.0
    out["ha_offset_s"] = float((0.5 * (hour_angle[0] + hour_angle[-1]) - 0.5 * (hours[0] + hours[1])) * 3600.0)
    return out


def _stokes_i(part: dict, add_noise: bool):
    """Stokes I = (XX + YY) / 2 and its statistical weight from the noise CASA added."""
    added = part["noisy"] - part["clean"]
    sigma_corr = float(np.sqrt(0.5 * np.mean(added.real**2 + added.imag**2)))
    data = part["noisy"] if add_noise else part["clean"]
    V = 0.5 * (data[:, 0, 0] + data[:, 0, -1])
    return V, sigma_corr


def simulate_casa(preset, disc: DiscModel, geometry: DiscGeometry, perturbation=None, *, r_p=None, phi_p=None,
                  seed: int = 0, add_noise: bool = True, thermalnoise: str = "tsys-atm", pwv: float = 0.9,
                  pixel_size: float = 0.004, supersample: int = 3, workdir=None) -> Visibilities:
    """Observe the model disc with CASA's simobserve, configuration by configuration (module docstring).

    Parameters
    ----------
    preset : Preset
    disc, geometry, perturbation, r_p, phi_p
        As :func:`~spiralbayes.simulate.simulate_observation`.
    seed : int
        simobserve's noise seed (configuration ``k`` uses ``seed + k``).
    add_noise : bool
        False returns the noise-free visibilities with the weights of the noisy ones.
    thermalnoise, pwv
        simobserve's ``thermalnoise`` (``"tsys-atm"`` or ``"tsys-manual"``) and ``user_pwv`` [mm].
    pixel_size, supersample
        Of the FITS sky model (:func:`sky_image`).
    workdir : path, optional
        Keep CASA's files (FITS model, antenna lists, Measurement Sets, log) here; default a
        temporary folder that is removed.

    Returns
    -------
    Visibilities
        u, v = CASA's UVW / wavelength as stored (CASA's sign: ``uvw(ANTENNA1) - uvw(ANTENNA2)``),
        Stokes I, weights from the measured noise, provenance with CASA's settings and timings.
    """
    if thermalnoise not in ("tsys-atm", "tsys-manual"):
        raise InputError(f"thermalnoise must be 'tsys-atm' or 'tsys-manual', got {thermalnoise!r} "
                         "(the weights are measured from the noise CASA adds)")
    if not casa_available():
        raise MissingDependencyError(f"the CASA backend needs CASA: {INSTALL_HINT}")
    keep = workdir is not None
    workdir = Path(workdir if keep else tempfile.mkdtemp(prefix="spiralbayes-casa-")).resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        return _simulate(preset, disc, geometry, perturbation, r_p, phi_p, seed, add_noise, thermalnoise, pwv,
                         pixel_size, supersample, workdir)
    finally:
        if not keep:
            shutil.rmtree(workdir, ignore_errors=True)


def _simulate(p, disc, geometry, perturbation, r_p, phi_p, seed, add_noise, thermalnoise, pwv, pixel_size,
              supersample, workdir: Path) -> Visibilities:
    frequency = C_LIGHT / p.wavelength
    t0 = time.perf_counter()
    image, pix = sky_image(disc, geometry, p.wavelength, perturbation=perturbation, r_p=r_p, phi_p=phi_p,
                           pixel_size=pixel_size, supersample=supersample)
    fits_path = write_fits_model(image, pix, workdir / "model.fits", frequency=frequency, ra_deg=_RA_DEG,
                                 dec_deg=p.declination)
    timings = {"sky_model_s": time.perf_counter() - t0}
    configs = list(zip(p.configurations, p.hour_angles))

    def jobs(indices, shift):
        return [_simobserve_kwargs(k, configs[k][0], configs[k][1], p, fits_path, pix, frequency, p.declination,
                                   seed, thermalnoise, pwv, workdir, shift) for k in indices]

    walls = _run_simobserve(jobs([0], 0.0), workdir)
    shift, offset0 = 0.0, _read_run(0, configs[0][1], workdir)["ha_offset_s"]
    rest = list(range(1, len(configs)))
    if abs(offset0) > 0.5:
        # simobserve's hour angles are offset from those of the mean sidereal time (by -69 s at refdate
        # 2000/01/01, RA 240 deg): observe again with the centre moved by as much
        shift = -offset0
        log.info("simobserve's hour angles are %.1f s off; observing again with that correction", offset0)
        rest = [0] + rest
    if rest:
        walls = (walls if rest[0] else []) + _run_simobserve(jobs(rest, shift), workdir)
    timings.update({f"simobserve_{k}_s": w for k, w in enumerate(walls)})
    parts, sigmas, offsets = [], [], []
    for k, (_, hours) in enumerate(configs):
        part = _read_run(k, hours, workdir)
        offsets.append(part["ha_offset_s"])
        V, sigma_corr = _stokes_i(part, add_noise)
        parts.append((part["uvw"], V, np.full(V.size, 2.0 / sigma_corr**2)))
        sigmas.append(sigma_corr)
    uvw = np.concatenate([x[0] for x in parts])
    prov = {
        "source": "spiralbayes.simulate (CASA simobserve)", "backend": "casa",
        "preset": p.to_dict(),
        "model": {"disc": disc.to_dict(), "geometry": geometry.to_dict(),
                  "perturbation": _describe_perturbation(perturbation), "r_p_arcsec": r_p, "phi_p_rad": phi_p,
                  "fits_pixel_arcsec": pix, "supersample": supersample, "flux_jy": float(image.sum())},
        "casa": {"thermalnoise": thermalnoise, "user_pwv_mm": pwv, "seed": seed, "refdate": "2000/01/01",
                 "bandwidth_hz": CASA_BANDWIDTH, "phase_centre_deg": [_RA_DEG, p.declination]},
        "noise": {"added": bool(add_noise), "sigma_per_correlation_jy": sigmas,
                  "sigma_stokes_i_jy": [float(s / np.sqrt(2.0)) for s in sigmas],
                  "weights": "2 / s^2, s = RMS of (noisy - noise-free) DATA per configuration "
                             "(simobserve leaves WEIGHT = 1)"},
        "timings": timings,
        "hour_angle_offset_s": {"requested_shift": shift, "remaining_per_configuration": offsets},
    }
    return Visibilities(uvw[:, 0] / p.wavelength, uvw[:, 1] / p.wavelength, np.concatenate([x[1] for x in parts]),
                        np.concatenate([x[2] for x in parts]), wavelength=p.wavelength, provenance=prov)
