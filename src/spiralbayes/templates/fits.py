"""Read δ maps stored as FITS files, in the layout used by Stevenson et al. (2024).

The paper's templates (made from the S22 FARGO3D runs) are four FITS files sharing a prefix::

    <base>_intens_frac_rt.fits      δ = ΔI/<I>_φ over (r, φ): shape (n_r, n_φ) (or transposed)
    <base>_rcenters.fits            radial cell centres [au], the planet at r_p = 50 au
    <base>_tcenters.fits            azimuth cell centres [rad] of the stored map
    <base>_tcenters_notshifted.fits azimuth centres before the authors' shift (optional)

The authors' pipeline places map column ``k`` at disc azimuth ``tcenters[k] + Δφ`` relative to
the planet, with ``Δφ = tcenters[0] − tcenters_notshifted[0]``; NaNs mean 0; the maps are
right-handed. :func:`read_fits_template` follows the same rules (``phi_offset`` overrides Δφ) and
resamples onto uniform azimuths ``2πk/n`` measured from the planet.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import InputError, MissingFileError
from ..units import TWO_PI, wrap_angle
from .template import SpiralTemplate, template_name, validate_hand

__all__ = ["read_fits_template", "write_fits_template"]

SUFFIXES = {
    "delta": "_intens_frac_rt.fits",
    "r": "_rcenters.fits",
    "phi": "_tcenters.fits",
    "phi_unshifted": "_tcenters_notshifted.fits",
}


def _fits():
    try:
        from astropy.io import fits
    except ImportError as exc:  # pragma: no cover - astropy is a dependency
        raise ImportError("reading FITS templates needs astropy (pip install astropy)") from exc
    return fits


def _read(path: Path, what: str) -> np.ndarray:
    if not path.exists():
        raise MissingFileError(
            f"FITS {what} file {path} not found; give its path explicitly (r_file=, phi_file=) or use "
            f"the paper's naming <base>{SUFFIXES.get(what, '.fits')}"
        )
    with _fits().open(path) as hdul:
        data = hdul[0].data
        if data is None:
            raise InputError(f"{path}: primary HDU holds no data")
        return np.asarray(data, dtype=float)


def _resolve(path, r_file, phi_file, phi_unshifted_file):
    """Paths of the δ, r, φ and unshifted-φ files from a δ file or the common prefix."""
    path = Path(path)
    text = str(path)
    if path.suffix.lower() == ".fits" and path.exists():
        delta_path = path
        base = text[: -len(SUFFIXES["delta"])] if text.endswith(SUFFIXES["delta"]) else None
    else:
        base = text
        delta_path = Path(base + SUFFIXES["delta"])

    def pick(given, key):
        if given is not None:
            return Path(given)
        return Path(base + SUFFIXES[key]) if base is not None else None

    r_path, phi_path = pick(r_file, "r"), pick(phi_file, "phi")
    if r_path is None or phi_path is None:
        raise InputError(
            f"{path}: give r_file= and phi_file= (the r- and φ-centre FITS files) when the δ file does "
            f"not follow the paper's naming <base>{SUFFIXES['delta']}"
        )
    return delta_path, r_path, phi_path, pick(phi_unshifted_file, "phi_unshifted")


def read_fits_template(
    path,
    *,
    r_file=None,
    phi_file=None,
    phi_unshifted_file=None,
    r_planet: float = 50.0,
    phi_offset: float | None = None,
    hand: str = "R",
    mass: float = float("nan"),
    tau0: float = float("nan"),
    beta: float = float("nan"),
    h_p: float = 0.07,
    flaring: float = 0.25,
    wavelength: float = 0.87e-3,
    name: str | None = None,
) -> SpiralTemplate:
    """Read a δ map from FITS files (the layout of Stevenson et al. 2024) into a template.

    Parameters
    ----------
    path : path
        The δ file, or the common prefix ``<base>`` of the four files (module docstring).
    r_file, phi_file, phi_unshifted_file : path, optional
        Radial-centre, azimuth-centre and unshifted-azimuth files (default: the paper's names).
    r_planet : float
        Planet radius in the unit of the r-centre file (the paper's files: 50 au).
    phi_offset : float, optional
        Azimuth [rad] added to the φ centres to put the planet at φ = 0; default
        ``tcenters[0] − tcenters_notshifted[0]`` if that file exists, else 0.
    hand : {'R', 'L'}
        Hand of the stored map (the paper's maps are right-handed); 'L' marks it so, no flip.
    mass, tau0, beta, h_p, flaring, wavelength : float
        Metadata (the paper's files encode them only in their names).
    name : str, optional
        Template name.

    Returns
    -------
    SpiralTemplate
        δ resampled onto ``φ_k = 2πk/n_φ`` from the planet (linear, periodic), NaNs set to 0.
    """
    hand = validate_hand(hand)
    if not np.isfinite(r_planet) or r_planet <= 0:
        raise InputError(f"r_planet must be positive, got {r_planet!r}")
    delta_path, r_path, phi_path, un_path = _resolve(path, r_file, phi_file, phi_unshifted_file)
    delta = _read(delta_path, "delta")
    r = np.ravel(_read(r_path, "r"))
    phi_c = np.ravel(_read(phi_path, "phi"))
    if delta.ndim != 2:
        raise InputError(f"{delta_path}: δ must be a 2-D (r, φ) map, got shape {delta.shape}")
    if delta.shape == (phi_c.size, r.size) and delta.shape != (r.size, phi_c.size):
        delta = delta.T
    if delta.shape != (r.size, phi_c.size):
        raise InputError(
            f"{delta_path}: δ has shape {delta.shape}, which matches neither (n_r, n_φ) = "
            f"({r.size}, {phi_c.size}) nor its transpose from {r_path.name} and {phi_path.name}"
        )
    if phi_offset is None:
        phi_offset = 0.0
        if un_path is not None and un_path.exists():
            phi_offset = float(phi_c[0] - np.ravel(_read(un_path, "phi_unshifted"))[0])
    delta = np.nan_to_num(delta, nan=0.0, posinf=0.0, neginf=0.0)
    order = np.argsort(r)
    r, delta = r[order], delta[order]
    x = r / r_planet
    # resample onto uniform azimuths from the planet
    n = phi_c.size
    phi_src = wrap_angle(phi_c + phi_offset, 0.0)
    srt = np.argsort(phi_src)
    phi_src, delta = phi_src[srt], delta[:, srt]
    phi = TWO_PI * np.arange(n) / n
    ext_phi = np.concatenate([phi_src[-1:] - TWO_PI, phi_src, phi_src[:1] + TWO_PI])
    ext = np.concatenate([delta[:, -1:], delta, delta[:, :1]], axis=1)
    idx = np.clip(np.searchsorted(ext_phi, phi, side="right") - 1, 0, ext_phi.size - 2)
    w = (phi - ext_phi[idx]) / (ext_phi[idx + 1] - ext_phi[idx])
    out = (1.0 - w) * ext[:, idx] + w * ext[:, idx + 1]
    return SpiralTemplate(
        x=x, phi=phi, delta=out.astype(np.float32), mass=mass, tau0=tau0, beta=beta, h_p=h_p,
        flaring=flaring, wavelength=wavelength, hand=hand,
        name=name or (template_name(mass, tau0, beta, hand, prefix="fits") if np.isfinite(mass)
                      else Path(str(delta_path)).name.replace(SUFFIXES["delta"], "")),
        provenance={"reader": "spiralbayes.templates.fits", "delta_file": str(delta_path),
                    "r_file": str(r_path), "phi_file": str(phi_path), "phi_offset": phi_offset,
                    "r_planet": r_planet},
    )


def write_fits_template(template: SpiralTemplate, base, *, r_planet: float = 50.0) -> list[Path]:
    """Write ``template`` in the paper's FITS layout (``<base>_intens_frac_rt.fits`` etc.).

    δ is written as ``(n_r, n_φ)``, r-centres as ``x · r_planet`` and φ-centres with no shift
    (so :func:`read_fits_template` reads it back unchanged). Files are replaced atomically.
    """
    from .._provenance import atomic_path

    fits = _fits()
    base = str(base)
    items = {
        "delta": np.asarray(template.delta, dtype=np.float32),
        "r": template.x * r_planet,
        "phi": template.phi,
        "phi_unshifted": template.phi,
    }
    out = []
    for key, data in items.items():
        path = Path(base + SUFFIXES[key])
        with atomic_path(path) as tmp:
            fits.PrimaryHDU(data).writeto(tmp, overwrite=True)
        out.append(path)
    return out
