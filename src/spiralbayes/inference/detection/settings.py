"""How test 3's competing asymmetries are fitted: :class:`AlternativesSettings` (``[alternatives]``)."""

from __future__ import annotations

from dataclasses import dataclass

from ...alternatives import DEFAULT_CELL_FACTOR
from ...settings import option

__all__ = ["AlternativesSettings"]


@dataclass(frozen=True)
class AlternativesSettings:
    """Options of :func:`~spiralbayes.inference.detection.fit_alternatives` and of test 3 in
    :func:`~spiralbayes.inference.detection.detect` (TOML section ``[alternatives]``, which adds the
    pipeline's switches ``fit`` and ``refit_geometry``).

    Every field's description is its ``metadata["doc"]``; ``--print-config`` shows them.
    """

    models: tuple | None = option(None, "which of geometry, arc, lopsided, eccentric_ring, m2 to fit (empty: all)",
                                  toml=[])
    threshold: float = option(10.0, "test 3: the spiral's Delta BIC must exceed the best alternative's by more "
                                    "than this")
    n_starts: int = option(2, "optimiser starts per alternative model (the shapes that best match the residual "
                              "image)")
    # code only
    max_iter: int = option(100, "L-BFGS-B iterations per start", config=False)
    r_max: float | None = option(None, "outer radius of the grid [arcsec] (default: 1.1 times the radius holding "
                                       "99.5 % of the profile's flux)", config=False)
    cell_factor: float = option(DEFAULT_CELL_FACTOR, "radial cells at most 1 / (cell_factor uv_max) wide",
                                config=False)
    nthreads: int = option(1, "threads of the NUFFTs (the pipeline uses [scan] nthreads)", config=False)
