"""Antenna gains per solution interval by weighted linear least squares: one implementation for the
diagnostic (:mod:`spiralbayes.calibration.diagnostics`) and the solver (:mod:`.solve`).

A row of :class:`~spiralbayes.visibilities.Visibilities` with ``antenna1 = q``, ``antenna2 = p`` is
corrupted as ``g_p conj(g_q) V`` (:mod:`spiralbayes.simulate.gains`), so the ratio of the data to a
model ``M`` of them is ``r = V_obs / M = a_p a_q exp(i (phi_p - phi_q))`` plus noise of variance
``1 / (|M|^2 w)`` on each of Re r and Im r. Per interval and per connected set of antennas:

* phase: ``arg r_pq = phi_p - phi_q`` with the set's first antenna fixed at 0, solved for the
  increment on the wrapped residual and iterated, so that tens of degrees are solved in full; optional
  further Gauss-Newton steps on ``Im(r_pq exp(-i (phi_p - phi_q)))`` reach the maximum-likelihood
  solution of ``sum w |V - g_p conj(g_q) M|^2`` (the solver's; the diagnostic keeps the angle);
* position (``keep_position``): phases ``2 pi (U_p dl + V_p dm)``, linear in the antennas' uv positions
  ``U_p`` (from the baselines ``u_pq = U_p - U_q``), shift the whole image. Each set's shift is fitted
  and their mean over the observation is removed from every set: a shift constant in time (the disc's
  offset, or the centroid offset of an asymmetric structure such as a spiral, which the gains would
  otherwise absorb) is left to the sky model, shifts that vary between intervals to the gains;
* amplitude: ``Re(r_pq exp(-i (phi_p - phi_q))) / (a_p a_q) - 1 = alpha_p + alpha_q`` to first order in
  the fractional corrections ``alpha`` (the real part of the phase-corrected ratio has unbiased noise,
  unlike ``|r|``); each iteration multiplies the amplitudes by ``1 + alpha``. One iteration from
  ``a = 1`` is the diagnostic's first-order estimate.

The weight of a row is ``|M|^2 w`` times ``(a_p a_q)^2`` of the current amplitudes; rows with model
S/N ``|M| sqrt(w) < min_snr`` are not used. The covariances returned are those of the last linear
step (the Gauss-Newton covariance of the solution).

Units: phases [rad]; amplitudes fractional; times [s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InputError
from ..visibilities import Visibilities

__all__ = ["GroupSolution", "interval_labels", "model_visibilities", "solve_groups"]

PHASE_ITERATIONS = 4
"""Wrapped-residual phase iterations (each converges the phases of a group further; 4 solves 60 deg)."""


@dataclass
class GroupSolution:
    """The gains of one connected set of antennas in one solution interval.

    Attributes
    ----------
    interval : int
        Label of the interval (:func:`interval_labels`).
    rows : ndarray of int
        Rows of the data used (indices into the visibilities passed to :func:`solve_groups`).
    antennas : ndarray of int
        Antenna indices of the set, sorted; ``antennas[0]`` is the phase reference (phase 0).
    phase : ndarray
        Antenna phases [rad] relative to ``antennas[0]``.
    cov_phase : ndarray, shape (n, n)
        Their covariance [rad^2] (zero row and column for the reference).
    amp : ndarray or None
        Antenna amplitudes ``a`` (1 = no error); None when amplitudes were not solved.
    cov_amp : ndarray or None
        Covariance of the fractional amplitudes.
    """

    interval: int
    rows: np.ndarray
    antennas: np.ndarray
    phase: np.ndarray
    cov_phase: np.ndarray
    amp: np.ndarray | None = None
    cov_amp: np.ndarray | None = None


EDGE_TOLERANCE = 1e-6
"""Fraction of an interval by which a time before an interval's edge still counts as on it."""


def model_visibilities(vis: Visibilities, model) -> np.ndarray:
    """The model's visibilities at the data's baselines: an array of ``vis.n`` values or an object with
    ``visibilities(u, v)``."""
    M = model.visibilities(vis.u, vis.v) if hasattr(model, "visibilities") else model
    M = np.asarray(M, dtype=complex).ravel()
    if M.shape != (vis.n,):
        raise InputError(f"model has {M.size} visibilities for {vis.n} data points: give the model at the data's "
                         "baselines (model.visibilities(vis.u, vis.v)) or the model object")
    return M


def interval_labels(time, interval_s: float | None, n: int) -> np.ndarray:
    """Solution interval of each row: one per distinct time (``interval_s`` None), else intervals of
    ``interval_s`` seconds that restart after any gap longer than one interval; all rows one interval
    when there are no times."""
    if time is None:
        return np.zeros(n, dtype=np.int64)
    if interval_s is None:
        return np.unique(time, return_inverse=True)[1].ravel()
    # intervals restart after each gap longer than an interval (a new block of the observation)
    times, row = np.unique(time, return_inverse=True)
    block = np.concatenate([[0], np.cumsum(np.diff(times) > interval_s)])
    start = times[np.searchsorted(block, block)]  # first time of each time's block
    # a time on an interval's edge belongs to the later interval whatever the rounding of (t - start)
    label = np.unique(np.column_stack([block, np.floor((times - start) / interval_s + EDGE_TOLERANCE)]), axis=0,
                      return_inverse=True)[1].ravel()
    return label[row.ravel()]


def solve_groups(vis: Visibilities, M: np.ndarray, interval_s: float | None, min_snr: float, *,
                 amplitude: bool = True, amp_iterations: int = 1, ml_iterations: int = 0,
                 keep_position: bool = False) -> tuple[list[GroupSolution], np.ndarray]:
    """Solve the antenna gains of every interval's connected sets of three or more antennas.

    Parameters
    ----------
    vis : Visibilities
        Data with ``antenna1``, ``antenna2`` (and ``time``; without it one interval).
    M : ndarray of complex, shape (N,)
        The model's visibilities [Jy].
    interval_s : float or None
        Solution interval [s] (:func:`interval_labels`).
    min_snr : float
        Rows with ``|M| sqrt(w)`` below this are not used.
    amplitude : bool
        Also solve the amplitudes.
    amp_iterations : int
        Amplitude iterations (1: the first-order estimate from unit amplitudes).
    ml_iterations : int
        Phase iterations after the wrapped-angle ones that take the residual's imaginary part
        ``Im(r exp(-i (phi_p - phi_q)))`` instead of its angle: Gauss-Newton steps on
        ``sum w |V - exp(i (phi_p - phi_q)) M|^2``, whose fixed point is the maximum-likelihood phase
        solution (CASA gaincal's); the angle's is the same at high S/N and biased where ``|r|`` is noisy.
    keep_position : bool
        Remove from every set's phases the image shift (phases linear in the antennas' uv positions)
        that the sets imply on average over the observation; ``antennas[0]``'s phase is then not held at zero.

    Returns
    -------
    solutions : list of GroupSolution
    use : ndarray of bool, shape (N,)
        Rows above ``min_snr``.
    """
    snr = np.abs(M) * np.sqrt(vis.weights)
    use = snr >= min_snr
    if use.sum() < 3:
        raise InputError(f"only {int(use.sum())} visibilities have model S/N >= min_snr = {min_snr}: "
                         "lower min_snr or check that the model matches the data")
    index = np.flatnonzero(use)
    ratio = vis.V[use] / M[use]
    wt = snr[use] ** 2
    assert vis.antenna1 is not None and vis.antenna2 is not None  # the callers check vis.has_antennas
    a1, a2 = vis.antenna1[use], vis.antenna2[use]
    interval = interval_labels(vis.time, interval_s, vis.n)[use]
    solved = []
    for rows in _solution_groups(interval, a1, a2):
        ants, idx = np.unique(np.concatenate([a1[rows], a2[rows]]), return_inverse=True)
        n_ant = ants.size
        if n_ant < 3:
            continue
        q, p = idx[: rows.size], idx[rows.size:]  # p = antenna2 carries g, q = antenna1 conj(g)
        r, w = ratio[rows], wt[rows]
        phi, cov_phi = _solve_phase(r, w, p, q, n_ant, ml_iterations=ml_iterations)
        if phi is None:
            continue
        if amplitude and ml_iterations:
            # joint maximum likelihood: the phases weighted by the amplitudes found, in turn
            for _ in range(max(int(amp_iterations), 1)):
                amp, _ = _solve_amp(r * np.exp(-1j * (phi[p] - phi[q])), w, p, q, n_ant, amp_iterations)
                if amp is None:
                    break
                phi, cov_phi = _solve_phase(r, w, p, q, n_ant, n_iter=0, ml_iterations=ml_iterations, start=phi,
                                            both=amp[p] * amp[q])
                if phi is None:
                    break
            if amp is None or phi is None:
                continue
        solved.append((rows, ants, p, q, phi, cov_phi))
    if keep_position and solved:
        solved = _keep_position(solved, vis.u[index], vis.v[index])
    out = []
    for rows, ants, p, q, phi, cov_phi in solved:
        amp = cov_amp = None
        if amplitude:
            amp, cov_amp = _solve_amp(ratio[rows] * np.exp(-1j * (phi[p] - phi[q])), wt[rows], p, q, ants.size,
                                      amp_iterations)
            if amp is None:
                continue
        out.append(GroupSolution(int(interval[rows[0]]), index[rows], ants, phi, cov_phi, amp, cov_amp))
    if not out:
        raise InputError("no solution interval has three or more antennas with enough S/N: "
                         "lengthen interval_s or lower min_snr")
    return out, use


def _solution_groups(interval: np.ndarray, a1: np.ndarray, a2: np.ndarray):
    """Row indices of each interval's connected sets of antennas (each needs its own reference)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    order = np.argsort(interval, kind="stable")
    starts = np.flatnonzero(np.diff(interval[order])) + 1
    for rows in np.split(order, starts):
        ants, idx = np.unique(np.concatenate([a1[rows], a2[rows]]), return_inverse=True)
        graph = coo_matrix((np.ones(rows.size), (idx[: rows.size], idx[rows.size:])), shape=(ants.size,) * 2)
        n_comp, label = connected_components(graph, directed=False)
        if n_comp == 1:
            yield rows
            continue
        row_label = label[idx[: rows.size]]
        for c in range(n_comp):
            yield rows[row_label == c]


class _Design:
    """The design matrix of antenna terms, ``+1`` at antenna ``p`` and ``sign`` at ``q`` in each row,
    without column ``drop`` (the reference) when given; two non-zeros a row, so its normal equations
    are sums over rows (``np.bincount``) rather than dense products."""

    def __init__(self, p, q, n_ant: int, sign: float, drop: int | None = None):
        self.p, self.q, self.n, self.sign, self.drop = p, q, n_ant, sign, drop

    def dot(self, x_kept: np.ndarray) -> np.ndarray:
        """``A @ x`` for the kept columns' values ``x_kept``."""
        x = self._full(x_kept)
        return x[self.p] + self.sign * x[self.q]

    def _full(self, x_kept):
        if self.drop is None:
            return x_kept
        return np.insert(x_kept, self.drop, 0.0, axis=0)

    def solve(self, y: np.ndarray, wt: np.ndarray):
        """Weighted least-squares solution of ``A x = y`` (y of shape (rows,) or (rows, k)) and the
        covariance ``(A^T W A)^-1``, or (None, None) when singular."""
        n, p, q, s = self.n, self.p, self.q, self.sign
        normal = (np.bincount(p * n + p, wt, n * n) + np.bincount(q * n + q, wt, n * n)
                  + s * np.bincount(p * n + q, wt, n * n) + s * np.bincount(q * n + p, wt, n * n)).reshape(n, n)
        y2 = y.reshape(y.shape[0], -1)
        rhs = np.stack([np.bincount(p, wt * col, n) + s * np.bincount(q, wt * col, n) for col in y2.T], axis=1)
        if self.drop is not None:
            keep = np.arange(n) != self.drop
            normal, rhs = normal[np.ix_(keep, keep)], rhs[keep]
        try:
            cov = np.linalg.inv(normal)
        except np.linalg.LinAlgError:
            return None, None
        x = cov @ rhs
        return (x[:, 0] if y.ndim == 1 else x), cov


def _solve_phase(ratio, wt, p, q, n_ant: int, n_iter: int = PHASE_ITERATIONS, ml_iterations: int = 0,
                 start=None, both=None):
    """Antenna phases [rad] (antenna 0 of the set fixed at 0) and their covariance.

    ``start``: phases to start from; ``both``: the amplitude products ``a_p a_q`` of the rows (1), which
    weight the Gauss-Newton steps (``w |M|^2 (a_p a_q)^2``, residual ``Im(r e^{-i theta}) / (a_p a_q)``)."""
    A = _Design(p, q, n_ant, -1.0, drop=0)
    phi = np.zeros(n_ant - 1) if start is None else start[1:] - start[0]
    both = np.ones(ratio.size) if both is None else both
    cov = None
    for k in range(n_iter + ml_iterations):
        rotated = ratio * np.exp(-1j * A.dot(phi))
        # wrapped angle first (solves tens of degrees), then Gauss-Newton on the complex residual
        if k < n_iter:
            step, cov = A.solve(np.angle(rotated), wt)
        else:
            step, cov = A.solve(rotated.imag / both, wt * both ** 2)
        if step is None:
            return None, None
        phi = phi + step
    full = np.zeros((n_ant, n_ant))
    full[1:, 1:] = cov
    return np.concatenate([[0.0], phi]), full


def _antenna_uv(u, v, p, q, n_ant: int) -> np.ndarray:
    """Antenna positions ``(n_ant, 2)`` [lambda], mean zero, from the baselines ``u = U_p - U_q`` (the
    interval's mean where it spans several times)."""
    pos, _ = _Design(p, q, n_ant, -1.0, drop=0).solve(np.column_stack([u, v]), np.ones(u.size))
    pos = np.vstack([[0.0, 0.0], pos])
    return pos - pos.mean(axis=0)


def _keep_position(solved: list, u, v) -> list:
    """The groups' phases without the image shift that their mean over all groups implies.

    Phases ``2 pi (U_p dl + V_p dm)`` shift the whole image by ``(dl, dm)``; each group's shift is fitted
    to its centred phases, and the mean over the groups (weighted by their numbers of rows) is removed
    from every group: what stays fixed over the observation is the sky's (the geometry's ``dRA``,
    ``dDec``), what varies from interval to interval is the gains'.
    """
    fits, n_rows = [], []
    for rows, ants, p, q, phi, _ in solved:
        G = 2 * np.pi * _antenna_uv(u[rows], v[rows], p, q, ants.size)  # centred
        fits.append((G, np.linalg.pinv(G) @ (phi - phi.mean())))
        n_rows.append(rows.size)
    weights = np.asarray(n_rows, float) / np.sum(n_rows)
    mean_shift = np.sum([w * shift for w, (_, shift) in zip(weights, fits)], axis=0)
    return [(rows, ants, p, q, phi - G @ mean_shift, cov) for (rows, ants, p, q, phi, cov), (G, _) in zip(solved, fits)]


def _solve_amp(phased_ratio, wt, p, q, n_ant: int, n_iter: int):
    """Antenna amplitudes and the covariance of their fractional errors from the phase-corrected ratios."""
    A = _Design(p, q, n_ant, 1.0)
    amp = np.ones(n_ant)
    cov = None
    for _ in range(max(int(n_iter), 1)):
        both = amp[p] * amp[q]
        step, cov = A.solve((phased_ratio / both).real - 1.0, wt * both ** 2)
        if step is None:
            return None, None
        amp = amp * (1.0 + step)
    return amp, cov
