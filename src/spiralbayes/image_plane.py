"""Image-plane comparisons: CLEAN residuals and gap depth, the methods the visibility scan is compared with.

Stevenson et al. (2024, sec. 3.3, Figs 7 and 12) compare their visibility-space search with what
an observer does in the image plane: CLEAN the data, remove the axisymmetric (frank) model
sampled at the same baselines, and look for a spiral in the residual image; and measure the
depth of a gap in the CLEAN image's azimuthally averaged profile (as Speedie, Booth & Dong 2022,
"S22", did). Both judged by eye; here each has a number and a stated criterion, so that surveys
can be run without looking at every image.

* :func:`clean_image` — CASA ``tclean`` (Högbom, standard gridder, MFS, Stokes I) of a
  :class:`~spiralbayes.visibilities.Visibilities`, written with
  :func:`~spiralbayes.io.write_ms`; images returned as ``array[iy north, ix west]`` (the
  package's orientation, :mod:`spiralbayes.fourier`) in Jy/beam.
* :func:`clean_residuals` — the residual image: the CLEAN image of the residual visibilities
  ``V - V_frank`` (default), or the CLEAN image of the data minus that of the frank model's
  visibilities at the same (u, v) with the same weights and CLEAN settings; and
  :func:`residual_detection` on it.
* :func:`radial_profile`, :func:`gap_depth` — the deprojected azimuthal average of the CLEAN
  image and the deepest gap in it.

Criteria
--------
**Spiral in the residual image** (:func:`residual_detection`): the statistic is the largest
``|R| / sigma`` inside the disc (deprojected radius below ``r_out``), ``sigma`` the robust RMS
(1.4826 x median absolute deviation) of the residual image outside ``1.5 r_out``. Noise in an
interferometric image is a smooth Gaussian random field whose correlation is the beam, so the
chance that noise alone reaches ``S`` somewhere in the disc (area ``A = pi r_out^2 cos i``,
perimeter ``P``) is the expected Euler characteristic of the excursion set (Adler 1981; Worsley
et al. 1996, Hum. Brain Mapp. 4, 58), two-sided::

    p = 2 [A sqrt(det L) / (2 pi)^{3/2} S exp(-S^2/2) + P/2 L^{1/2} / (2 pi) exp(-S^2/2) + erfc(S/sqrt 2) / 2]

with ``sqrt(det L) = 8 ln 2 / (b_maj b_min)`` for a Gaussian beam (``L`` the covariance of the
field's gradient) and ``L^{1/2}`` its geometric mean. Verdict: ``"detected"`` if
``p < 2.7e-3`` (a 3-sigma event after the look-elsewhere correction), ``"marginal"`` if
``p < 0.05``, else ``"not detected"``. A peak can also come from CLEAN artefacts or a wrong
axisymmetric model: the residual image shows where it is (the statistic says nothing about a
spiral's shape, which the paper judged by eye). The difference of two Högbom CLEAN images
(``method="difference"``) carries such artefacts: for data that are exactly the model plus
noise (fiducial set-up, Briggs 0.5) they reached 17 sigma (CLEAN to 4 sigma) and 27 sigma (to
1 sigma) inside the disc, so the default residual image is the CLEAN image of the residual
visibilities (``method="visibilities"``), which is linear in the data.

**Gap depth** (:func:`gap_depth`; S22): in the azimuthally averaged, deprojected CLEAN profile
a gap is a local minimum ``I_gap`` followed outwards by a local maximum (the ring) ``I_ring``;
``delta = I_ring / I_gap``. The deepest gap (largest delta) between one beam from the centre
and ``r_out`` is reported. Verdict (S22's classes): ``"clear"`` if ``delta > 1.5``,
``"marginal"`` if ``1 < delta <= 1.5`` and ``delta - 1`` exceeds three times its noise error,
else ``"none"``. The error of each profile bin is the image noise divided by the square root
of the number of beams in its annulus.
"""

from __future__ import annotations

import logging
import math
import resource
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._casa import casa_log, import_casa, working_directory
from .exceptions import InputError
from .fourier import image_axes
from .geometry import DiscGeometry
from .io import write_ms
from .units import ARCSEC
from .visibilities import Visibilities

__all__ = [
    "CleanImage",
    "CleanResiduals",
    "GapDepth",
    "ResidualDetection",
    "clean_image",
    "clean_residuals",
    "default_clean_grid",
    "false_alarm_probability",
    "gap_depth",
    "radial_profile",
    "residual_detection",
]

log = logging.getLogger(__name__)

DETECTION_P = 2.7e-3
"""False-alarm probability below which a residual peak counts as detected (3 sigma, two-sided)."""
MARGINAL_P = 0.05
CLEAR_GAP = 1.5
"""S22's gap depth above which a gap is clear (marginal between 1 and this)."""
_FWHM_AREA = np.pi / (4.0 * np.log(2.0))


# ---------------------------------------------------------------------------------- results
@dataclass
class CleanImage:
    """A tclean result in the package's orientation (``array[iy north, ix west]``, centre ``n // 2``).

    Attributes
    ----------
    image, residual : ndarray
        Restored image and residual image [Jy/beam].
    model : ndarray
        CLEAN components [Jy/pixel].
    cell : float
        Pixel size [arcsec].
    beam : (float, float, float)
        Restoring beam: major and minor FWHM [arcsec], position angle [deg east of north].
    sumwt : float
        CASA's sum of the imaging weights (natural weighting: ``sum(w)`` of the data).
    iterations : int
        CLEAN iterations done.
    settings : dict
        The tclean parameters used.
    timings : dict
        ``write_ms_s``, ``tclean_wall_s``, ``tclean_cpu_s`` (CPU of this process).
    """

    image: np.ndarray
    residual: np.ndarray
    model: np.ndarray
    cell: float
    beam: tuple
    sumwt: float
    iterations: int
    settings: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple:
        return self.image.shape

    @property
    def beam_area(self) -> float:
        """Solid angle of the restoring beam [arcsec^2]."""
        return _FWHM_AREA * self.beam[0] * self.beam[1]

    def axes(self):
        """Pixel offsets ``(l east, m north)`` [arcsec] along x and y (:func:`spiralbayes.fourier.image_axes`)."""
        return image_axes(self.shape, self.cell)


@dataclass
class ResidualDetection:
    """Outcome of :func:`residual_detection` (see the module docstring for the criterion)."""

    peak_snr: float
    peak_r: float
    peak_phi_deg: float
    noise: float
    n_beams: float
    p_false_alarm: float
    verdict: str
    r_out: float

    @property
    def detected(self) -> bool:
        return self.verdict == "detected"


@dataclass
class CleanResiduals:
    """The CLEAN image of the data, the residual image and its statistic.

    ``method="difference"``: ``model`` is the CLEAN image of the axisymmetric model and
    ``difference = data.image - model.image``; ``method="visibilities"``: ``model`` is the CLEAN
    image of the residual visibilities and ``difference`` its restored image.
    """

    data: CleanImage
    model: CleanImage
    difference: np.ndarray
    detection: ResidualDetection
    method: str = "difference"


@dataclass
class GapDepth:
    """Outcome of :func:`gap_depth`: S22's ``delta = I_ring / I_gap`` of the deepest gap."""

    delta: float
    delta_error: float
    r_gap: float | None
    r_ring: float | None
    verdict: str
    r: np.ndarray
    profile: np.ndarray
    profile_error: np.ndarray


# ------------------------------------------------------------------------------------ tclean
def default_clean_grid(vis: Visibilities, r_out: float, *, pixels_per_fringe: float = 3.0) -> tuple[int, float]:
    """``(imsize, cell [arcsec])``: cell ``1 / (pixels_per_fringe u_max)``; the image spans at
    least ``6 r_out`` and 4"; imsize is even and a product of 2, 3 and 5 (fast FFTs in CASA)."""
    cell = 1.0 / (pixels_per_fringe * float(np.max(vis.uv_distance))) / ARCSEC
    cell = float(f"{cell:.2g}")
    n = int(np.ceil(max(6.0 * r_out, 4.0) / cell))
    while n % 2 or _largest_prime_factor(n) > 5:
        n += 1
    return n, cell


def _largest_prime_factor(n: int) -> int:
    largest, k = 1, 2
    while k * k <= n:
        while n % k == 0:
            largest, n = k, n // k
        k += 1
    return max(largest, n)


def clean_image(vis: Visibilities, workdir, name: str = "data", *, imsize: int, cell: float,
                weighting: str = "briggs", robust: float = 0.5, niter: int = 10000, threshold: float = 0.0,
                deconvolver: str = "hogbom", scales=(0, 5, 15), keep_files: bool = True) -> CleanImage:
    """CLEAN ``vis`` with CASA's tclean (Högbom, standard gridder, MFS, Stokes I).

    Parameters
    ----------
    vis : Visibilities
        Written to ``workdir/<name>.ms`` with :func:`~spiralbayes.io.write_ms`.
    workdir : path
        Folder for the MS, the CASA images ``<name>.image`` etc. and the CASA log; tclean runs
        with it as working directory (it leaves scratch files there).
    imsize, cell
        Image size [pixels] and pixel [arcsec] (see :func:`default_clean_grid`).
    weighting, robust
        tclean's ``weighting`` (``"natural"``, ``"briggs"``, ``"uniform"``) and Briggs ``robust``.
    niter, threshold
        Iteration limit and stopping threshold [Jy/beam] of the peak residual.
    keep_files : bool
        Keep the MS and CASA images in ``workdir`` (False deletes them after reading).

    Raises
    ------
    MissingDependencyError
        CASA is not installed (``pip install "spiralbayes[casa]"``).
    """
    casatools, casatasks = import_casa()
    workdir = Path(workdir).resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    ms = write_ms(vis, workdir / f"{name}.ms")
    timings = {"write_ms_s": time.perf_counter() - t0}
    for old in workdir.glob(f"{name}.*"):
        if old != ms:
            shutil.rmtree(old, ignore_errors=True) if old.is_dir() else old.unlink()
    settings = {"imsize": int(imsize), "cell": f"{cell}arcsec", "specmode": "mfs", "gridder": "standard",
                "deconvolver": deconvolver, "weighting": weighting, "robust": float(robust), "niter": int(niter),
                "threshold": f"{threshold * 1e3:.6g}mJy", "stokes": "I", "interactive": False}
    if deconvolver == "multiscale":
        settings["scales"] = [int(s) for s in scales]
    cpu0, t1 = _cpu_seconds(), time.perf_counter()
    with working_directory(workdir), casa_log(workdir / "casa.log"):
        summary = casatasks.tclean(vis=str(ms), imagename=str(workdir / name), **settings)
    timings.update(tclean_wall_s=time.perf_counter() - t1, tclean_cpu_s=_cpu_seconds() - cpu0)
    log.info("tclean %s: %.1f s wall, %.1f s CPU", name, timings["tclean_wall_s"], timings["tclean_cpu_s"])
    result = _read_clean(casatools, workdir / name, cell, settings, timings, summary)
    if not keep_files:
        for path in [ms, *workdir.glob(f"{name}.*")]:
            shutil.rmtree(path, ignore_errors=True) if path.is_dir() else path.unlink(missing_ok=True)
    return result


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _read_casa_image(casatools, path: Path) -> tuple[np.ndarray, dict]:
    """CASA image (axes RA, Dec, Stokes, freq) -> ``array[iy, ix]``; CASA's pixel x grows westwards."""
    if not path.exists():
        raise InputError(f"tclean did not write {path}: see the CASA log in {path.parent / 'casa.log'}")
    ia = casatools.image()
    ia.open(str(path))
    try:
        pixels = np.asarray(ia.getchunk()[:, :, 0, 0], dtype=float).T
        beam = ia.restoringbeam()
    finally:
        ia.close()
    return pixels, beam


def _read_clean(casatools, stem: Path, cell: float, settings: dict, timings: dict, summary) -> CleanImage:
    image, beam = _read_casa_image(casatools, stem.with_name(stem.name + ".image"))
    residual, _ = _read_casa_image(casatools, stem.with_name(stem.name + ".residual"))
    model, _ = _read_casa_image(casatools, stem.with_name(stem.name + ".model"))
    sumwt, _ = _read_casa_image(casatools, stem.with_name(stem.name + ".sumwt"))
    if "major" not in beam:
        raise InputError(f"tclean gave no restoring beam for {stem}: see {stem.parent / 'casa.log'}")
    to_arcsec = {"arcsec": 1.0, "deg": 3600.0, "rad": 1.0 / ARCSEC}
    bmaj = beam["major"]["value"] * to_arcsec[beam["major"]["unit"]]
    bmin = beam["minor"]["value"] * to_arcsec[beam["minor"]["unit"]]
    bpa = beam["positionangle"]["value"] * (1.0 if beam["positionangle"]["unit"] == "deg" else 180.0 / np.pi)
    iterations = int(summary.get("iterdone", 0)) if isinstance(summary, dict) else 0
    return CleanImage(image=image, residual=residual, model=model, cell=float(cell), beam=(bmaj, bmin, bpa),
                      sumwt=float(sumwt.ravel()[0]), iterations=iterations, settings=settings, timings=timings)


def clean_residuals(vis: Visibilities, axisymmetric, workdir, *, method: str = "visibilities",
                    r_out: float | None = None, imsize: int | None = None, cell: float | None = None,
                    threshold_sigma: float = 2.0, **clean_kwargs) -> CleanResiduals:
    """CLEAN the data and the axisymmetric model at the same baselines; the residual image and its statistic.

    Parameters
    ----------
    vis : Visibilities
    axisymmetric : AxisymmetricModel
        Its visibilities at ``(vis.u, vis.v)`` (with its geometry) and the data's weights form
        the model data set; both are CLEANed with the same settings.
    method : {"difference", "visibilities"}
        ``"visibilities"`` (default): CLEAN image of the residual visibilities ``V - V_model``
        (linear in the data). ``"difference"``: CLEAN image of the data minus CLEAN image of the
        model, as the issue describes the paper's comparison; it carries the two CLEANs'
        different component placements (module docstring).
    workdir : path
        Folder for the Measurement Sets, CASA images and log (``data.*``, ``model.*``).
    r_out : float, optional
        Outer radius of the disc [arcsec] for the statistic (default ``1.1 R_eff(0.99)`` of the
        model).
    imsize, cell : optional
        Default :func:`default_clean_grid`.
    threshold_sigma : float
        CLEAN both to this many times the natural-weighted image noise ``1 / sqrt(sum w)``.
    **clean_kwargs
        ``weighting``, ``robust``, ``niter``, ``keep_files`` for :func:`clean_image`.
    """
    vis = vis.standardised()
    r_out = 1.1 * axisymmetric.R_eff(0.99) if r_out is None else float(r_out)
    if imsize is None or cell is None:
        n, c = default_clean_grid(vis, r_out)
        imsize, cell = imsize or n, cell or c
    threshold = threshold_sigma / math.sqrt(float(np.sum(vis.weights)))
    if method not in ("difference", "visibilities"):
        raise InputError(f"method must be 'difference' or 'visibilities', got {method!r}")
    V_model = axisymmetric.visibilities(vis.u, vis.v)
    kwargs = {"imsize": imsize, "cell": cell, "threshold": threshold, **clean_kwargs}
    data = clean_image(vis, workdir, "data", **kwargs)
    if method == "difference":
        model = clean_image(vis.with_V(V_model, "axisymmetric model at the data's baselines"), workdir, "model",
                            **kwargs)
        difference = data.image - model.image
    else:
        model = clean_image(vis.with_V(vis.V - V_model, "data minus the axisymmetric model"), workdir, "residual",
                            **kwargs)
        difference = model.image
    detection = residual_detection(difference, data.cell, axisymmetric.geometry, r_out, data.beam)
    return CleanResiduals(data=data, model=model, difference=difference, detection=detection, method=method)


# --------------------------------------------------------------------------- image statistics
def _disc_coordinates(shape, cell: float, geometry: DiscGeometry):
    l, m = image_axes(shape, cell)
    ll, mm = np.meshgrid(l, m)
    return geometry.sky_to_disc(ll, mm)


def residual_detection(residual, cell: float, geometry: DiscGeometry, r_out: float, beam) -> ResidualDetection:
    """Peak ``|R| / sigma`` in the disc and its look-elsewhere false-alarm probability (module docstring).

    Parameters
    ----------
    residual : ndarray
        Residual image [Jy/beam], ``array[iy north, ix west]``.
    cell : float
        Pixel [arcsec].
    geometry : DiscGeometry
        Disc geometry for the deprojected radius.
    r_out : float
        Disc radius [arcsec]: the statistic inside, the noise outside ``1.5 r_out``.
    beam : (bmaj, bmin, bpa)
        FWHM [arcsec] and position angle [deg].
    """
    residual = np.asarray(residual, dtype=float)
    r, phi = _disc_coordinates(residual.shape, cell, geometry)
    ny, nx = residual.shape
    iy, ix = np.indices(residual.shape)
    inner = (np.abs(iy - ny // 2) < 0.4 * ny) & (np.abs(ix - nx // 2) < 0.4 * nx)  # away from the edges
    outside = inner & (r > 1.5 * r_out)
    if outside.sum() < 100:
        raise InputError(f"the image ({nx} x {ny} pixels of {cell} arcsec) leaves too little sky outside "
                         f"1.5 r_out = {1.5 * r_out:.3g} arcsec to measure the noise: make it larger")
    noise = 1.4826 * float(np.median(np.abs(residual[outside] - np.median(residual[outside]))))
    disc = r < r_out
    snr = np.where(disc, np.abs(residual), 0.0) / noise
    k = int(np.argmax(snr))
    peak = float(snr.flat[k])
    area = np.pi * r_out**2 * geometry.cos_inc
    n_beams = max(1.0, area / (_FWHM_AREA * beam[0] * beam[1]))
    p = false_alarm_probability(peak, area, _ellipse_perimeter(r_out, r_out * geometry.cos_inc), beam)
    verdict = "detected" if p < DETECTION_P else ("marginal" if p < MARGINAL_P else "not detected")
    return ResidualDetection(peak_snr=peak, peak_r=float(r.flat[k]), peak_phi_deg=float(np.degrees(phi.flat[k])),
                             noise=noise, n_beams=float(n_beams), p_false_alarm=p, verdict=verdict, r_out=float(r_out))


def false_alarm_probability(peak: float, area: float, perimeter: float, beam) -> float:
    """Chance that a Gaussian random field of beam-shaped correlation exceeds ``|peak|`` (in sigma)
    somewhere in a region of ``area`` [arcsec^2] and ``perimeter`` [arcsec] (module docstring)."""
    u = float(peak)
    lam_det = 8.0 * np.log(2.0) / (beam[0] * beam[1])  # sqrt(det L) [arcsec^-2]
    ec = (area * lam_det / (2.0 * np.pi) ** 1.5 * u * np.exp(-0.5 * u * u)
          + 0.5 * perimeter * np.sqrt(lam_det) / (2.0 * np.pi) * np.exp(-0.5 * u * u)
          + 0.5 * math.erfc(u / math.sqrt(2.0)))
    return float(min(1.0, 2.0 * ec))


def _ellipse_perimeter(a: float, b: float) -> float:
    """Ramanujan's approximation (relative error < 1e-4 for b/a > 0.1)."""
    h = ((a - b) / (a + b)) ** 2
    return float(np.pi * (a + b) * (1.0 + 3.0 * h / (10.0 + np.sqrt(4.0 - 3.0 * h))))


def radial_profile(image, cell: float, geometry: DiscGeometry, r_max: float, bin_width: float):
    """Azimuthal average of ``image`` over deprojected radius: ``(r, mean, n_pixels)`` per bin.

    ``r`` are the bin centres [arcsec] from 0 to ``r_max`` in steps of ``bin_width``; empty bins
    are dropped.
    """
    if not (bin_width > 0 and r_max > bin_width):
        raise InputError(f"need 0 < bin_width < r_max, got bin_width={bin_width}, r_max={r_max} [arcsec]")
    r, _ = _disc_coordinates(np.shape(image), cell, geometry)
    edges = np.arange(0.0, r_max + bin_width, bin_width)
    index = np.digitize(r.ravel(), edges) - 1
    keep = (index >= 0) & (index < edges.size - 1)
    counts = np.bincount(index[keep], minlength=edges.size - 1)
    sums = np.bincount(index[keep], weights=np.asarray(image, dtype=float).ravel()[keep], minlength=edges.size - 1)
    ok = counts > 0
    centres = 0.5 * (edges[1:] + edges[:-1])
    return centres[ok], sums[ok] / counts[ok], counts[ok]


def gap_depth(clean: CleanImage, geometry: DiscGeometry, r_out: float, *, noise: float | None = None,
              bin_width: float | None = None, r_range: tuple | None = None) -> GapDepth:
    """S22's gap depth ``delta = I_ring / I_gap`` of the deepest gap in the CLEAN profile.

    Parameters
    ----------
    clean : CleanImage
    geometry : DiscGeometry
    r_out : float
        Outer disc radius [arcsec]; the profile runs to ``1.2 r_out``.
    noise : float, optional
        Image noise [Jy/beam] (default: robust RMS of the residual image).
    bin_width : float, optional
        Radial bin [arcsec] (default a quarter of the beam's minor FWHM).
    r_range : (float, float), optional
        Radii [arcsec] where the gap minimum may lie (default one beam FWHM to ``r_out``).
    """
    bmaj, bmin, _ = clean.beam
    bin_width = 0.25 * bmin if bin_width is None else float(bin_width)
    if noise is None:
        res = clean.residual
        noise = 1.4826 * float(np.median(np.abs(res - np.median(res))))
    r, profile, counts = radial_profile(clean.image, clean.cell, geometry, 1.2 * r_out, bin_width)
    beams = np.maximum(1.0, counts * clean.cell**2 / clean.beam_area)
    err = noise / np.sqrt(beams)
    lo, hi = r_range if r_range is not None else (np.sqrt(bmaj * bmin), r_out)
    best: tuple[float, float, float | None, float | None] = (1.0, 0.0, None, None)
    for i in range(1, r.size - 1):
        if not (lo <= r[i] <= hi and profile[i] < profile[i - 1] and profile[i] <= profile[i + 1] and profile[i] > 0):
            continue
        j = i + 1
        while j + 1 < r.size and profile[j + 1] >= profile[j]:
            j += 1
        delta = profile[j] / profile[i]
        if delta > best[0]:
            error = delta * math.hypot(err[j] / profile[j], err[i] / profile[i])
            best = (float(delta), float(error), float(r[i]), float(r[j]))
    delta, error, r_gap, r_ring = best
    if delta > CLEAR_GAP:
        verdict = "clear"
    elif delta > 1.0 and delta - 1.0 > 3.0 * error:
        verdict = "marginal"
    else:
        verdict = "none"
    return GapDepth(delta=delta, delta_error=error, r_gap=r_gap, r_ring=r_ring, verdict=verdict, r=r,
                    profile=profile, profile_error=err)
