"""The observing set-ups of Stevenson et al. (2024, Table 1) and :func:`simulate_observation`."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..exceptions import InputError
from ..geometry import DiscGeometry
from ..visibilities import Visibilities
from .coverage import SIDEREAL_RATE, UVCoverage, uv_coverage
from .discs import DiscModel, _describe_perturbation, disc_visibilities
from .gains import GainErrors
from .noise import Radiometer, fit_beam, measure_image_noise, observe

__all__ = ["PRESETS", "Preset", "get_preset", "preset_coverage", "preset_table", "simulate_observation"]

@dataclass(frozen=True)
class Preset:
    """An observing set-up: configurations with their times on source, noise, wavelength.

    ``time_on_source[k]`` is the time [min] spent in ``configurations[k]``, observed in
    ``integration_time`` [s] integrations over an hour-angle range centred on transit
    (:attr:`hour_angles`); the number of visibilities is ``903 x`` the number of integrations
    (43 antennas). ``paper_6lnN`` is the Delta chi^2(Delta BIC = 0) = 6 ln N column of the paper's
    Table 1. ``resolution`` is the paper's nominal resolution [arcsec] (ALMA's quoted value for the
    most extended configuration, e.g. C-7 at 345 GHz); the natural-weighted beam of the simulated
    data is ~1.5 x larger (:func:`preset_table` fits it).
    """

    name: str
    description: str
    configurations: tuple
    time_on_source: tuple
    sensitivity: float
    wavelength: float
    resolution: float
    declination: float
    integration_time: float = 60.0
    min_elevation: float = 15.0
    cycle: int = 11
    paper_6lnN: float | None = None
    radiometer: Radiometer = field(default_factory=Radiometer)

    def __post_init__(self):
        if len(self.time_on_source) != len(self.configurations):
            raise InputError(f"preset {self.name!r}: give one time on source [min] per configuration "
                             f"({len(self.configurations)}), got {len(self.time_on_source)}")
        if any(not t > 0 for t in self.time_on_source):
            raise InputError(f"preset {self.name!r}: times on source must be positive [min], "
                             f"got {self.time_on_source}")

    @property
    def hour_angles(self) -> tuple:
        """Hour-angle range [h] of each configuration, centred on transit."""
        return tuple(_ha(t) for t in self.time_on_source)

    @property
    def total_time_on_source(self) -> float:
        """Time on source [min], all configurations together."""
        return float(sum(self.time_on_source))

    def coverage(self) -> UVCoverage:
        return uv_coverage(self.configurations, self.declination, self.hour_angles,
                           self.integration_time, self.wavelength, min_elevation=self.min_elevation,
                           cycle=self.cycle)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["configurations"] = list(self.configurations)
        d["time_on_source"] = list(self.time_on_source)
        d["hour_angles"] = [list(h) for h in self.hour_angles]
        return d


def _ha(minutes: float) -> tuple:
    """Hour-angle range [h] centred on transit holding ``minutes`` of integrations."""
    half = minutes / 60.0 * SIDEREAL_RATE / 2.0
    return (-half - 1e-6, half + 1e-6)


# Effective system temperatures: with them the radiometer equation gives the paper's image noise
# for the paper's times on source (they lump atmosphere at the observed elevation and losses).
_BAND7 = Radiometer(T_sys=210.0)
_BAND6 = Radiometer(T_sys=125.0)

PRESETS: dict[str, Preset] = {
    p.name: p
    for p in (
        Preset("fiducial", "0.061\" / 35 uJy/beam / 40 min, C-4 + C-7, 0.87 mm (Upper Sco / Lupus)",
               ("C-4", "C-7"), (10.0, 30.0), 35e-6, 0.87e-3, 0.061, -25.0,
               paper_6lnN=63.0, radiometer=_BAND7),
        Preset("high_sensitivity", "0.061\" / 10 uJy/beam / 8 h, C-4 + C-7, 0.87 mm",
               ("C-4", "C-7"), (120.0, 360.0), 10e-6, 0.87e-3, 0.061, -25.0,
               paper_6lnN=78.0, radiometer=_BAND7),
        Preset("low_sensitivity", "0.061\" / 50 uJy/beam / 20 min, C-4 + C-7, 0.87 mm",
               ("C-4", "C-7"), (5.0, 15.0), 50e-6, 0.87e-3, 0.061, -25.0,
               paper_6lnN=59.0, radiometer=_BAND7),
        Preset("high_resolution", "0.028\" / 35 uJy/beam / 40 min, C-5 + C-8, 0.87 mm",
               ("C-5", "C-8"), (10.0, 30.0), 35e-6, 0.87e-3, 0.028, -25.0,
               paper_6lnN=63.0, radiometer=_BAND7),
        Preset("taurus", "0.13\" / 50 uJy/beam / 7 min, C-6, 1.33 mm (Taurus survey comparison)",
               ("C-6",), (7.0,), 50e-6, 1.33e-3, 0.13, 25.0,
               paper_6lnN=52.0, radiometer=_BAND6),
    )
}
"""The five set-ups of Stevenson et al. (2024), Table 1 (see :func:`preset_table`).

Times on source: 40 min for the fiducial and high-resolution sets, 8 h for the high-sensitivity
set, 20 min for the low-sensitivity set (Table 1), and 7 min in C-6 for the Taurus comparison.
With 60-s integrations (the usual time averaging of continuum data; the Taurus survey data the
paper used were binned to 60 s) these times give N = 903 x minutes visibilities: 3.6e4, 4.3e5,
1.8e4, 3.6e4 and 6.3e3, i.e. 6 ln N = 62.9, 77.9, 58.7, 62.9 and 52.5 against the paper's 63, 78,
59, 63 and 52. The compact configuration gets a quarter of the time (10 + 30 min fiducial,
2 + 6 h, 5 + 15 min); sources transit (hour-angle ranges centred on 0; declination -25 deg for
Upper Sco / Lupus, +25 deg for Taurus). The Taurus time is the one that reproduces the paper's
N (the survey's own times varied by target). The noise actually added is set from the requested
sensitivity; the radiometer equation (:class:`Radiometer`) with effective system temperatures of
210 K (Band 7) and 125 K (Band 6) predicts it within 2 % for these times. ALMA's nominal T_sys
at good weather (~150 K and ~90 K) would give ~30 % less noise: the paper's sensitivities are
conservative for its times. Earlier versions used 30-s integrations and half these times, which
gave the same N but made every time-based forecast wrong by a factor of 2.
"""


def get_preset(preset) -> Preset:
    """A :class:`Preset` by name (or the preset itself)."""
    if isinstance(preset, Preset):
        return preset
    try:
        return PRESETS[preset]
    except (KeyError, TypeError):
        raise InputError(f"unknown preset {preset!r}: use one of {', '.join(PRESETS)}") from None


def preset_coverage(preset) -> UVCoverage:
    """The uv coverage of a preset (no model, no noise)."""
    return get_preset(preset).coverage()


def simulate_observation(preset="fiducial", disc: DiscModel | None = None,
                         geometry: DiscGeometry | None = None, perturbation=None, *,
                         r_p: float | None = None, phi_p: float | None = None, seed=0,
                         sensitivity: float | None = None, add_noise: bool = True,
                         coverage: UVCoverage | None = None, method: str = "hankel",
                         pixel_size: float = 0.004, supersample: int = 3, backend: str = "package",
                         casa_options: dict | None = None, gains: GainErrors | None = None) -> Visibilities:
    """A synthetic observation of a model disc with one of the paper's set-ups.

    Parameters
    ----------
    preset : str or Preset
        One of :data:`.PRESETS` (``"fiducial"``, ``"high_sensitivity"``, ``"low_sensitivity"``,
        ``"high_resolution"``, ``"taurus"``).
    disc : DiscModel
        Default ``DiscModel()`` (10-110 au at 140 pc).
    geometry : DiscGeometry
        Default ``DiscGeometry(inc=30, PA=60)``.
    perturbation, r_p, phi_p
        ``delta(r [arcsec], phi [rad])``, or a template with ``evaluate(r, phi, r_p, phi_p)``
        and the planet position ``r_p`` [arcsec], ``phi_p`` [rad].
    seed : int
        Noise seed.
    sensitivity : float, optional
        Override the preset's image noise [Jy/beam].
    coverage : UVCoverage, optional
        Reuse a coverage computed earlier (must belong to the preset).
    method, pixel_size, supersample
        See :func:`.disc_visibilities` (with ``backend="casa"``: the FITS sky model's pixel and
        sub-sampling).
    backend : {"package", "casa"}
        ``"casa"`` observes the same sky with CASA's simobserve (:mod:`spiralbayes.simulate.casa`;
        needs ``pip install "spiralbayes[casa]"``): noise as CASA adds it (so ``sensitivity`` and
        ``coverage`` cannot be given), weights measured from that noise.
    casa_options : dict, optional
        Keyword arguments of :func:`spiralbayes.simulate.casa.simulate_casa` (``thermalnoise``,
        ``pwv``, ``workdir``).
    gains : GainErrors, optional
        Antenna-based gain errors applied to the model visibilities before the thermal noise
        (:func:`.observe`); package backend only.

    Returns
    -------
    Visibilities
        u, v [λ], V [Jy] (model, gain errors and thermal noise), weights ``1/σ²`` [Jy⁻²], the antennas and
        times of every row, and a provenance record of the set-up, model, noise and seed.

    Examples
    --------
    The Taurus survey's set-up (C-6, 1.33 mm, 7 min) observing the default disc, without a planet:

    >>> import spiralbayes as sb
    >>> vis = sb.simulate_observation("taurus", seed=1)
    >>> vis.n
    6321

    With a 1 M_th planet at 0.3 arcsec and 90 degrees (the template sets the spiral):

    >>> import numpy as np
    >>> planet = sb.make_template(mass=1.0, tau0=3.0, beta=10.0, wavelength=1.33e-3)
    >>> vis = sb.simulate_observation("taurus", sb.DiscModel(distance=140.0), sb.DiscGeometry(inc=30, PA=60),
    ...                               planet, r_p=0.3, phi_p=np.radians(90.0), seed=1)
    """
    p = get_preset(preset)
    disc = DiscModel() if disc is None else disc
    geometry = DiscGeometry(30.0, 60.0) if geometry is None else geometry
    if backend not in ("package", "casa"):
        raise InputError(f"backend must be 'package' or 'casa', got {backend!r}")
    if backend == "casa":
        if gains is not None:
            raise InputError("gains= is applied by the package backend only: drop gains= or use backend='package'")
        if sensitivity is not None or coverage is not None:
            raise InputError("backend='casa' sets the noise and the uv coverage as CASA does: "
                             "drop sensitivity= and coverage=")
        from .casa import simulate_casa

        return simulate_casa(p, disc, geometry, perturbation, r_p=r_p, phi_p=phi_p, seed=seed, add_noise=add_noise,
                             pixel_size=pixel_size, supersample=supersample, **(casa_options or {}))
    cov = p.coverage() if coverage is None else coverage
    if not np.isclose(cov.wavelength, p.wavelength):
        raise InputError(
            f"the coverage ({cov.wavelength} m) is not that of preset {p.name!r} ({p.wavelength} m)"
        )
    V = disc_visibilities(cov.u, cov.v, disc.profile(cov.wavelength), geometry, disc.r_max,
                          r_min=disc.r_min, perturbation=perturbation, r_p=r_p, phi_p=phi_p,
                          method=method, pixel_size=pixel_size, supersample=supersample)
    model = {
        "disc": disc.to_dict(),
        "geometry": geometry.to_dict(),
        "perturbation": _describe_perturbation(perturbation),
        "r_p_arcsec": r_p,
        "phi_p_rad": phi_p,
        "method": method,
        "pixel_size_arcsec": pixel_size,
        "supersample": supersample,
    }
    return observe(V, cov, sensitivity=p.sensitivity if sensitivity is None else sensitivity,
                   add_noise=add_noise, seed=seed, gains=gains,
                   provenance={"preset": p.to_dict(), "model": model})


def preset_table(names=None, *, measure: bool = True, seed: int = 0) -> list[dict]:
    """One row per preset: N, 6 ln N (and the paper's), beam, requested and measured noise.

    ``measure=False`` skips the beam fit and the noise-only dirty image (fast).
    ``radiometer_noise`` is the image noise the preset's :class:`Radiometer` predicts for the
    same N (a consistency check of the chosen time on source).
    """
    rows = []
    for name in names or PRESETS:
        p = get_preset(name)
        cov = p.coverage()
        n = cov.n
        row = {
            "name": p.name,
            "configurations": "+".join(p.configurations),
            "wavelength_mm": p.wavelength * 1e3,
            "time_on_source_min": n / 903 * p.integration_time / 60.0,
            "paper_time_on_source_min": p.total_time_on_source,
            "N": n,
            "6lnN": 6 * np.log(n),
            "paper_6lnN": p.paper_6lnN,
            "resolution": p.resolution,
            "sensitivity": p.sensitivity,
            "radiometer_noise": p.radiometer.sigma(p.integration_time) / np.sqrt(n),
        }
        if measure:
            bmaj, bmin, bpa = fit_beam(cov.u, cov.v)
            noise_only = observe(None, cov, sensitivity=p.sensitivity, seed=seed)
            row.update(beam_major=bmaj, beam_minor=bmin, beam_pa=bpa, beam=np.sqrt(bmaj * bmin),
                       measured_noise=measure_image_noise(noise_only))
        rows.append(row)
    return rows
