"""Is an axisymmetric model the fit of these visibilities? (its recorded data hash against theirs).

A frank fit records ``provenance["data_hash"]`` (u, v, V and weights; ``data_hash``).
A model fitted to other data makes every Δχ² of a scan or posterior meaningless (a model of
another disc leaves the whole disc in the residuals: Δχ² of hundreds "detected"), so the scan and
the pipelines refuse it unless told the difference is intended (injected signals).
"""

from __future__ import annotations

from .._provenance import data_hash
from ..exceptions import InputError

__all__ = ["check_fitted_to", "fitted_data_hash", "same_data"]


def fitted_data_hash(model) -> str | None:
    """The data hash a model records (None for a bare profile or a model built without data)."""
    provenance = getattr(model, "provenance", None) or {}
    value = provenance.get("data_hash") if isinstance(provenance, dict) else None
    return str(value) if value else None


def same_data(model, vis) -> bool | None:
    """True/False when the model records its data hash (as given or in the frank convention), else None."""
    recorded = fitted_data_hash(model)
    if recorded is None:
        return None
    candidates = {data_hash(vis.u, vis.v, vis.V, vis.weights)}
    standard = vis.standardised() if hasattr(vis, "standardised") else vis
    candidates.add(data_hash(standard.u, standard.v, standard.V, standard.weights))
    return recorded in candidates


def check_fitted_to(model, vis, what: str = "the axisymmetric model") -> None:
    """Raise :class:`~spiralbayes.exceptions.InputError` when ``model`` records a fit to other data.

    Parameters
    ----------
    model : AxisymmetricModel or any object
        Objects without a recorded data hash pass (a profile built by hand).
    vis : Visibilities
    what : str
        The model, for the message (e.g. the file it came from).
    """
    if same_data(model, vis) is False:
        raise InputError(
            f"{what} was fitted to other data (data hash {fitted_data_hash(model)}, these visibilities "
            f"{data_hash(vis.u, vis.v, vis.V, vis.weights)}): refit frank on these data (fit_axisymmetric(vis, ...); "
            "in a configuration leave [frank] model empty), or pass allow_other_data=True if the difference is "
            "intended (e.g. injected signals)")
