"""The labelled case form of the submit page: the fields people set most, in the units they
think in (MPa, kPa, kN/m³, m, mm, °, cm²/m), each with the factor that turns it into the
case JSON's SI value. The browser builds the JSON (``dashboard.js``); the service validates it
as any other case, and a refused field is marked beside its input.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from solver.spec import CaseSpec

#: ``path``: the case JSON field; ``weight``: typed as a unit weight (kN/m³), stored as a density.
_FIELDS: tuple[tuple[str, str, str, str, float], ...] = (
    # (group, path, label, unit, factor: SI value = typed value x factor)
    ("Geometry", "geometry.depth", "depth of the tunnel axis", "m", 1.0),
    ("Geometry", "geometry.inner_radius", "lining inner radius", "m", 1.0),
    ("Geometry", "geometry.thickness", "lining thickness", "m", 1.0),
    ("Geometry", "geometry.gap", "initial clearance lining–ground", "mm", 1e-3),
    ("Ground", "ground.model", "ground model", "", 1.0),
    ("Ground", "ground.young", "Young's modulus E", "MPa", 1e6),
    ("Ground", "ground.poisson", "Poisson's ratio ν", "", 1.0),
    ("Ground", "ground.density", "unit weight γ", "kN/m³", 0.0),
    ("Ground", "loads.lateral_ratio", "lateral earth pressure ratio K0", "", 1.0),
    ("Ground", "ground.cohesion", "cohesion c (Mohr–Coulomb)", "kPa", 1e3),
    ("Ground", "ground.friction_angle", "friction angle φ (Mohr–Coulomb)", "°", 1.0),
    ("Ground", "ground.dilatancy", "dilatancy angle ψ (Mohr–Coulomb)", "°", 1.0),
    ("Ground", "loads.surface_load", "surface load", "kPa", 1e3),
    ("Ground", "water.table", "water table depth (empty: dry)", "m", 1.0),
    ("Lining and interface", "lining.young", "lining Young's modulus", "MPa", 1e6),
    ("Lining and interface", "lining.density", "lining unit weight", "kN/m³", 0.0),
    ("Lining and interface", "interface.model", "interface model", "", 1.0),
    ("Lining and interface", "interface.friction", "interface friction coefficient μ", "", 1.0),
    ("Lining and interface", "excavation.deconfinement", "deconfinement λd before the lining", "", 1.0),
    ("Design (EN 1992)", "design.concrete_strength", "concrete strength fck", "MPa", 1e6),
    ("Design (EN 1992)", "design.reinforcement_area", "reinforcement per face As", "cm²/m", 1e-4),
    ("Design (EN 1992)", "design.load_factor", "load factor γF", "", 1.0),
    ("Mesh", "mesh.interface_size", "element size along the interface", "m", 1.0),
)
_CHOICES = {"ground.model": ("elastic", "mohr-coulomb"), "interface.model": ("frictionless", "coulomb", "bonded")}


@dataclass(frozen=True)
class FormField:
    group: str
    path: str
    label: str
    unit: str
    factor: float  # SI = typed x factor; 0 for a unit weight (density = typed x 1000 / gravity)
    value: Any
    choices: Optional[tuple[str, ...]] = None


def _default(data: dict, path: str) -> Any:
    for part in path.split("."):
        data = data[part]
    return data


def case_form() -> list[tuple[str, list[FormField]]]:
    """The form's fields by group (in the form's order), filled with the default case in the
    shown units."""
    data = CaseSpec().model_dump(mode="json")
    gravity = data["loads"]["gravity"]
    fields = []
    for group, path, label, unit, factor in _FIELDS:
        value = _default(data, path)
        if value is not None and path in _CHOICES:
            shown: Any = value
        elif value is None:
            shown = ""
        elif factor == 0.0:  # a density shown as a unit weight
            shown = f"{value * gravity / 1e3:.6g}"
        else:
            shown = f"{value / factor:.6g}"
        fields.append(FormField(group, path, label, unit, factor, shown, _CHOICES.get(path)))
    groups: dict[str, list[FormField]] = {}
    for f in fields:
        groups.setdefault(f.group, []).append(f)
    return list(groups.items())
