"""Chain files that survive ``kill -9``: emcee's HDF5 layout, rewritten atomically per batch.

One file per run (``chains/<run_name>.h5``, root attribute ``kind = spiralbayes.PosteriorRun``),
one group per template in emcee's ``HDFBackend`` layout — ``chain`` (steps, walkers, dims),
``log_prob``, ``accepted``, ``blobs``, attributes ``iteration``, ``nwalkers``, ``ndim``,
``random_state_0..4`` — so ``emcee.backends.HDFBackend(path, name=template, read_only=True)``
reads it. spiralbayes adds, per group, ``spiralbayes_inputs`` (JSON: everything that changes
the result, checked on resume), and once the template is finished ``result`` (JSON) and
``samples``.

The sampler stores its steps in a :class:`ChainBackend`, an ``emcee.backends.Backend`` (emcee's
in-memory storage interface: ``reset``, ``grow``, ``save_step``, ``get_chain``, ``get_log_prob``,
``get_blobs``, ``iteration``, ``accepted``, ``random_state``) whose :meth:`ChainBackend.flush`
writes everything so far to the chain file. Why not emcee's own ``HDFBackend``: it writes every
step into the file in place, so a kill during a write can leave a damaged file, and it restores
emcee's random state but not the other streams of a run. Here the sampler runs ``flush_every``
steps in memory, then the whole file is copied, updated and renamed into place
(``spiralbayes._provenance.atomic_path``): a kill loses at most the current batch, and the
file on disk is always a consistent snapshot that holds the random state at its last step. A
resumed run (:meth:`ChainBackend.restore`) therefore continues exactly as the uninterrupted one
would have (tested by killing a subprocess, ``tests/test_faults_sampling.py``).
"""

from __future__ import annotations

import json
import shutil
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from emcee.backends import Backend

from ..._hdf5 import refuse_other_kind
from ..._provenance import FORMAT_VERSION, atomic_path, json_default
from ...exceptions import DataFileError, ResumeMismatchError

__all__ = ["CHAIN_KIND", "ChainBackend", "ChainState", "ChainStore"]

CHAIN_KIND = "spiralbayes.PosteriorRun"


@dataclass
class ChainState:
    """What a group holds: the chain so far and, when finished, the result."""

    chain: np.ndarray
    log_prob: np.ndarray
    blobs: np.ndarray | None
    accepted: np.ndarray
    random_state: tuple | None
    inputs: dict = field(default_factory=dict)
    result: dict | None = None
    samples: np.ndarray | None = None

    @property
    def iteration(self) -> int:
        return int(self.chain.shape[0])


class ChainStore:
    """Read and atomically rewrite one group of a chain file (see the module docs)."""

    def __init__(self, path, group: str):
        self.path = Path(path)
        self.group = str(group)

    def read(self) -> ChainState | None:
        """The stored state, or None when the file or group does not exist."""
        import h5py

        if not self.path.exists():
            return None
        refuse_other_kind(self.path, CHAIN_KIND)
        try:
            f = h5py.File(self.path, "r")
        except OSError:
            raise DataFileError(f"chain file {self.path} is not readable HDF5 (damaged?): delete it or choose "
                                "another run_name to start afresh") from None
        with f:
            if self.group not in f:
                return None
            g = f[self.group]
            n = int(g.attrs.get("iteration", 0))
            ndim = int(g.attrs.get("ndim", 0))
            walkers = int(g.attrs.get("nwalkers", 0))
            chain = g["chain"][:n] if "chain" in g else np.empty((0, walkers, ndim))
            log_prob = g["log_prob"][:n] if "log_prob" in g else np.empty((0, walkers))
            blobs = g["blobs"][:n] if "blobs" in g else None
            accepted = g["accepted"][()] if "accepted" in g else np.zeros(walkers)
            rs = [g.attrs[k] for k in sorted(g.attrs) if k.startswith("random_state_")]
            random_state = _random_state(rs) if rs else None
            inputs = json.loads(g.attrs.get("spiralbayes_inputs", "{}"))
            result = json.loads(g.attrs["result"]) if "result" in g.attrs else None
            samples = g["samples"][()] if "samples" in g else None
        return ChainState(chain, log_prob, blobs, accepted, random_state, inputs, result, samples)

    def check_inputs(self, state: ChainState | None, inputs: dict) -> None:
        """Raise :class:`ResumeMismatchError` if ``state`` was written for other ``inputs``."""
        if state is None or not state.inputs:
            return
        want = _canonical(inputs)
        if state.inputs != want:
            diff = sorted(k for k in set(state.inputs) | set(want) if state.inputs.get(k) != want.get(k))
            raise ResumeMismatchError(
                f"chain file {self.path} (group {self.group!r}) was written for different inputs (differ in {diff}): "
                "delete it or choose another run_name to start afresh")

    @contextmanager
    def _rewrite(self):
        """The file open for editing as a temporary copy that replaces it on success (kill-safe)."""
        import h5py

        refuse_other_kind(self.path, CHAIN_KIND)
        with atomic_path(self.path) as tmp:
            if self.path.exists():
                shutil.copyfile(self.path, tmp)
            with h5py.File(tmp, "a") as f:
                f.attrs["kind"] = CHAIN_KIND
                f.attrs["format_version"] = FORMAT_VERSION
                yield f

    def write(self, state: ChainState) -> None:
        """Replace the group with ``state`` (the whole file is rewritten through a temporary copy)."""
        with self._rewrite() as f:
            if self.group in f:
                del f[self.group]
            _write_group(f.create_group(self.group), state)

    def write_root(self, **items) -> None:
        """JSON attributes of the file's root (the run's summary)."""
        with self._rewrite() as f:
            for key, value in items.items():
                f.attrs[key] = json.dumps(value, default=json_default)


class ChainBackend(Backend):
    """emcee's in-memory backend, grown geometrically and flushed to a :class:`ChainStore`.

    Parameters
    ----------
    store : ChainStore
        The chain file and group written by :meth:`flush`.
    inputs : dict
        What the chain was run for (checked on resume), stored with every flush.
    """

    def __init__(self, store: ChainStore, inputs: dict):
        super().__init__()
        self.store = store
        self.inputs = inputs

    def restore(self, saved: ChainState) -> None:
        """Continue from a stored chain: its steps, log posteriors, blobs, acceptances and random state."""
        n, walkers, ndim = saved.chain.shape
        self.reset(walkers, ndim)
        self.chain = np.array(saved.chain, dtype=self.dtype)
        self.log_prob = np.array(saved.log_prob, dtype=self.dtype)
        self.blobs = None if saved.blobs is None else np.array(saved.blobs)
        self.accepted = np.asarray(saved.accepted, dtype=self.dtype).copy()
        self.random_state = saved.random_state
        self.iteration = n

    def grow(self, ngrow, blobs):
        """Room for ``ngrow`` more steps; capacity doubles, so a long run copies its chain O(log n) times."""
        self._check_blobs(blobs)
        need = self.iteration + int(ngrow)
        if need <= len(self.chain):
            return
        size = max(need, 2 * len(self.chain))
        self.chain = _resized(self.chain, size)
        self.log_prob = _resized(self.log_prob, size)
        if blobs is not None:
            blobs = np.asarray(blobs)
            if self.blobs is None:
                self.blobs = np.empty((0, self.nwalkers) + blobs.shape[1:], dtype=blobs.dtype)
            self.blobs = _resized(self.blobs, size)

    def state(self) -> ChainState:
        """The steps so far (copies trimmed to ``iteration``) as a :class:`ChainState`."""
        n = self.iteration
        return ChainState(self.chain[:n].copy(), self.log_prob[:n].copy(),
                          None if self.blobs is None else self.blobs[:n].copy(), self.accepted.copy(),
                          self.random_state, self.inputs)

    def flush(self) -> None:
        """Write the chain so far to the store (atomically: the whole file is replaced)."""
        self.store.write(self.state())


def _resized(a: np.ndarray, size: int) -> np.ndarray:
    out = np.empty((size,) + a.shape[1:], dtype=a.dtype)
    out[:len(a)] = a
    return out


def _write_group(g, s: ChainState) -> None:
    n, walkers, ndim = s.chain.shape if s.chain.ndim == 3 else (0, 0, 0)
    g.attrs["version"] = "spiralbayes"
    g.attrs["nwalkers"] = walkers
    g.attrs["ndim"] = ndim
    g.attrs["iteration"] = n
    g.attrs["has_blobs"] = s.blobs is not None
    g.create_dataset("chain", data=s.chain, maxshape=(None,) + s.chain.shape[1:])
    g.create_dataset("log_prob", data=s.log_prob, maxshape=(None,) + s.log_prob.shape[1:])
    g.create_dataset("accepted", data=s.accepted)
    if s.blobs is not None:
        g.create_dataset("blobs", data=s.blobs, maxshape=(None,) + s.blobs.shape[1:])
    if s.random_state is not None:
        for i, v in enumerate(s.random_state):
            g.attrs[f"random_state_{i}"] = v
    g.attrs["spiralbayes_inputs"] = json.dumps(_canonical(s.inputs), default=json_default)
    if s.result is not None:
        g.attrs["result"] = json.dumps(s.result, default=json_default)
    if s.samples is not None:
        g.create_dataset("samples", data=s.samples)


def _random_state(items) -> tuple:
    """numpy's ``RandomState.get_state()`` tuple from stored attributes."""
    name = items[0].decode() if isinstance(items[0], bytes) else str(items[0])
    return (name, np.asarray(items[1], dtype=np.uint32), int(items[2]), int(items[3]), float(items[4]))


def _canonical(d: dict) -> dict:
    """``d`` as it reads back from JSON (tuples as lists, numpy scalars as numbers)."""
    return json.loads(json.dumps(d, default=json_default))


def _saved_samples(saved: ChainState, store: ChainStore) -> np.ndarray:
    """The samples of a finished group (every finished group is written with them)."""
    if saved.samples is None:
        raise DataFileError(f"chain file {store.path}: group {store.group} is finished but holds no samples "
                            "(damaged?): delete it or choose another run_name to start afresh")
    return saved.samples
