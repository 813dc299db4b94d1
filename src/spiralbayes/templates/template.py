"""The :class:`SpiralTemplate`: a fractional residual brightness map around a planet.

A template is ``δ(x, φ) = I(x, φ) / <I>_φ(x) − 1`` on a polar grid of the disc plane
(Stevenson et al. 2024, sec. 2.2), scale-free in ``x = r / r_p``.

Conventions
-----------
* ``phi`` is the disc azimuth [rad], measured anticlockwise in the usual sky display (north up,
  east left) after deprojection (DESIGN.md, "Conventions"). The template is in the planet's frame:
  the planet sits at ``x = 1, φ = 0``.
* ``hand = 'R'`` (right-handed): the planet orbits anticlockwise (increasing φ) and its arms trail,
  so the wake ridge ``φ_wake(x)`` decreases with ``x``: the outer arm lies at ``φ < 0`` for
  ``x > 1`` and the inner arm at ``φ > 0`` for ``x < 1`` (Rafikov 2002 eq. 44 with ``s = +1``).
  ``hand = 'L'`` is the mirror image, ``φ → −φ`` (:meth:`SpiralTemplate.mirror`).
* Interpolation (:meth:`SpiralTemplate.evaluate`) is bilinear in ``(ln x, φ)``, periodic in φ,
  and zero outside ``[x[0], x[-1]]`` (the first and last cell centres).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._hdf5 import checked_dataset
from .._provenance import json_safe, to_json
from ..exceptions import InputError
from ..units import TWO_PI

__all__ = ["SpiralTemplate", "HANDS", "SCALAR_FIELDS", "bilinear", "limit_margin", "template_metadata",
           "check_mass_beta", "check_tau0", "SIMULATION", "metadata_variant", "repeated_names", "template_kind",
           "template_name", "validate_hand"]

log = logging.getLogger(__name__)

HANDS = ("R", "L")
SCALAR_FIELDS = ("mass", "tau0", "beta", "h_p", "flaring", "wavelength")
"""Numeric metadata every template carries (NaN where unknown)."""


def validate_hand(hand: str) -> str:
    """Return ``'R'`` or ``'L'``; raise ``ValueError`` for anything else."""
    h = str(hand).strip().upper()
    if h not in HANDS:
        raise InputError(
            f"unknown hand {hand!r}: use 'R' (planet orbiting anticlockwise, trailing arms) or 'L'"
        )
    return h


def check_mass_beta(mass, beta) -> None:
    """Raise :class:`InputError` unless the mass [M_th] is positive and beta non-negative."""
    if not np.isfinite(mass) or mass <= 0:
        raise InputError(f"planet mass must be positive (in thermal masses M_th), got {mass!r}")
    if not np.isfinite(beta) or beta < 0:
        raise InputError(f"cooling time beta must be >= 0 (0 = isothermal), got {beta!r}")


def _check_parameters(template) -> None:
    """Refuse metadata no template can have; NaN stays allowed where it means "unknown" (mass, tau0, beta)."""
    for key in ("mass", "tau0"):
        value = getattr(template, key)
        if np.isinf(value) or value <= 0:
            raise InputError(f"SpiralTemplate.{key} = {value!r} must be positive and finite "
                             f"({'M_p/M_th' if key == 'mass' else 'optical depth at r_p'}), or NaN if unknown")
    if np.isinf(template.beta) or template.beta < 0:
        raise InputError(f"SpiralTemplate.beta = {template.beta!r} must be >= 0 and finite (0 = isothermal), "
                         "or NaN if unknown")
    for key, what in (("h_p", "the aspect ratio H/r at r_p, e.g. 0.07"), ("wavelength", "in metres, e.g. 1.3e-3")):
        value = getattr(template, key)
        if not np.isfinite(value) or value <= 0:
            raise InputError(f"SpiralTemplate.{key} = {value!r} must be positive and finite ({what})")
    if not np.isfinite(template.flaring):
        raise InputError(f"SpiralTemplate.flaring = {template.flaring!r} must be finite (H/r ∝ r**flaring)")


def check_tau0(tau0) -> None:
    """Raise :class:`InputError` unless tau0 is positive and finite."""
    if not np.isfinite(tau0) or tau0 <= 0:
        raise InputError(f"tau0 (initial optical depth at r_p) must be positive, got {tau0!r}")


def repeated_names(templates) -> list[str]:
    """The names that occur more than once among ``templates``, sorted (banks, scan results and test 3
    find a template by its name)."""
    names = [getattr(t, "name", None) for t in templates]
    return sorted({n for n in names if n is not None and names.count(n) > 1})


SIMULATION = "simulation"
"""The kind of a map read from a simulation (:func:`template_kind`), and the morphology of one that
names no variant (:func:`metadata_variant`)."""


def template_kind(template) -> str:
    """``"generator"`` for a template of the package's semi-analytic generator (any morphology variant),
    ``"simulation"`` for a map read from a simulation (FARGO3D, a FITS file, a reference library).

    ``template`` may also be its :func:`template_metadata` (a scan result's ``templates``), whose
    ``kind`` marks the maps; metadata without it (older results) are the generator's.
    """
    if isinstance(template, Mapping):
        return SIMULATION if template.get("kind") == SIMULATION else "generator"
    return "generator" if "generator" in (getattr(template, "provenance", None) or {}) else SIMULATION


def metadata_variant(meta: Mapping) -> str | None:
    """The morphology a template's metadata stand for: its variant name, ``"simulation"`` for a map
    that names none, None for the generator's compromise (the limits' families and the verdict's mass
    range keep a map apart from the generator's templates by it)."""
    variant = meta.get("variant")
    if variant is not None:
        return str(variant)
    return SIMULATION if template_kind(meta) == SIMULATION else None


def template_name(mass: float, tau0: float, beta: float, hand: str, prefix: str = "wake",
                  h_p: float | None = None) -> str:
    """Canonical template name, e.g. ``wake_m1_tau0.3_b10_h0.07_R`` (``h_p`` given: the disc
    aspect ratio at r_p, two decimals when that is exact) or ``wake_m1_tau0.3_b10_h0.07_R``."""
    h = ""
    if h_p is not None and np.isfinite(h_p):
        h = f"_h{h_p:.2f}" if abs(h_p - round(h_p, 2)) < 1e-12 else f"_h{h_p:g}"
    return f"{prefix}_m{mass:g}_tau{tau0:g}_b{beta:g}{h}_{hand}"


@dataclass(eq=False)
class SpiralTemplate:
    """Fractional residual brightness ``δ = I/<I>_φ − 1`` of a planet-driven spiral.

    Parameters
    ----------
    x : (n_x,) array
        Radial cell centres ``r / r_p``, strictly increasing (log-spaced for built-in templates).
    phi : (n_phi,) array
        Azimuth cell centres [rad], uniform in ``[0, 2π)``; the planet is at ``φ = 0``.
    delta : (n_x, n_phi) array
        ``δ(x, φ)``; stored as given (float32 in banks).
    mass : float
        Planet mass ``M_p / M_th`` (``M_th = h_p^3 M_*``), positive; NaN if unknown. Infinite or
        non-positive values, and non-finite ``delta`` or ``brightness``, raise InputError.
    tau0 : float
        Initial dust optical depth at ``r_p``; NaN if unknown.
    beta : float
        Dimensionless cooling time ``β = t_c Ω`` (0 = isothermal); NaN if unknown.
    h_p : float
        Aspect ratio ``H/r`` at ``r_p``.
    flaring : float
        Flaring index: ``H/r ∝ r**flaring``.
    wavelength : float
        Observing wavelength [m].
    hand : {'R', 'L'}
        Handedness (see the module docstring).
    name : str
        Identifier, unique within a :class:`~spiralbayes.templates.TemplateBank`.
    provenance : dict
        How the template was made (generator, settings, versions); JSON-serialisable.
    brightness : (n_x, n_phi) array, optional
        Intensity ``I`` normalised to ``<I>_φ`` at ``x = 1`` (for plots); not stored in banks.
    """

    x: np.ndarray
    phi: np.ndarray
    delta: np.ndarray
    mass: float = float("nan")
    tau0: float = float("nan")
    beta: float = float("nan")
    h_p: float = 0.07
    flaring: float = 0.25
    wavelength: float = 0.87e-3
    hand: str = "R"
    name: str = ""
    provenance: dict = field(default_factory=dict)
    brightness: np.ndarray | None = None

    def __post_init__(self):
        self.x = np.asarray(self.x, dtype=float)
        self.phi = np.asarray(self.phi, dtype=float)
        self.delta = np.asarray(self.delta)
        if self.delta.dtype.kind != "f":
            self.delta = self.delta.astype(float)
        self.hand = validate_hand(self.hand)
        if self.x.ndim != 1 or self.x.size < 2:
            raise InputError(f"SpiralTemplate.x must be 1-D with >= 2 radii, got shape {self.x.shape}")
        if np.any(self.x <= 0) or np.any(np.diff(self.x) <= 0):
            raise InputError("SpiralTemplate.x (r/r_p) must be positive and strictly increasing")
        if self.phi.ndim != 1 or self.phi.size < 2:
            raise InputError(f"SpiralTemplate.phi must be 1-D with >= 2 azimuths, got {self.phi.shape}")
        dphi = np.diff(self.phi)
        if np.any(dphi <= 0) or not np.allclose(dphi, TWO_PI / self.phi.size, rtol=1e-6, atol=1e-9):
            raise InputError(
                "SpiralTemplate.phi must be uniform with spacing 2π/n_phi (cell centres covering "
                "one full turn); resample the map onto such a grid first"
            )
        if self.delta.shape != (self.x.size, self.phi.size):
            raise InputError(
                f"SpiralTemplate.delta has shape {self.delta.shape}, expected (len(x), len(phi)) = "
                f"({self.x.size}, {self.phi.size})"
            )
        if not np.all(np.isfinite(self.delta)):
            raise InputError("SpiralTemplate.delta contains NaN or inf; replace them (e.g. by 0) first")
        if self.brightness is not None:
            self.brightness = np.asarray(self.brightness, dtype=float)
            if self.brightness.shape != self.delta.shape:
                raise InputError("SpiralTemplate.brightness must have the shape of delta")
            if not np.all(np.isfinite(self.brightness)):
                raise InputError("SpiralTemplate.brightness contains NaN or inf; give a finite map normalised to "
                                 "<I>_phi at x = 1, or brightness=None (it is only drawn)")
        for key in ("mass", "tau0", "beta", "h_p", "flaring", "wavelength"):
            setattr(self, key, float(getattr(self, key)))
        _check_parameters(self)
        if not self.name:
            self.name = template_name(self.mass, self.tau0, self.beta, self.hand, prefix="template")

    # ------------------------------------------------------------------ basic properties
    @property
    def shape(self) -> tuple[int, int]:
        """``(n_x, n_phi)``."""
        return self.delta.shape

    @property
    def parameters(self) -> dict:
        """The scalar metadata as a dict (name, mass, tau0, beta, hand, h_p, flaring, wavelength)."""
        return {
            "name": self.name,
            "mass": self.mass,
            "tau0": self.tau0,
            "beta": self.beta,
            "hand": self.hand,
            "h_p": self.h_p,
            "flaring": self.flaring,
            "wavelength": self.wavelength,
        }

    def peak(self) -> float:
        """Peak ``|δ|`` over the grid."""
        return float(np.max(np.abs(self.delta)))

    def rms(self) -> float:
        """Area-weighted RMS of δ over the grid (weights ``x² dln x dφ``, i.e. disc area)."""
        w = self.x**2
        d2 = np.mean(self.delta.astype(float) ** 2, axis=1)
        return float(np.sqrt(np.sum(w * d2) / np.sum(w)))

    # ------------------------------------------------------------------ transformations
    def mirror(self) -> SpiralTemplate:
        """The other hand: ``δ_L(x, φ) = δ_R(x, −φ)``, ``hand`` flipped.

        Exact on the grid when ``phi`` is symmetric under ``φ → −φ (mod 2π)`` (e.g. ``φ_k = 2πk/n``);
        otherwise the map is resampled by linear interpolation. Mirroring twice is the identity.
        """
        delta = _mirror_phi(self.delta, self.phi)
        bright = None if self.brightness is None else _mirror_phi(self.brightness, self.phi)
        other = "L" if self.hand == "R" else "R"
        name = self.name
        if name.endswith("_" + self.hand):
            name = name[:-1] + other
        elif name.endswith("_mirror"):
            name = name[: -len("_mirror")]
        else:
            name = f"{name}_mirror"
        prov = dict(self.provenance)
        prov["mirrored_from"] = self.name
        return replace(self, delta=delta, hand=other, name=name, provenance=prov, brightness=bright)

    def evaluate(self, r, phi, r_p: float, phi_p: float = 0.0) -> np.ndarray:
        """δ at disc-plane points for a planet at radius ``r_p`` and azimuth ``phi_p``.

        Parameters
        ----------
        r : array
            Disc-plane radii, in the same unit as ``r_p`` (arcsec, au, ...).
        phi : array
            Disc-plane azimuths [rad], broadcastable with ``r`` (convention: module docstring).
        r_p : float
            Planet radius (same unit as ``r``), > 0.
        phi_p : float
            Planet azimuth [rad].

        Returns
        -------
        array
            ``δ(r/r_p, φ − φ_p)`` with the broadcast shape of ``r`` and ``phi`` (float64).
            Bilinear interpolation in ``(ln x, φ)``, periodic in φ; zero where ``r/r_p`` is outside
            ``[x[0], x[-1]]``.
        """
        if not np.isfinite(r_p) or r_p <= 0:
            raise InputError(f"r_p must be positive and finite, got {r_p!r}")
        r, phi = np.broadcast_arrays(np.asarray(r, dtype=float), np.asarray(phi, dtype=float))
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.log(r / r_p)
        return bilinear(self.delta, np.log(self.x), self.phi, u, phi - phi_p)

    def on_grid(self, x_new, n_phi: int | None = None) -> SpiralTemplate:
        """Resample onto radii ``x_new`` (r/r_p) and ``n_phi`` uniform azimuths ``2πk/n_phi``.

        Uses :meth:`evaluate` (bilinear in ``(ln x, φ)``); radii outside the current range get 0.
        """
        x_new = np.asarray(x_new, dtype=float)
        n_phi = self.phi.size if n_phi is None else int(n_phi)
        if n_phi < 2:
            raise InputError(f"n_phi must be >= 2, got {n_phi}")
        phi_new = TWO_PI * np.arange(n_phi) / n_phi
        delta = self.evaluate(x_new[:, None], phi_new[None, :], 1.0, 0.0).astype(self.delta.dtype)
        bright = None
        if self.brightness is not None:
            bright = bilinear(
                self.brightness, np.log(self.x), self.phi, np.log(x_new)[:, None], phi_new[None, :]
            )
        prov = dict(self.provenance)
        prov["resampled"] = {"n_x": int(x_new.size), "n_phi": n_phi}
        return replace(self, x=x_new, phi=phi_new, delta=delta, provenance=prov, brightness=bright)

    # ------------------------------------------------------------------ I/O
    def to_hdf5_group(self, group, *, compression: str | None = None) -> None:
        """Store the template in an open ``h5py.Group`` (datasets delta, x, phi; scalars as attributes)."""
        checked_dataset(group, "delta", np.asarray(self.delta, dtype=np.float32), compression=compression)
        checked_dataset(group, "x", self.x)
        checked_dataset(group, "phi", self.phi)
        for k in SCALAR_FIELDS:
            group.attrs[k] = float(getattr(self, k))
        group.attrs["hand"] = self.hand
        group.attrs["name"] = self.name
        group.attrs["provenance"] = self.provenance_json()

    @classmethod
    def from_hdf5_group(cls, group) -> SpiralTemplate:
        """Read a template written by :meth:`to_hdf5_group`."""
        a = group.attrs
        scalars: dict[str, Any] = {k: float(a[k]) for k in SCALAR_FIELDS}
        return cls(x=group["x"][()], phi=group["phi"][()], delta=group["delta"][()], hand=str(a["hand"]),
                   name=str(a["name"]), provenance=json.loads(a.get("provenance", "{}")),
                   **scalars)

    def provenance_json(self) -> str:
        """``provenance`` serialised to JSON (non-JSON values become strings)."""
        return to_json(self.provenance, sort_keys=True)

    def __repr__(self) -> str:  # pragma: no cover - cosmetic
        return (
            f"SpiralTemplate(name={self.name!r}, mass={self.mass:g}, tau0={self.tau0:g}, "
            f"beta={self.beta:g}, hand={self.hand!r}, shape={self.shape}, "
            f"x=[{self.x[0]:.3g}, {self.x[-1]:.3g}])"
        )


def _mirror_phi(values: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Map ``f(φ) → f(−φ)`` on a uniform periodic grid."""
    n = phi.size
    dphi = TWO_PI / n
    offset = phi[0] / dphi  # grid φ_k = (k + offset) dφ
    # −φ_k = (−k − offset) dφ; on the grid iff 2·offset is an integer
    shift = -2.0 * offset
    if abs(shift - round(shift)) < 1e-9:
        idx = (-np.arange(n) + int(round(shift))) % n
        return values[:, idx].copy()
    log.debug("mirror: phi grid not symmetric about 0; interpolating")
    return bilinear(values, np.arange(values.shape[0], dtype=float), phi,
                    np.arange(values.shape[0], dtype=float)[:, None], -phi[None, :]).astype(values.dtype)


def bilinear(table: np.ndarray, u_grid: np.ndarray, phi_grid: np.ndarray, u, phi) -> np.ndarray:
    """Bilinear interpolation of ``table[u, φ]``: linear in ``u`` (zero outside
    ``[u_grid[0], u_grid[-1]]``) and periodic-linear in φ on the uniform ``phi_grid``."""
    u = np.asarray(u, dtype=float)
    phi = np.asarray(phi, dtype=float)
    u, phi = np.broadcast_arrays(u, phi)
    n_u, n_phi = table.shape
    out = np.zeros(u.shape, dtype=float)
    inside = np.isfinite(u) & (u >= u_grid[0]) & (u <= u_grid[-1]) & np.isfinite(phi)
    if not np.any(inside):
        return out
    uu = u[inside]
    i = np.clip(np.searchsorted(u_grid, uu, side="right") - 1, 0, n_u - 2)
    wu = (uu - u_grid[i]) / (u_grid[i + 1] - u_grid[i])
    dphi = TWO_PI / n_phi
    s = (phi[inside] - phi_grid[0]) / dphi
    j0f = np.floor(s)
    wp = s - j0f
    j0 = j0f.astype(np.int64) % n_phi
    j1 = (j0 + 1) % n_phi
    t = table
    v = (
        (1 - wu) * ((1 - wp) * t[i, j0] + wp * t[i, j1])
        + wu * ((1 - wp) * t[i + 1, j0] + wp * t[i + 1, j1])
    )
    out[inside] = v
    return out


LEARNED_PHYSICS = ("slope", "alpha", "orbits")
"""The disc physics a learned template adds to its metadata (:func:`template_metadata`): surface-density
slope ``p``, viscosity ``α`` at r_p and age [orbits]."""

LEARNED_LIMIT_MARGIN = 0.45
"""The limits' margin of a learned template (metadata ``limit_margin``): a mass is excluded only where
the data's upper limit on the template's amplitude is below 0.45, i.e. the template scaled by 0.45 is
excluded (the variants' shrink of 0.8 does the same for them). The largest margin at which every
source of the leave-one-source-out check passes (docs/limits.md §4d; the continuum design held out
needs 0.45, wakeflow 0.5)."""


def limit_margin(meta: dict) -> float:
    """The limits' margin recorded in a template's metadata (:func:`template_metadata`): 1 for a template
    without one, :data:`LEARNED_LIMIT_MARGIN` for a learned template. The limits exclude a mass only where
    the template scaled by it is excluded, and completeness plants the template scaled by it."""
    return float(meta.get("limit_margin") or 1.0)


def template_metadata(template) -> dict:
    """JSON-able description of a template (name and physical parameters).

    Unknown values (NaN, e.g. the cooling time of a FARGO3D run) become ``None``, so the
    metadata is strict JSON and compares equal to itself after a save and load. A map read from a
    simulation carries ``"kind": "simulation"`` (:func:`template_kind`), so that the limits keep it
    out of the generator's families; the generator's templates carry no ``kind``.
    """
    keys = ("name", "mass", "tau0", "beta", "hand", "h_p", "flaring", "wavelength")
    meta = {k: getattr(template, k) for k in keys if getattr(template, k, None) is not None}
    meta.setdefault("name", f"template{id(template)}")
    variant = (getattr(template, "provenance", None) or {}).get("variant")
    if variant is not None:  # the morphology variant (templates.variants)
        meta["variant"] = str(variant)
    provenance = getattr(template, "provenance", None) or {}
    learned = provenance.get("learned")
    if isinstance(learned, dict) and "point" in learned:  # the learned model's disc (templates.learned)
        meta.update({k: float(learned["point"][k]) for k in LEARNED_PHYSICS})
        meta["limit_margin"] = float(learned.get("limit_margin", LEARNED_LIMIT_MARGIN))
    if "asymmetry" in provenance:  # a competing explanation's template (templates.asymmetry)
        meta["kind"] = str(provenance["asymmetry"])
        meta.update({k: provenance[k] for k in ("sigma_r_over_r", "sigma_phi_deg") if k in provenance})
    elif template_kind(template) == SIMULATION:
        meta["kind"] = SIMULATION
    return json_safe(meta)
