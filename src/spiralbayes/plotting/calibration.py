"""Plot of a gain solution: each antenna's phase (and amplitude) against time.

Returns a :class:`matplotlib.figure.Figure` built without pyplot's global state.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..calibration import GainSolution

__all__ = ["plot_gain_phases"]


def plot_gain_phases(solution: GainSolution, *, max_antennas: int = 12, figsize=(7.0, 4.2)) -> Figure:
    """Solved antenna phases [deg] against time [min], one line per antenna.

    Phases are shown relative to each interval's mean over the solved antennas (the reference-free
    part a solve measures). With ``"amplitude+phase"`` a second panel shows ``|g| - 1`` [%].

    Parameters
    ----------
    solution : GainSolution
    max_antennas : int
        The antennas with the largest phase rms are drawn (all when there are fewer).
    """
    amplitude = solution.mode != "phase"
    fig = Figure(figsize=(figsize[0], figsize[1] * (1.6 if amplitude else 1.0)), layout="constrained")
    axes = fig.subplots(2 if amplitude else 1, 1, sharex=True, squeeze=False)[:, 0]
    t = (solution.time - solution.time.min()) / 60.0
    phase = np.degrees(np.angle(solution.gains))
    phase = phase - np.nanmean(phase, axis=1, keepdims=True)
    rms = np.nan_to_num(solution.antenna_phase_rms_deg, nan=-1.0)
    shown = np.sort(np.argsort(rms)[::-1][:max_antennas])
    for col in shown:
        label = f"ant {solution.antennas[col]}"
        axes[0].plot(t, phase[:, col], ".-", lw=0.8, ms=3, label=label)
        if amplitude:
            axes[1].plot(t, 100 * (np.abs(solution.gains[:, col]) - 1.0), ".-", lw=0.8, ms=3)
    axes[0].set_ylabel("phase - interval mean [deg]")
    axes[0].set_title(f"antenna gains ({solution.describe()})", fontsize="medium")
    axes[0].legend(fontsize="x-small", ncol=4, loc="best")
    if amplitude:
        axes[1].set_ylabel("|g| - 1 [%]")
    axes[-1].set_xlabel("time since first interval [min] (gaps between blocks included)")
    return fig
