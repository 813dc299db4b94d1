"""Template families: the scanned templates grouped by everything but mass and hand.

A limit on the planet mass needs templates that differ only in mass: the family of a template is
its initial optical depth ``tau0``, cooling time ``beta`` and aspect ratio ``h_p`` (when the
metadata give it; banks without ``h_p`` form families by ``tau0`` and ``beta`` alone), with both
hands. A family's masses are sorted; each hand's templates are listed in that order (missing
ones as None). Templates of a bank with morphology variants (:mod:`spiralbayes.templates.variants`)
carry a ``variant`` name, which is part of the family key (``None`` without one), so each variant is
its own family; :mod:`.robust` combines them. Maps read from simulations (metadata ``kind``
``"simulation"``) never join a generator family: without a ``variant`` of their own they form the
variant ``"simulation"``. One mass and hand of a family is one template; two that would fill the
same place are an error, since either choice would change the limit silently.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...exceptions import InputError
from ...templates.template import SIMULATION, metadata_variant

__all__ = ["Family", "select_family", "template_families"]

FAMILY_KEYS = ("tau0", "beta", "h_p", "variant")
SIMULATION_VARIANT = SIMULATION
"""The variant of simulated maps that carry no variant name of their own."""


def _value(meta: dict, key: str):
    value = meta.get(key)
    if value is None:
        return None
    value = float(value)
    return None if not np.isfinite(value) else value


@dataclass
class Family:
    """Templates that differ only in mass and hand.

    Attributes
    ----------
    key : dict
        ``tau0``, ``beta`` and (when known) ``h_p`` shared by the family.
    masses : list of float
        Planet masses [M_th], increasing.
    members : dict
        ``hand -> [template index or None, one per mass]`` (indices into the scan's arrays).
    """

    key: dict
    masses: list
    members: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        parts = [f"tau0={self.key['tau0']:g}", f"beta={self.key['beta']:g}"]
        if self.key.get("h_p") is not None:
            parts.append(f"h_p={self.key['h_p']:g}")
        if self.key.get("variant") is not None:
            parts.append(f"variant={self.key['variant']}")
        return ", ".join(parts)

    @property
    def hands(self) -> list:
        """Hands present, right-handed first."""
        return sorted(self.members, key=lambda h: ({"R": 0, "L": 1}.get(h, 2), h))

    def index(self, mass: float, hand: str) -> int | None:
        """Template index of ``mass`` [M_th] and ``hand``, or None."""
        k = int(np.argmin(np.abs(np.log(np.asarray(self.masses)) - np.log(mass))))
        if not np.isclose(self.masses[k], mass, rtol=1e-6):
            return None
        return self.members.get(hand, [None] * len(self.masses))[k]

    def to_dict(self) -> dict:
        return {"key": self.key, "masses": self.masses, "members": self.members, "label": self.label}

    @classmethod
    def from_dict(cls, d: dict) -> Family:
        return cls(d["key"], list(d["masses"]), {h: list(v) for h, v in d["members"].items()})


def template_families(templates: list) -> list[Family]:
    """Group template metadata (dicts with mass, tau0, beta, hand, optional h_p) into families.

    Templates without a mass, tau0 or beta (e.g. reference spirals without labels) belong to no
    family and are left out.

    Raises
    ------
    InputError
        Two templates of one family with the same mass and hand (e.g. maps of two simulations that
        differ in a parameter the metadata do not hold, such as the viscosity).
    """
    groups: dict = {}
    for index, meta in enumerate(templates):
        mass, tau0, beta = _value(meta, "mass"), _value(meta, "tau0"), _value(meta, "beta")
        if mass is None or tau0 is None or beta is None or mass <= 0:
            continue
        key = (tau0, beta, _value(meta, "h_p"), metadata_variant(meta))
        groups.setdefault(key, []).append((mass, str(meta.get("hand", "R")), index))
    families = []
    for (tau0, beta, h_p, variant), rows in sorted(groups.items(), key=_sort_key):
        masses = sorted({m for m, _, _ in rows})
        members: dict = {}
        for mass, hand, index in rows:
            slot = members.setdefault(hand, [None] * len(masses))
            k = masses.index(mass)
            if slot[k] is not None:
                raise InputError(_clash_message(templates, slot[k], index, mass, hand))
            slot[k] = index
        family_key = {"tau0": tau0, "beta": beta, "h_p": h_p}
        if variant is not None:
            family_key["variant"] = variant
        families.append(Family(family_key, masses, members))
    return families


def _clash_message(templates: list, first: int, second: int, mass: float, hand: str) -> str:
    names = [str(templates[i].get("name", f"template {i}")) for i in (first, second)]
    fields = {k: templates[first].get(k) for k in ("tau0", "beta", "h_p", "variant", "kind")}
    described = ", ".join(f"{k}={v}" for k, v in fields.items() if v is not None)
    return (f"templates {names[0]!r} and {names[1]!r} are both the {mass:g} M_th, hand {hand} member of one "
            f"mass family ({described}), so a mass limit cannot tell them apart: give each simulation "
            "set its own variant name, e.g. dataclasses.replace(t, provenance={**t.provenance, "
            "'variant': 'nu1e-4'}), or leave beta unknown (NaN) so the maps stay out of the limits")


def _sort_key(item) -> tuple:
    tau0, beta, h_p, variant = item[0]
    return tuple(-1 if v is None else v for v in (tau0, beta, h_p)) + ("" if variant is None else variant,)


def select_family(families: list[Family], family=None) -> Family:
    """The family matching ``family`` (a Family, an index, a label or a dict of key values).

    None picks the only family; several families need a choice.
    """
    if not families:
        raise InputError("no template family: the scanned templates carry no mass/tau0/beta metadata "
                         "(scan templates from a TemplateBank or make_template)")
    if isinstance(family, Family):
        return family
    if family is None:
        if len(families) > 1:
            raise InputError("the scan holds several template families "
                             f"({'; '.join(f.label for f in families)}): choose one with family=")
        return families[0]
    if isinstance(family, (int, np.integer)):
        return families[int(family)]
    if isinstance(family, str):
        for f in families:
            if f.label == family:
                return f
        raise InputError(f"no template family {family!r}; the scan has: {'; '.join(f.label for f in families)}")
    unknown = set(dict(family)) - set(FAMILY_KEYS)
    if unknown:
        raise InputError(f"a family is chosen by {FAMILY_KEYS}, got {sorted(unknown)}")
    wanted = {k: (str(v) if k == "variant" else float(v)) for k, v in dict(family).items() if v is not None}

    def matches(f, k, v):
        if f.key.get(k) is None:
            return False
        return f.key[k] == v if k == "variant" else bool(np.isclose(f.key[k], v, rtol=1e-6))

    chosen = [f for f in families if all(matches(f, k, v) for k, v in wanted.items())]
    if not chosen:
        raise InputError(f"the template family {wanted} is empty: no scanned template matches it; "
                         f"the scan has: {'; '.join(f.label for f in families)}")
    if len(chosen) > 1:
        raise InputError(f"{wanted} matches several families ({'; '.join(f.label for f in chosen)}): "
                         "give tau0, beta, h_p (and variant)")
    return chosen[0]
