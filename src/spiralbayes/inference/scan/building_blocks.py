"""Variant banks scanned through their building blocks: one scan of each generator template and
each near-planet peak instead of one per variant.

A morphology variant (:mod:`spiralbayes.templates.variants`) is ``δ = s T + a B``: a generator
template ``T`` (mass, τ0, β, H/r, hand) times ``s`` plus a near-planet peak ``B`` (mass, τ0, H/r,
peak width; no β, and the same for both hands when it is mirror-symmetric) times ``a``. A variant
with a broad wake (``s T + w W + a B``) is not in that span: its member becomes a generator of its
own, ``T' = δ - a B`` with ``s = 1``, sharing the group's ``B`` (one more plain scan per such
member, and its cross-power pass; ``B`` still recovered from a variant without a broad wake). The
perturbation visibilities are linear in δ, so at every planet position

    cross = s cross_T + a cross_B,
    power = s^2 power_TT + 2 s a power_TB + a^2 power_BB,

where ``power_TB = Re sum_k w_k ΔV_T,k conj(ΔV_B,k)`` comes from the same uv grids as the powers
(:func:`~.uv_levels.power_all_phi` with a second spectrum; the interpolation is linear in ``G``,
so this is the plain path's arithmetic regrouped, not an approximation). A group (one ``B``, its
generators, their variants) costs one plain scan per ``T`` and per ``B`` and one cross-power pass
per ``T``, whatever the number of variants: the default variant bank (576 templates) scans
192 ``T`` and 48 ``B``. On the polar path the blocks' fluxes (real) go through the type-3
transform two at a time (:func:`pair_transforms`: one transform to ``±q`` for the price of 1.37),
two groups together; the transform's change of the power is measured once per scan against the
one-at-a-time transform (:func:`check_pairs`, ~1e-8 relative) and enters the error estimates like
the power path's own check.

The blocks come from the bank itself, not from the generators: ``T`` is the variant with
``s = 1, a = 0`` (the compromise, stored bit for bit as the generator's template) and ``B`` is
recovered from the variant of largest ``|a|``, ``B = (δ_k - s_k T) / a_k`` in double precision,
so that this variant is reproduced exactly. Every other member is checked, ``|δ_j - s_j T - a_j B|``
within a few float32 rounding units of its own values (the bank stores δ in single precision);
a template that fails the check, whose group has no ``T`` or that lacks the provenance
(``provenance["variant_constants"]``) is scanned plainly. The structured result therefore
differs from the plain scan of the stored templates only by their float32 rounding (≤ 2^-24 of
δ per cell; measured: tests/inference/scan/test_building_blocks.py).

Error estimates: the quadrature's bound is subadditive in δ (an L1 norm and sums of ``|C|``
against mean ``|δ|``), so ``|s| B_T + |a| B_B`` bounds the variant's; the power path's measured
relative discrepancy multiplies ``(|s| sqrt(P_TT) + |a| sqrt(P_BB))^2 >= P`` (its error in each
block is relative to that block's power), and the pairing's measured change adds to the power's.
For ``a = 0`` the cross term and the bound are the plain scan's bit for bit (and, on the direct
path, which transforms one at a time, every number).
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass, field, replace

import numpy as np

from ..._threads import blas_threads
from ...exceptions import InputError
from ...quadrature import ProductQuadrature, TemplateSpectrum
from ...templates.template import SpiralTemplate
from ...templates.variants import Variant
from .engine import (
    CHECK_SAFETY,
    ScanContext,
    TemplateTerms,
    _cross_all_phi,
    _error_estimates,
    _node_transform,
)
from .uv_levels import power_all_phi

__all__ = ["VariantGroup", "building_block_groups", "pair_terms", "scan_group"]

log = logging.getLogger(__name__)

STRUCTURE_VERSION = 2
"""Recorded in the resume key of a scan that used building blocks."""
ROUNDING_UNITS = 8.0
"""A member passes when ``|δ_j - s_j T - a_j B| <= ROUNDING_UNITS 2^-24 (max|δ_j| + |a_j / a_k| max|δ_k|)``
(``k`` the member ``B`` was recovered from): float32 storage errs by half a unit of 2^-23."""


@dataclass
class Generator:
    """A generator template ``T`` and its variants: ``members`` are ``(index, s, a)``, the row of the
    scan, the factor on ``T`` and the factor on the group's ``B``."""

    template: SpiralTemplate
    members: list = field(default_factory=list)


@dataclass
class VariantGroup:
    """One near-planet peak ``B`` (None when every member has ``a = 0``) and the generators using it."""

    blob: SpiralTemplate | None
    generators: list

    @property
    def indices(self) -> list[int]:
        return [m[0] for g in self.generators for m in g.members]


def _grid_key(template) -> str:
    x = np.ascontiguousarray(np.asarray(template.x, dtype=float))
    phi = np.ascontiguousarray(np.asarray(template.phi, dtype=float))
    return hashlib.sha1(x.tobytes() + phi.tobytes() + str(np.shape(template.delta)).encode()).hexdigest()


def _coefficients(template) -> tuple | None:
    """``(s, a, width, broad)`` of a variant template from its provenance, or None: ``δ = s T + a B``
    (+ a broad wake when ``broad`` is true: such a member is not in the span of ``T`` and ``B`` and
    becomes a generator of its own, ``δ - a B``, sharing ``B``; module docstring)."""
    prov = getattr(template, "provenance", None) or {}
    c = prov.get("variant_constants")
    if not isinstance(c, dict):
        return None
    try:
        v = Variant.from_constants(prov.get("variant", ""), c)
        s, a = v.scale_at(float(template.mass)), v.blob_amplitude(float(template.mass))
    except (KeyError, TypeError, ValueError):
        return None
    if not (np.isfinite(s) and np.isfinite(a)):
        return None
    return s, a, float(v.blob_width), v.broad != 0.0


def _mirror_delta(template, delta: np.ndarray) -> np.ndarray:
    return np.asarray(replace(template, delta=delta, brightness=None).mirror().delta, dtype=float)


def building_block_groups(templates) -> tuple[list[VariantGroup], list[int]]:
    """Split ``templates`` into groups scanned through building blocks and the indices scanned plainly
    (module docstring)."""
    templates = list(templates)
    by_t: dict = {}
    plain = []
    for i, t in enumerate(templates):
        coef = _coefficients(t)
        if coef is None:
            plain.append(i)
            continue
        key = (float(t.mass), float(t.tau0), float(t.beta), float(t.h_p), str(t.hand), _grid_key(t))
        by_t.setdefault(key, []).append((i, *coef))
    by_blob: dict = {}
    for key, members in by_t.items():
        base = next((m for m in members if m[1] == 1.0 and m[2] == 0.0 and not m[4]), None)
        if base is None:  # no generator template in the bank to build on
            plain.extend(m[0] for m in members)
            continue
        mass, tau0, _, h_p, hand, grid = key
        T = templates[base[0]]
        plain.extend(m[0] for m in members if m[4] and m[2] == 0.0)  # a broad wake alone: nothing to share
        members = [m for m in members if not (m[4] and m[2] == 0.0)]
        zero = [m for m in members if m[2] == 0.0]
        widths = sorted({m[3] for m in members if m[2] != 0.0})
        if not widths:
            by_blob.setdefault((mass, tau0, h_p, None, grid), []).append((hand, T, zero))
        for n, width in enumerate(widths):  # members with a = 0 go with the first peak
            chosen = [m for m in members if m[2] != 0.0 and m[3] == width] + (zero if n == 0 else [])
            by_blob.setdefault((mass, tau0, h_p, width, grid), []).append((hand, T, chosen))
    groups: list[VariantGroup] = []
    for gens in by_blob.values():
        groups.extend(g for g in _build_groups(templates, gens, plain) if g.indices)
    return groups, sorted(plain)


def _build_groups(templates, gens, plain: list) -> list[VariantGroup]:
    """The groups of one peak (mass, τ0, H/r, width): recover ``B``, share it between the hands when
    it is mirror-symmetric, check every member."""
    candidates = [(abs(m[2]), hand, T, m) for hand, T, chosen in gens for m in chosen if m[2] != 0.0 and not m[4]]
    if not candidates:
        plain.extend(m[0] for _, _, chosen in gens for m in chosen if m[4])
        return [VariantGroup(None, [Generator(T, [(m[0], m[1], m[2]) for m in chosen if not m[4]])
                                    for _, T, chosen in gens])]
    _, hand0, T0, k = max(candidates, key=lambda c: (c[0], c[1] == "R"))
    dk = np.asarray(templates[k[0]].delta, dtype=float)
    blob = (dk - k[1] * np.asarray(T0.delta, dtype=float)) / k[2]
    scale_k = float(np.max(np.abs(dk))) / abs(k[2])
    blobs = {hand0: blob}
    other = "L" if hand0 == "R" else "R"
    mirrored = _mirror_delta(T0, blob)
    symmetric = float(np.max(np.abs(mirrored - blob))) <= ROUNDING_UNITS * 2.0 ** -24 * scale_k
    blobs[other] = blob if symmetric else mirrored
    out: dict = {}
    work, other_work = np.empty_like(blob), np.empty_like(blob)
    for hand, T, chosen in gens:
        Td = np.asarray(T.delta, dtype=float)
        kept, own = [], []
        for index, s, a, _, broad in chosen:
            if broad:  # its own generator δ - a B, sharing B (module docstring)
                delta = np.asarray(templates[index].delta, dtype=float) - a * blobs[hand]
                own.append(Generator(replace(templates[index], delta=delta, brightness=None,
                                             name=f"blocks:{templates[index].name}:T",
                                             provenance={"recovered_from": templates[index].name}),
                                     [(index, 1.0, a)]))
                continue
            if a != 0.0:  # in place: this check touches every cell of 384 maps for the default bank
                np.multiply(Td, s, out=work)
                work += np.multiply(blobs[hand], a, out=other_work)
                np.subtract(templates[index].delta, work, out=work)
                np.abs(work, out=work)
                tol = ROUNDING_UNITS * 2.0 ** -24 * (float(np.max(np.abs(templates[index].delta))) + abs(a) * scale_k)
                if float(work.max()) > tol:
                    log.info("template %s is not s T + a B to float32 rounding: scanned plainly",
                             templates[index].name)
                    plain.append(index)
                    continue
            kept.append((index, s, a))
        slot = "shared" if symmetric else hand
        if slot not in out:
            b = blobs[hand]
            out[slot] = VariantGroup(replace(T, delta=b, brightness=None, name=f"blocks:{T.name}:B",
                                             provenance={"recovered_from": templates[k[0]].name}), [])
        if kept:
            out[slot].generators.append(Generator(T, kept))
        out[slot].generators.extend(own)
    return [g for g in out.values() if g.generators]


# --- the scan of a group ------------------------------------------------------------------------------
@dataclass
class _Block:
    cross: np.ndarray
    power: np.ndarray
    transform: np.ndarray  # P_hat at the uv nodes, or ΔV at the rotated baselines
    bound: float


def _pair_plan(context: ScanContext, quad):
    """A type-3 plan from the nodes to the uv nodes and their mirror images ``-q`` (cached)."""
    key = (quad.key, "pair")
    if key not in context._plan_cache:
        import ducc0

        nodes = context.level(quad).nodes()
        context._plan_cache[key] = ducc0.nufft.experimental.plan3(
            coord_in=2 * np.pi * quad.positions(), coord_out=np.concatenate([nodes, -nodes]),
            epsilon=context.settings.power_epsilon, nthreads=context.nthreads)
    return context._plan_cache[key]


def pair_transforms(context: ScanContext, quad, fluxes: list[np.ndarray]) -> list[np.ndarray]:
    """``P_hat`` of each real flux vector at the uv nodes, two per transform (polar path).

    The fluxes are real, so ``P_hat(-q) = conj(P_hat(q))``: the transform of ``f1 + i f2`` at ``q``
    and ``-q`` gives ``P1 = (Z(q) + conj Z(-q)) / 2`` and ``P2 = (Z(q) - conj Z(-q)) / 2i``. One
    transform with twice the outputs cost 1.37 of one (ducc0, 28,710 nodes to 55,080 uv nodes,
    2 threads): two blocks for 0.69 each.
    """
    plan = _pair_plan(context, quad)
    half = context.level(quad).size
    out = []
    for k in range(0, len(fluxes), 2):
        z = fluxes[k].astype(complex)
        if k + 1 < len(fluxes):
            z.imag = fluxes[k + 1]
        Z = plan.exec(forward=False, points_in=z)
        plus, minus = Z[:half], np.conj(Z[half:])
        out.append(0.5 * (plus + minus))
        if k + 1 < len(fluxes):
            out.append(-0.5j * (plus - minus))
    return out


def _blocks(context: ScanContext, quad, spectra: list) -> list[_Block]:
    """The building blocks at one radius: as the plain engine computes a template, but on the polar
    path with the transforms two at a time (:func:`pair_transforms`)."""
    ci = context.geometry.cos_inc
    fluxes = [quad.flux(context.profile, sp) for sp in spectra]
    if context.power_path == "direct":
        out = []
        for flux, sp in zip(fluxes, spectra):
            dV = _node_transform(context, flux, quad)
            cross = ci * ((dV.real * context.residual.real + dV.imag * context.residual.imag) @ context.weights)
            power = ci ** 2 * ((dV.real ** 2 + dV.imag ** 2) @ context.weights)
            out.append(_Block(cross, power, dV, ci * quad.error_bound(context.profile, sp)["total"]))
        return out
    level = context.level(quad)
    return [_Block(_cross_all_phi(context, flux, quad), ci ** 2 * power_all_phi(level, p_hat, context.n_phi_p), p_hat,
                   ci * quad.error_bound(context.profile, sp)["total"])
            for flux, sp, p_hat in zip(fluxes, spectra, pair_transforms(context, quad, fluxes))]


def _cross_power(context: ScanContext, quad, a: _Block, b: _Block) -> np.ndarray:
    """``Re sum_k w_k ΔV_a conj(ΔV_b)`` at every planet azimuth."""
    ci2 = context.geometry.cos_inc ** 2
    if context.power_path == "direct":
        x, y = a.transform, b.transform
        return ci2 * ((x.real * y.real + x.imag * y.imag) @ context.weights)
    return ci2 * power_all_phi(context.level(quad), a.transform, context.n_phi_p, other=b.transform)


def pair_terms(context: ScanContext, first, second) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                               np.ndarray]:
    """Scan terms of two templates on one grid and their cross power, at every planet position.

    The weighted inner products of a two-block linear model ``ΔV = a ΔV_1 + b ΔV_2`` over the
    context's ``r_p`` × ``phi_p`` grid, from the blocks' transforms as the variant scan computes
    ``s T + a B``: the best free amplitudes at a position are the 2 × 2 solve of these numbers.

    Parameters
    ----------
    context : ScanContext
    first, second : SpiralTemplate
        Two templates on the same ``(x, phi)`` grid (so that they share the quadrature).

    Returns
    -------
    cross_1, power_1, cross_2, power_2, power_12 : ndarray, shape (n_rp, n_phi_p)
        ``Re Σ w R conj ΔV_i`` (R the residual), ``Σ w |ΔV_i|²`` and ``Re Σ w ΔV_1 conj ΔV_2`` [the
        scan's units: weights × Jy²].
    """
    if _grid_key(first) != _grid_key(second):
        raise InputError(f"pair_terms: {getattr(first, 'name', 'first')!r} and {getattr(second, 'name', 'second')!r} "
                         "are on different (x, phi) grids; build both with the same grid settings")
    shape = (context.r_p.size, context.n_phi_p)
    cross_1, power_1, cross_2, power_2, power_12 = (np.empty(shape) for _ in range(5))
    with blas_threads(1):
        for i, r_p in enumerate(context.r_p):
            quad = context.quadrature(first, r_p)
            a, b = _blocks(context, quad, [TemplateSpectrum(first), TemplateSpectrum(second)])
            cross_1[i], power_1[i], cross_2[i], power_2[i] = a.cross, a.power, b.cross, b.power
            power_12[i] = _cross_power(context, quad, a, b)
    return cross_1, power_1, cross_2, power_2, power_12


def scan_group(context: ScanContext, group) -> dict[int, TemplateTerms]:
    """``cross``, ``power`` and their error estimates of every member of ``group`` (a
    :class:`VariantGroup` or a list of them, whose transforms are then shared) over the context's
    grid, by row of the scan."""
    with blas_threads(1):
        return _scan_groups(context, group if isinstance(group, list) else [group])


def _scan_groups(context: ScanContext, groups: list[VariantGroup]) -> dict[int, TemplateTerms]:
    shape = (context.r_p.size, context.n_phi_p)
    rows = {index: [np.empty(shape), np.empty(shape), np.empty(shape), np.empty(shape)]
            for g in groups for index in g.indices}
    spectra = [([] if g.blob is None else [TemplateSpectrum(g.blob)]) + [TemplateSpectrum(t.template)
                                                                          for t in g.generators] for g in groups]
    pair_error = context.algorithm_error.get("pairs", 0.0) if context.power_path == "polar" else 0.0
    for i, r_p in enumerate(context.r_p):
        quads = [context.quadrature(g.generators[0].template, r_p) for g in groups]
        if not all(isinstance(q, ProductQuadrature) for q in quads):
            raise TypeError("building blocks need the product rule (its error bound)")
        blocks: list = [[None] * len(sp) for sp in spectra]
        for quad in {id(q): q for q in quads}.values():  # groups on one node set share transforms
            # peaks first, so that like is paired with like (a transform's error follows the larger flux)
            slots = sorted(((n, j) for n, q in enumerate(quads) if q is quad for j in range(len(spectra[n]))),
                           key=lambda nj: (nj[1] != 0 or groups[nj[0]].blob is None, nj))
            for (n, j), block in zip(slots, _blocks(context, quad, [spectra[n][j] for n, j in slots])):
                blocks[n][j] = block
        for group, quad, found in zip(groups, quads, blocks):
            b = None if group.blob is None else found[0]
            for gen, t in zip(group.generators, found[1:] if b is not None else found):
                _assemble(context, quad, rows, i, gen, t, b, pair_error)
    return {index: TemplateTerms(*row) for index, row in rows.items()}


def _assemble(context: ScanContext, quad, rows: dict, i: int, gen: Generator,
              t: _Block, b: _Block | None, pair_error: float) -> None:
    """Each variant of ``gen`` at radius ``i`` from its blocks (module docstring)."""
    tb = None if b is None or all(a == 0.0 for _, _, a in gen.members) else _cross_power(context, quad, t, b)
    for index, s, a in gen.members:
        row = rows[index]
        if a == 0.0:
            cross, power, bound = s * t.cross, (s * s) * t.power, abs(s) * t.bound
            scale = (s * s) * np.maximum(t.power, 0.0)
        else:
            if b is None:  # a group whose members have a != 0 always has its blob
                raise RuntimeError(f"scan row {index}: blob amplitude {a} but no blob block for its group")
            cross = s * t.cross + a * b.cross
            power = (s * s) * t.power + (2 * s * a) * tb + (a * a) * b.power
            bound = abs(s) * t.bound + abs(a) * b.bound
            scale = (abs(s) * np.sqrt(np.maximum(t.power, 0.0)) + abs(a) * np.sqrt(np.maximum(b.power, 0.0))) ** 2
        row[0][i], row[1][i] = cross, power
        row[2][i], row[3][i] = _error_estimates(context, bound, power, scale)
        row[3][i] += CHECK_SAFETY * pair_error * scale


# --- units of work for the runners ---------------------------------------------------------------------
def work_units(templates, todo, groups: list[VariantGroup], plain: list[int] | None = None) -> list:
    """What to run for the rows ``todo``: ``(index, template)`` pairs for the rows scanned plainly
    (``plain``; default every row outside ``groups``) and lists of two :class:`VariantGroup` (their
    transforms are shared, :func:`pair_transforms`) holding a row to do (a group runs whole)."""
    todo = set(int(i) for i in todo)
    grouped = {i for g in groups for i in g.indices}
    plain = [i for i in range(len(templates)) if i not in grouped] if plain is None else plain
    wanted = [g for g in groups if todo.intersection(g.indices)]
    return [(i, templates[i]) for i in plain if i in todo] + [wanted[k: k + 2] for k in range(0, len(wanted), 2)]


def unit_rows(unit) -> list[int]:
    """The rows of the scan that a unit of :func:`work_units` computes."""
    return [i for g in unit for i in g.indices] if isinstance(unit, list) else [unit[0]]


def check_pairs(context: ScanContext, group: VariantGroup) -> float:
    """The power's relative change from computing the transforms two at a time
    (:func:`pair_transforms`) instead of one by one, at the radii the power path was checked at
    (:func:`~.accuracy.check_terms`), for the group's first two blocks; stored in
    ``context.algorithm_error["pairs"]`` and added to the error estimates of grouped templates."""
    if context.power_path != "polar":
        return 0.0
    spectra = ([] if group.blob is None else [TemplateSpectrum(group.blob)]) + [
        TemplateSpectrum(g.template) for g in group.generators]
    worst = 0.0
    radii = context.algorithm_error.get("r_p") or [float(context.r_p[-1])]
    with blas_threads(1):
        for r_p in radii:
            quad = context.quadrature(group.generators[0].template, r_p)
            level = context.level(quad)
            fluxes = [quad.flux(context.profile, sp) for sp in spectra[:2]]
            for flux, p_hat in zip(fluxes, pair_transforms(context, quad, fluxes)):
                one = power_all_phi(level, _node_transform(context, flux, quad), context.n_phi_p)
                two = power_all_phi(level, p_hat, context.n_phi_p)
                worst = max(worst, float(np.max(np.abs(two - one) / np.maximum(np.abs(one), 1e-300))))
    context.algorithm_error["pairs"] = worst
    log.info("transforms two at a time change the power by <= %.2g relative", worst)
    return worst


def describe_blocks(groups: list[VariantGroup]) -> dict | None:
    """The resume key's record of the building blocks (None without groups)."""
    if not groups:
        return None
    return {"kind": "variant building blocks (s T + a B)", "version": STRUCTURE_VERSION,
            "rows": sorted(i for g in groups for i in g.indices),
            "blocks": [[g.generators[0].template.name, None if g.blob is None else g.blob.provenance["recovered_from"]]
                       for g in groups]}


