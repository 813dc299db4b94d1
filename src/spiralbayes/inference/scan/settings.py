"""What the scan does: :class:`ScanSettings`, the ``[grid]`` and ``[scan]`` sections of the configuration.

One object holds every scan option with its one default, for :func:`~spiralbayes.inference.scan.scan`
in a notebook and ``spiralbayes scan`` alike, so the same data give the same grid both ways. The
planet radii are data-driven by default (:meth:`ScanSettings.planet_radii`): ``n_r_p`` equally
spaced radii ``r_p_max k / n_r_p`` (k = 1 ... n_r_p) up to ``r_p_max = 0.6 R_eff`` of the
axisymmetric profile (R_eff: the radius holding 95 % of its flux). For the paper's discs
(R_eff ~ 0.8 arcsec) that is its grid, 25 radii from 0.02 to 0.5 arcsec; to reproduce that grid
exactly, set it::

    ScanSettings(r_p_min=0.02, r_p_max=0.5)          # Python
    [grid]  r_p_min = 0.02   r_p_max = 0.5           # TOML

The engine's numerical knobs (uv grids, NUFFT accuracy) are not user options: they stay in
:class:`~.engine.EngineSettings`, made from these by :meth:`~.engine.EngineSettings.of`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, fields

import numpy as np

from ...exceptions import InputError
from ...model import DEFAULT_CELL_FACTOR, DEFAULT_RULE, RULES
from ...settings import documented, option

# the constants and helpers below are importable too (the configuration and the follow-up use them)
__all__ = ["ScanSettings", "grid_radii"]

POWER_PATHS = ("auto", "polar", "direct")
"""How the power term is computed (:mod:`~spiralbayes.inference.scan.engine`): "auto" takes the cheaper for the data."""
AMPLITUDES = ("fixed", "free")
R_EFF_FRACTION = 0.6
"""The automatic largest planet radius, as a fraction of the profile's R_eff (95 % of the flux)."""
GRID_FIELDS = ("r_p_min", "r_p_max", "n_r_p", "n_phi_p")
"""The fields of the ``[grid]`` section; the other configuration fields form ``[scan]``."""


@documented
@dataclass(frozen=True)
class ScanSettings:
    """Options of :func:`~spiralbayes.inference.scan.scan` (TOML sections ``[grid]`` and ``[scan]``).

    Every field's description (with units) is its ``metadata["doc"]``; ``--print-config`` shows
    them. ``None`` means automatic (written ``0`` in the TOML file). The planet radii are
    ``n_r_p`` equally spaced values from ``r_p_min`` to ``r_p_max`` (:meth:`planet_radii`); the
    default is data-driven, ``r_p_max = 0.6 R_eff`` and ``r_p_min = r_p_max / n_r_p``. The paper's
    grid (25 radii from 0.02 to 0.5 arcsec) is ``ScanSettings(r_p_min=0.02, r_p_max=0.5)``.

    Raises
    ------
    InputError
        A value out of range; the message names the field and what it accepts.
    """

    r_p_min: float | None = option(None, "smallest planet radius [arcsec] (0: r_p_max / n_r_p, equal steps from 0)",
                                   toml=0.0)
    r_p_max: float | None = option(None, "largest planet radius [arcsec] (0: 0.6 R_eff of the axisymmetric profile; "
                                         "the paper's 0.5 for its discs)", toml=0.0)
    n_r_p: int = option(25, "number of planet radii (paper: 25)")
    n_phi_p: int = option(90, "number of planet azimuths over 360 deg, even (paper: 90, i.e. 4 deg)")
    amplitude: str = option("fixed", "'fixed' (the paper's A = 1) or 'free' (best linear spiral amplitude per "
                                     "instance, +1 BIC parameter); used by the verdict")
    quadrature: str = option(DEFAULT_RULE, "'product' (exact, with an error estimate per instance) or 'midpoint' "
                                           "(the earlier cells, for comparison)")
    cell_factor: float = option(DEFAULT_CELL_FACTOR, "midpoint quadrature only: cells at most 1/(cell_factor u_max) "
                                                     "across")
    power_path: str = option("auto", "'auto', 'polar' (uv grids; large N) or 'direct' (the model at every baseline; "
                                     "small N)")
    nthreads: int = option(1, "threads per template for the NUFFTs (results agree to ~1e-9 between counts)")
    building_blocks: bool = option(True, "scan morphology variants through their generator templates (same numbers, "
                                         "~1.3x the generators' cost); false: every template on its own")
    checkpoint: bool = option(True, "checkpoint after each template and resume an interrupted scan (Python: when a "
                                    "checkpoint path is given)")

    def __post_init__(self):
        for f in fields(self):
            error = field_error(f.name, getattr(self, f.name))
            if error:
                raise InputError(f"ScanSettings.{f.name} = {getattr(self, f.name)!r} {error}")
        if self.r_p_min is not None and self.r_p_max is not None and self.r_p_min >= self.r_p_max:
            raise InputError(f"ScanSettings.r_p_min = {self.r_p_min!r} must be smaller than r_p_max = "
                             f"{self.r_p_max!r} [arcsec]")

    @property
    def free_amplitude(self):
        """The ``amplitude`` argument of the verdict: ``"free"`` or None (the paper's A = 1)."""
        return "free" if self.amplitude == "free" else None

    def planet_radii(self, axisymmetric=None) -> np.ndarray:
        """The planet radii [arcsec] scanned for ``axisymmetric`` (needed only for automatic bounds).

        ``n_r_p`` radii equally spaced from ``r_p_min`` to ``r_p_max``; an automatic ``r_p_max`` is
        0.6 R_eff of the model (:data:`R_EFF_FRACTION`), an automatic ``r_p_min`` is
        ``r_p_max / n_r_p`` (so the radii are ``r_p_max k / n_r_p``).
        """
        return grid_radii(self.r_p_min, self.r_p_max, self.n_r_p, axisymmetric)

    @classmethod
    def field_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]


def grid_radii(r_p_min: float | None, r_p_max: float | None, n_r_p: int, axisymmetric=None) -> np.ndarray:
    """``n_r_p`` equally spaced planet radii [arcsec]; ``None`` bounds are automatic (:class:`ScanSettings`).

    Raises
    ------
    InputError
        An automatic bound is asked for but ``axisymmetric`` has no ``R_eff``, or an automatic
        ``r_p_max`` falls below the given ``r_p_min``.
    """
    if r_p_max is None:
        r_eff = getattr(axisymmetric, "R_eff", None)
        if r_eff is None:
            raise InputError("give the planet radii (r_p=..., or r_p_max in ScanSettings / [grid]): the automatic "
                             "grid needs an axisymmetric model with an R_eff")
        r_p_max = R_EFF_FRACTION * float(r_eff() if callable(r_eff) else r_eff)
        if r_p_min is not None and r_p_min >= r_p_max:
            raise InputError(f"r_p_min = {r_p_min!r} arcsec is not below the automatic r_p_max = {r_p_max:.4g} arcsec "
                             f"(0.6 R_eff): lower r_p_min or set r_p_max")
    if r_p_min is None:
        r_p_min = r_p_max / n_r_p
    return np.linspace(float(r_p_min), float(r_p_max), int(n_r_p))


def field_error(name: str, value) -> str | None:
    """What is wrong with ``value`` for the field ``name`` of :class:`ScanSettings` (None: nothing).

    The text completes ``"<option> = <value> "``; the configuration's checks use it too, so a
    rule is written once for Python and TOML.
    """
    if name in ("r_p_min", "r_p_max"):
        ok = value is None or _positive_number(value)
        return None if ok else "must be a positive, finite number [arcsec] (None, or 0 in TOML: automatic)"
    if name == "n_r_p":
        return None if _integer(value) and value >= 1 else "must be an integer >= 1 (the paper uses 25)"
    if name == "n_phi_p":
        ok = _integer(value) and value >= 2 and value % 2 == 0
        return None if ok else "must be a positive, even integer (the paper uses 90, i.e. 4 deg steps)"
    if name == "cell_factor":
        return None if _positive_number(value) else f"must be a positive number (default {DEFAULT_CELL_FACTOR})"
    if name == "nthreads":
        return None if _integer(value) and value >= 1 else "must be an integer >= 1"
    if name in ("building_blocks", "checkpoint"):
        return None if isinstance(value, (bool, np.bool_)) else "must be True or False"
    allowed = {"amplitude": AMPLITUDES, "quadrature": RULES, "power_path": POWER_PATHS}.get(name)
    if allowed is not None and value not in allowed:
        return f"must be one of {', '.join(repr(a) for a in allowed)}"
    return None


def _positive_number(value) -> bool:
    return not isinstance(value, (bool, str)) and isinstance(value, (int, float, np.number)) \
        and math.isfinite(value) and bool(value > 0)


def _integer(value) -> bool:
    return not isinstance(value, (bool, np.bool_)) and isinstance(value, (int, np.integer))


def renamed_keyword(overrides: dict, old: str, new: str, value, where: str):
    """``overrides[old]`` (taken out of it, with a FutureWarning) when given, else ``value``.

    For a keyword argument of ``where`` (a function name) whose name changed to ``new``.

    Raises
    ------
    TypeError
        Both names were given.
    """
    if old not in overrides:
        return value
    if value is not None:
        raise TypeError(f"{where}() got both {old}= and {new}=; {old}= is the old name of {new}=: pass {new}= only")
    warnings.warn(f"{where}({old}=...) is renamed {new}=...; the old name will be removed", FutureWarning,
                  stacklevel=3)
    return overrides.pop(old)
