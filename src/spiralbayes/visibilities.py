"""Interferometric visibilities: the container and its validation.

Readers and writers for the formats users bring live beside it (see ``spiralbayes.io``
once present); every reader returns a :class:`Visibilities`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["Visibilities"]

log = logging.getLogger(__name__)


@dataclass
class Visibilities:
    """Visibilities of one source, in the convention of frank, galario and CASA.

    Parameters
    ----------
    u, v : ndarray, shape (N,)
        Baseline coordinates [lambda] (the Measurement Set's UVW[0:2] divided by the
        wavelength, as stored).
    V : ndarray of complex, shape (N,)
        Visibilities [Jy].
    weights : ndarray, shape (N,)
        Statistical weights ``1 / sigma^2`` [Jy^-2], sigma the noise of each of Re and Im.
        Zero weights (flagged data) are dropped at construction, with a logged count.
    wavelength : float, optional
        Observing wavelength [m], when known.
    conjugated : bool
        True if ``V`` is the complex conjugate of the frank/galario convention (e.g. data
        exported by visread). Use :meth:`standardised` before modelling.
    provenance : dict
        Where the data came from (file, reader, conversions applied).
    """

    u: np.ndarray
    v: np.ndarray
    V: np.ndarray
    weights: np.ndarray
    wavelength: float | None = None
    conjugated: bool = False
    provenance: dict = field(default_factory=dict)

    def __post_init__(self):
        self.u = _real_array(self.u, "u")
        self.v = _real_array(self.v, "v")
        self.V = np.asarray(self.V, dtype=complex).ravel()
        self.weights = _real_array(self.weights, "weights")
        self._check_lengths()
        self._check_values()
        self._drop_zero_weights()
        if self.wavelength is not None:
            self.wavelength = float(self.wavelength)
            if not (np.isfinite(self.wavelength) and self.wavelength > 0):
                raise ValueError(f"wavelength must be a positive number of metres, got {self.wavelength!r}")
        self.provenance = dict(self.provenance)

    def _check_lengths(self):
        lengths = {"u": self.u.size, "v": self.v.size, "V": self.V.size, "weights": self.weights.size}
        if len(set(lengths.values())) != 1:
            raise ValueError(f"u, v, V and weights must have the same length, got {lengths}")
        if self.u.size == 0:
            raise ValueError("no visibilities: u, v, V and weights are empty")

    def _check_values(self):
        for name, arr in (("u", self.u), ("v", self.v), ("V", self.V), ("weights", self.weights)):
            bad = ~np.isfinite(arr)
            if bad.any():
                raise ValueError(
                    f"{name} has {bad.sum()} NaN/inf values (first at index {np.argmax(bad)}); "
                    "remove or flag those rows before loading"
                )
        if (self.weights < 0).any():
            n = int((self.weights < 0).sum())
            raise ValueError(
                f"weights has {n} negative values (first at index {np.argmax(self.weights < 0)}); "
                "weights are 1/sigma^2 [Jy^-2] and must be >= 0"
            )

    def _drop_zero_weights(self):
        keep = self.weights > 0
        n_drop = int((~keep).sum())
        if n_drop == self.u.size:
            raise ValueError("every visibility has zero weight (all flagged): nothing to fit")
        if n_drop:
            log.info("dropped %d visibilities with zero weight (flagged data)", n_drop)
            self.u, self.v, self.V, self.weights = (a[keep] for a in (self.u, self.v, self.V, self.weights))
            self.provenance = {**self.provenance, "dropped_zero_weight": n_drop}

    # ------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self.u.size

    @property
    def n(self) -> int:
        """Number of visibility points N (the N of the BIC)."""
        return self.u.size

    @property
    def uv_distance(self) -> np.ndarray:
        """Baseline length [lambda]."""
        return np.hypot(self.u, self.v)

    @property
    def sigma(self) -> np.ndarray:
        """Noise of each of Re V and Im V [Jy]."""
        return 1.0 / np.sqrt(self.weights)

    def standardised(self) -> "Visibilities":
        """The same data in the frank/galario convention (un-conjugated if needed)."""
        if not self.conjugated:
            return self
        prov = {**self.provenance, "conjugated_on_load": True}
        return replace(self, V=np.conj(self.V), conjugated=False, provenance=prov)

    def subset(self, index) -> "Visibilities":
        """A copy with only the selected rows (boolean mask or indices)."""
        return replace(self, u=self.u[index], v=self.v[index], V=self.V[index], weights=self.weights[index])

    def with_weights(self, weights, note: str) -> "Visibilities":
        """A copy with new weights; ``note`` is recorded in the provenance."""
        prov = {**self.provenance, "weights": note}
        return replace(self, weights=np.asarray(weights, dtype=float), provenance=prov)

    def with_V(self, V, note: str | None = None) -> "Visibilities":
        """A copy with new visibility values (e.g. model or residuals)."""
        prov = self.provenance if note is None else {**self.provenance, "V": note}
        return replace(self, V=np.asarray(V, dtype=complex), provenance=prov)


def _real_array(x, name: str) -> np.ndarray:
    arr = np.asarray(x)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name} must be real, got complex values")
    try:
        return arr.astype(float).ravel()
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric: {exc}") from None
