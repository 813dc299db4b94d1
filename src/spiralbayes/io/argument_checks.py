"""Type checks of the first arguments of the stage functions, for notebook users.

A path, a template name or ``None`` where an object is expected failed deep inside a stage with
an ``AttributeError`` (or, for a path given as the data, "only 0 visibilities"). These checks
raise :class:`~spiralbayes.exceptions.InputError` naming the argument, what it was given and
what it accepts, before any work is done. They test attributes, not classes, so that any object
with the interface a stage uses (a result read back from a file, a test double) is accepted.
"""

from __future__ import annotations

import os

from ..exceptions import InputError

__all__ = ["check_scan_arguments", "check_scan_result"]

_VISIBILITY_FIELDS = ("u", "v", "V", "weights")
_TEMPLATE_FIELDS = ("x", "phi", "delta", "hand")
_SCAN_FIELDS = ("cross", "power", "templates", "r_p", "phi_p")


def _given(value) -> str:
    """``'obs.txt' (a str)``: what was passed, short."""
    text = repr(value)
    return f"{text[:60]}{'...' if len(text) > 60 else ''} (a {type(value).__name__})"


def _is_path(value) -> bool:
    return isinstance(value, (str, bytes, os.PathLike))


def check_scan_arguments(vis, axisymmetric, templates) -> None:
    """Refuse data, an axisymmetric model or templates of the wrong kind, naming the argument.

    Parameters
    ----------
    vis : Visibilities
        Anything with ``u``, ``v``, ``V`` and ``weights``; a path is refused with the loader to use.
    axisymmetric : AxisymmetricModel or (profile, V_A)
        Not None, not a path.
    templates : TemplateBank or sequence of SpiralTemplate
        Not a string or path; the items of a list or tuple must be templates.

    Raises
    ------
    InputError
    """
    if _is_path(vis):
        raise InputError(f"vis = {_given(vis)} is a file name, not visibilities: load it first, "
                         f"vis = sb.load_visibilities({str(vis)!r})")
    if not all(hasattr(vis, name) for name in _VISIBILITY_FIELDS):
        raise InputError(f"vis = {_given(vis)} is not visibilities: pass a Visibilities "
                         "(sb.load_visibilities(path), or Visibilities(u, v, V, weights))")
    if axisymmetric is None or _is_path(axisymmetric):
        hint = (f"load it with AxisymmetricModel.load({str(axisymmetric)!r}) or " if _is_path(axisymmetric) else "")
        raise InputError(f"axisymmetric = {_given(axisymmetric)}: pass the disc's axisymmetric model ({hint}fit it "
                         "with sb.fit_axisymmetric(vis, geometry)), or a (profile, V_A) pair")
    if _is_path(templates):
        raise InputError(f"templates = {_given(templates)}: pass a TemplateBank or a list of SpiralTemplate "
                         "(e.g. sb.default_bank(), or TemplateBank.load(path) for a bank file), not a name")
    if templates is None:
        raise InputError("templates = None: pass a TemplateBank or a list of SpiralTemplate (e.g. sb.default_bank())")
    if isinstance(templates, (list, tuple)):
        for i, item in enumerate(templates):
            if not all(hasattr(item, name) for name in _TEMPLATE_FIELDS):
                raise InputError(f"templates[{i}] = {_given(item)} is not a SpiralTemplate: pass a TemplateBank or "
                                 "a list of SpiralTemplate (make_template(...), sb.default_bank().select(...))")


def check_scan_result(scan_result, name: str = "scan_result") -> None:
    """Refuse anything but a scan's result as ``name``, with where one comes from.

    Raises
    ------
    InputError
        For None, a path (with the loader to use) or an object without a scan's Δχ² maps.
    """
    if _is_path(scan_result):
        raise InputError(f"{name} = {_given(scan_result)} is a file name: load it first, "
                         f"ScanResult.load({str(scan_result)!r})")
    if not all(hasattr(scan_result, field) for field in _SCAN_FIELDS):
        raise InputError(f"{name} = {_given(scan_result)} is not a scan result: pass the ScanResult returned by "
                         "sb.scan(vis, disc, templates) (or ScanResult.load(path))")
