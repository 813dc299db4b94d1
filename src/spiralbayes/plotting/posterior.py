"""Posterior plots: corner plots, trace plots, template probabilities. All return Figures (Agg-safe)."""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..inference.likelihood import PARAMETER_LABELS, PARAMETER_NAMES

__all__ = ["plot_corner", "plot_trace", "plot_template_probabilities"]


def _figure(**kwargs):
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _truth_vector(truths, mu_phi: float | None = None):
    if truths is None:
        return None
    if isinstance(truths, dict):
        unknown = set(truths) - set(PARAMETER_NAMES)
        if unknown:
            raise InputError(f"unknown truth keys {sorted(unknown)}: use {PARAMETER_NAMES}")
        vec = [truths.get(n) for n in PARAMETER_NAMES]
    else:
        vec = list(truths)
        if len(vec) != len(PARAMETER_NAMES):
            raise InputError(f"truths needs {len(PARAMETER_NAMES)} values ({PARAMETER_NAMES})")
    if vec[1] is not None and mu_phi is not None:  # wrap phi_p next to the samples
        vec[1] = mu_phi + (vec[1] - mu_phi + np.pi) % (2 * np.pi) - np.pi
    return [None if v is None else float(v) for v in vec]


def plot_corner(result, template=None, *, truths=None, fig=None, **corner_kwargs):
    """Corner plot of one template's samples (default: the most probable template).

    Parameters
    ----------
    result : PosteriorResult or TemplateRun
    truths : dict or sequence, optional
        True values (``{"r_p": ..., "phi_p": ..., ...}`` or six numbers; None entries skipped);
        drawn as lines. ``phi_p`` is wrapped next to the samples.
    **corner_kwargs
        Passed to ``corner.corner``.
    """
    import corner

    run = result.run(template) if hasattr(result, "run") else result
    samples = run.samples
    mu = float(np.angle(np.mean(np.exp(1j * samples[:, 1]))))
    fig = fig or _figure(figsize=(10, 10))
    kwargs = {"labels": list(PARAMETER_LABELS), "quantiles": [0.16, 0.5, 0.84], "show_titles": True,
              "title_fmt": ".4f", "title_kwargs": {"fontsize": 9}, "label_kwargs": {"fontsize": 9},
              "labelpad": 0.12, "truth_color": "tab:red", **corner_kwargs}
    corner.corner(samples, fig=fig, truths=_truth_vector(truths, mu), **kwargs)
    fig.subplots_adjust(top=0.92, left=0.1, bottom=0.1)
    fig.suptitle(f"{run.name} ({run.mode})", y=0.99)
    return fig


def plot_trace(result, template=None, *, discard: int = 0, max_walkers: int = 32):
    """Walker traces of every parameter (``phi_p`` unwrapped, as sampled)."""
    run = result.run(template) if hasattr(result, "run") else result
    chain = run.chain(discard=discard, thin=1)
    fig = _figure(figsize=(8, 1.6 * len(PARAMETER_NAMES)))
    axes = fig.subplots(len(PARAMETER_NAMES), 1, sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(chain[:, :max_walkers, j], color="k", alpha=0.25, lw=0.5)
        ax.set_ylabel(PARAMETER_LABELS[j])
        burn = run.diagnostics.get("burn_in")
        if burn:
            ax.axvline(burn - discard, color="tab:red", ls="--", lw=1)
    axes[-1].set_xlabel("step")
    fig.suptitle(f"{run.name}: traces (dashed: burn-in)")
    return fig


def plot_template_probabilities(result, *, top: int = 20):
    """Bar chart of ``P(T | data)`` (the ``top`` templates) and the marginals over hand, mass, beta, tau0
    and H/r (``h_p``)."""
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
    ax.set_ylabel("P(template | data)")
    ax.set_ylim(0, 1)
    ax.set_title("templates (grey: Laplace only)")
    for k, key in enumerate(("hand", "mass", "beta", "tau0", "h_p"), start=1):
        sub = fig.add_subplot(gs[k])
        table = marg.get(key, {})
        labels = [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in table]
        sub.bar(range(len(table)), list(table.values()), color="tab:orange")
        sub.set_xticks(range(len(table)))
        sub.set_xticklabels(labels, fontsize=8)
        sub.set_ylim(0, 1)
        sub.set_title(f"P({key})")
    fig.tight_layout()
    return fig
