"""Posterior plots: corner plots, trace plots, hypothesis probabilities. All return Figures (Agg-safe).

The corner plot shows the planet in the units people read: ``r_p`` in au (when a distance is
given; arcsec otherwise, and the title gives both), ``phi_p`` in degrees, offsets in mas,
angles in degrees, the amplitude ``A``. Panel titles are short (median and 68 % interval rounded
to two significant digits of the error) so that neighbours do not overlap; truths
(injections) can be marked; a companion panel in the empty upper triangle gives the verdict,
``P(planet | data)``, the Bayes factor and the hypotheses' probabilities.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..inference.posterior.conditional import PARAMETER_NAMES
from ..inference.posterior.results import MASS_SAMPLE_NAMES, SAMPLE_NAMES
from ..units import wrap_angle

__all__ = ["plot_corner", "plot_hypotheses", "plot_template_probabilities", "plot_trace"]

def _figure(**kwargs):
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _columns(distance: float | None, mass: bool = False):
    """Per sample column: (label, unit, factor from the stored unit); 1 arcsec at 1 pc is 1 au.
    ``mass``: a continuous-mass run's ``M_p`` [M_th] and ``M_p_MJup`` columns follow."""
    r = ("r_p", "au", float(distance)) if distance else ("r_p", "arcsec", 1.0)
    cols = [r, (r"\phi_p", "deg", 180.0 / np.pi), ("A", "", 1.0), ("i", "deg", 1.0), ("PA", "deg", 1.0),
            (r"\Delta RA", "mas", 1e3), (r"\Delta Dec", "mas", 1e3)]
    return cols + [("M_p", "M_th", 1.0), ("M_p", "M_Jup", 1.0)] if mass else cols


def _display(samples: np.ndarray, distance: float | None) -> np.ndarray:
    out = samples.astype(float).copy()
    for j, (_, _, factor) in enumerate(_columns(distance, samples.shape[1] == len(MASS_SAMPLE_NAMES))):
        out[:, j] *= factor
    return out


def _truth_vector(truths, samples: np.ndarray, distance: float | None):
    """Truths in display units (phi_p wrapped next to the samples); keys of :data:`SAMPLE_NAMES`."""
    if truths is None:
        return None
    mass = samples.shape[1] == len(MASS_SAMPLE_NAMES)
    names = MASS_SAMPLE_NAMES if mass else SAMPLE_NAMES
    if isinstance(truths, dict):
        unknown = set(truths) - set(names)
        if unknown:
            raise InputError(f"unknown truth keys {sorted(unknown)}: use {names}")
        vec = [truths.get(n) for n in names]
    else:
        vec = list(truths)
        if len(vec) == len(PARAMETER_NAMES):  # (r_p, phi_p, inc, PA, dRA, dDec): no amplitude
            vec = vec[:2] + [None] + vec[2:]
        vec += [None] * (len(names) - len(vec)) if len(vec) == len(SAMPLE_NAMES) else []
        if len(vec) != len(names):
            raise InputError(f"truths needs {len(SAMPLE_NAMES)} values ({SAMPLE_NAMES}) or {len(PARAMETER_NAMES)}")
    if vec[1] is not None:
        mu = float(np.angle(np.mean(np.exp(1j * samples[:, 1]))))
        vec[1] = float(wrap_angle(vec[1], mu - np.pi))
    factors = [c[2] for c in _columns(distance, mass)]
    return [None if v is None else float(v) * f for v, f in zip(vec, factors)]


def _title(label: str, unit: str, x: np.ndarray) -> str:
    lo, med, hi = np.percentile(x, [16, 50, 84])
    err = max(hi - med, med - lo, 1e-300)
    digits = int(np.clip(1 - np.floor(np.log10(err)), 0, 8))
    fmt = f"{{:.{digits}f}}"
    unit = f" {unit}" if unit else ""
    return f"${label} = {fmt.format(med)}^{{+{fmt.format(hi - med)}}}_{{-{fmt.format(med - lo)}}}${unit}"


def plot_corner(result, template=None, *, truths=None, distance: float | None = None, fig=None,
                summary_panel: bool = True, **corner_kwargs):
    """Corner plot of one template's posterior (default: the most probable template).

    Parameters
    ----------
    result : PosteriorResult or TemplateRun
    truths : dict or sequence, optional
        Injected values in the package's units: ``{"r_p": arcsec, "phi_p": rad, "A": ..., "inc": deg,
        "PA": deg, "dRA": arcsec, "dDec": arcsec}`` (None entries skipped; a continuous-mass run also
        takes ``"M_p"`` [M_th] and ``"M_p_MJup"``), or 7 (or 6, without ``A``) numbers in that order.
        Drawn as lines. A continuous-mass run's corner has ``M_p`` in M_th and in M_Jup.
    distance : float, optional
        Distance [pc]: ``r_p`` is shown in au (arcsec otherwise; the title gives both).
    summary_panel : bool
        Add the panel with the verdict and the hypotheses' probabilities (needs a PosteriorResult).
    **corner_kwargs
        Passed to ``corner.corner``.
    """
    import corner

    run = result.run(template) if hasattr(result, "run") else result
    samples = run.samples
    mass = samples.shape[1] == len(MASS_SAMPLE_NAMES)
    if samples.shape[1] != len(SAMPLE_NAMES) and not mass:
        raise InputError(f"samples have {samples.shape[1]} columns, expected {len(SAMPLE_NAMES)} ({SAMPLE_NAMES})")
    data = _display(samples, distance)
    cols = _columns(distance, mass)
    keep = [j for j in range(data.shape[1]) if np.ptp(data[:, j]) > 0]  # A = 1 fixed: no column
    labels = [f"${c[0]}$" + (f" [{c[1]}]" if c[1] else "") for c in cols]
    truth = _truth_vector(truths, samples, distance)
    fig = fig or _figure(figsize=(11, 11))
    kwargs = {"labels": [labels[j] for j in keep], "quantiles": [0.16, 0.5, 0.84], "show_titles": False,
              "label_kwargs": {"fontsize": 10}, "labelpad": 0.08, "truth_color": "tab:red", "quiet": True,
              "max_n_ticks": 4, **corner_kwargs}
    corner.corner(data[:, keep], fig=fig, truths=None if truth is None else [truth[j] for j in keep], **kwargs)
    axes = np.array(fig.axes).reshape(len(keep), len(keep))
    for k, j in enumerate(keep):
        axes[k, k].set_title(_title(cols[j][0], cols[j][1], data[:, j]), fontsize=8.5)
        for tick in axes[-1, k].get_xticklabels():
            tick.set_fontsize(8)
    if distance:  # r_p in arcsec too
        r_title = _title("r_p", "arcsec", samples[:, 0])
        axes[0, 0].set_title(axes[0, 0].get_title() + "\n" + r_title, fontsize=8.5)
    fig.subplots_adjust(top=0.94, left=0.08, bottom=0.08, right=0.98, wspace=0.06, hspace=0.06)
    if summary_panel and hasattr(result, "runs"):
        _summary_panel(fig, result, run)
    fig.suptitle(f"{run.name} ({run.mode})", y=0.995, fontsize=11)
    return fig


def _summary_panel(fig, result, run) -> None:
    """The verdict and the hypotheses' probabilities, in the corner plot's empty upper right."""
    ax = fig.add_axes([0.58, 0.66, 0.38, 0.26])
    probs = result.hypothesis_probabilities if result.null is not None else result.template_probabilities
    names = sorted(probs, key=probs.get, reverse=True)[:8]
    colors = ["tab:gray" if n == "no planet" else ("tab:red" if n == run.name else "tab:blue") for n in names]
    ax.barh(range(len(names))[::-1], [probs[n] for n in names], color=colors)
    ax.set_yticks(range(len(names))[::-1])
    ax.set_yticklabels(names, fontsize=7)
    ax.set_xlim(0, 1)
    ax.set_xlabel("P(hypothesis | data)", fontsize=8)
    ax.tick_params(axis="x", labelsize=7)
    text = result.verdict.split(";")[0]
    if result.null is not None:
        text += f"\nP(right-handed | planet) = {result.p_right_handed:.3g}"
    ax.set_title(text, fontsize=8, loc="left", wrap=True)


def plot_trace(result, template=None, *, discard: int = 0, max_walkers: int = 32):
    """Walker traces of every sampled parameter (``phi_p`` in degrees, on the circle)."""
    run = result.run(template) if hasattr(result, "run") else result
    chain = run.chain(discard=discard, thin=1)
    fig = _figure(figsize=(8, 1.6 * len(PARAMETER_NAMES)))
    axes = fig.subplots(len(PARAMETER_NAMES), 1, sharex=True)
    labels = [r"$r_p$ [arcsec]", r"$\phi_p$ [deg]", "$i$ [deg]", "PA [deg]", r"$\Delta$RA [mas]", r"$\Delta$Dec [mas]"]
    factors = [1.0, 180.0 / np.pi, 1.0, 1.0, 1e3, 1e3]
    for j, ax in enumerate(axes):
        ax.plot(chain[:, :max_walkers, j] * factors[j], color="k", alpha=0.25, lw=0.5,
                ls="none" if j == 1 else "-", marker="," if j == 1 else None)
        ax.set_ylabel(labels[j], fontsize=8)
        burn = run.diagnostics.get("burn_in")
        if burn:
            ax.axvline(burn - discard, color="tab:red", ls="--", lw=1)
    axes[-1].set_xlabel("step")
    fig.suptitle(f"{run.name}: traces (dashed: burn-in)")
    return fig


def plot_hypotheses(result, *, top: int = 12):
    """Bar chart of ``P(hypothesis | data)``: "no planet" and the templates."""
    probs = result.hypothesis_probabilities
    names = sorted(probs, key=probs.get, reverse=True)[:top]
    fig = _figure(figsize=(7, 0.35 * len(names) + 1.5))
    ax = fig.add_subplot()
    ax.barh(range(len(names))[::-1], [probs[n] for n in names],
            color=["tab:gray" if n == "no planet" else "tab:blue" for n in names])
    ax.set_yticks(range(len(names))[::-1])
    ax.set_yticklabels(names, fontsize=8)
    ax.set_xlim(0, 1)
    ax.set_xlabel("P(hypothesis | data)")
    ax.set_title(result.verdict.split(";")[0], fontsize=9, loc="left")
    fig.tight_layout()
    return fig


def plot_template_probabilities(result, *, top: int = 20):
    """Bar chart of ``P(T | data, planet)`` (the ``top`` templates) and the marginals over hand, mass, beta,
    tau0 and H/r (``h_p``)."""
    probs = result.template_probabilities
    names = sorted(probs, key=probs.get, reverse=True)[:top]
    marg = result.marginals()
    fig = _figure(figsize=(12.5, 4))
    gs = fig.add_gridspec(1, 6, width_ratios=[3, 1, 1, 1, 1, 1])
    ax = fig.add_subplot(gs[0])
    modes = {r.name: r.mode for r in result.runs}
    colors = ["tab:blue" if modes[n] == "mcmc" else "tab:gray" for n in names]
    ax.bar(range(len(names)), [probs[n] for n in names], color=colors)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names, rotation=70, fontsize=7, ha="right")
    ax.set_ylabel("P(template | data, planet)")
    ax.set_ylim(0, 1)
    p = getattr(result, "p_planet", float("nan"))
    ax.set_title(f"templates (grey: Laplace only); P(planet | data) = {p:.3g}", fontsize=9)
    for k, key in enumerate(("hand", "mass", "beta", "tau0", "h_p"), start=1):
        sub = fig.add_subplot(gs[k])
        table = marg.get(key, {})
        labels = [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in table]
        sub.bar(range(len(table)), list(table.values()), color="tab:orange")
        sub.set_xticks(range(len(table)))
        sub.set_xticklabels(labels, fontsize=8)
        sub.set_ylim(0, 1)
        sub.set_title(f"P({key} | planet)", fontsize=9)
    fig.tight_layout()
    return fig
