"""The labelled case form of the submit page: the fields people set most, in the units they
think in (MPa, kPa, kN/m³, m, mm, °, cm²/m), each with the factor that turns it into the
case JSON's SI value. The browser builds the JSON (``dashboard.js``); the service validates it
as any other case, and a refused field is marked beside its input.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from solver.ground.ldp import PROFILES
from solver.spec import CaseSpec
from workflows.parameters import flat_name, flat_parameters, parameter_attrs
from workflows.units import input_unit

#: (group, case JSON path, label) in the form's order; units from the parameter table
#: (:func:`workflows.units.input_unit`) unless :data:`_TYPED_AS` says otherwise.
_FIELDS: tuple[tuple[str, str, str], ...] = (
    ("Geometry", "geometry.depth", "depth of the tunnel axis"),
    ("Geometry", "geometry.inner_radius", "lining inner radius"),
    ("Geometry", "geometry.thickness", "lining thickness"),
    ("Geometry", "geometry.gap", "initial clearance lining–ground"),
    ("Ground", "ground.model", "ground model"),
    ("Ground", "ground.young", "Young's modulus E"),
    ("Ground", "ground.poisson", "Poisson's ratio ν"),
    ("Ground", "ground.density", "unit weight γ"),
    ("Ground", "loads.lateral_ratio", "lateral earth pressure ratio K0"),
    ("Ground", "ground.cohesion", "cohesion c (Mohr–Coulomb)"),
    ("Ground", "ground.friction_angle", "friction angle φ (Mohr–Coulomb)"),
    ("Ground", "ground.dilatancy", "dilatancy angle ψ (Mohr–Coulomb, Hoek–Brown)"),
    ("Ground", "ground.ucs", "intact rock strength σci (Hoek–Brown)"),
    ("Ground", "ground.gsi", "geological strength index GSI (Hoek–Brown)"),
    ("Ground", "ground.mi", "intact rock constant mi (Hoek–Brown)"),
    ("Ground", "ground.disturbance", "disturbance factor D (Hoek–Brown)"),
    ("Ground", "loads.surface_load", "surface load"),
    ("Ground", "water.table", "water table depth (empty: dry)"),
    ("Lining and interface", "lining.young", "lining Young's modulus"),
    ("Lining and interface", "lining.density", "lining unit weight"),
    ("Lining and interface", "interface.model", "interface model"),
    ("Lining and interface", "interface.friction", "interface friction coefficient μ"),
    ("Lining and interface", "excavation.deconfinement", "deconfinement λd before the lining (empty with a face "
                                                         "distance)"),
    ("Section and face", "geometry.section.shape", "shape of the intrados"),
    ("Section and face", "geometry.section.width", "ellipse: intrados width"),
    ("Section and face", "geometry.section.height", "ellipse: intrados height"),
    ("Section and face", "geometry.section.crown_radius", "horseshoe: crown arc radius"),
    ("Section and face", "geometry.section.crown_angle", "horseshoe: crown arc angle"),
    ("Section and face", "geometry.section.side_radius", "horseshoe: side arc radius"),
    ("Section and face", "geometry.section.side_angle", "horseshoe: side arc angle"),
    ("Section and face", "excavation.face_distance", "lining installed this far behind the face (empty: λd given)"),
    ("Section and face", "excavation.ldp", "longitudinal displacement profile"),
    ("Design (EN 1992)", "design.concrete_strength", "concrete strength fck"),
    ("Design (EN 1992)", "design.reinforcement_area", "reinforcement per face As"),
    ("Design (EN 1992)", "design.load_factor", "load factor γF"),
    ("Mesh", "mesh.interface_size", "element size along the interface"),
)
#: Fields typed in a unit of their own: (unit, factor); factor 0 marks a density typed as a
#: unit weight in kN/m³ (density = typed x 1000 / gravity).
_TYPED_AS = {"geometry.gap": ("mm", 1e-3), "ground.density": ("kN/m³", 0.0), "lining.density": ("kN/m³", 0.0)}
_CHOICES = {"ground.model": ("elastic", "mohr-coulomb", "hoek-brown"),
            "geometry.section.shape": ("circle", "ellipse", "horseshoe"), "excavation.ldp": PROFILES,
            "interface.model": ("frictionless", "coulomb", "bonded")}


@dataclass(frozen=True)
class FormField:
    group: str
    path: str
    label: str
    unit: str
    factor: float  # SI = typed x factor; 0 for a unit weight (density = typed x 1000 / gravity)
    value: Any
    choices: Optional[tuple[str, ...]] = None


def typed_unit(path: str) -> tuple[str, float]:
    """``(unit, factor)`` in which the form's field ``path`` is typed: SI = typed x factor."""
    if path in _TYPED_AS:
        return _TYPED_AS[path]
    unit, from_si = input_unit(flat_name(path), parameter_attrs(path).get("units"))
    return unit, 1.0 / from_si


def case_form() -> list[tuple[str, list[FormField]]]:
    """The form's fields by group (in the form's order), filled with the default case in the
    shown units."""
    defaults = flat_parameters(CaseSpec())
    gravity = CaseSpec().loads.gravity
    groups: dict[str, list[FormField]] = {}
    for group, path, label in _FIELDS:
        unit, factor = typed_unit(path)
        value = defaults[flat_name(path)]
        if value is None:
            shown: Any = ""
        elif path in _CHOICES:
            shown = value
        elif factor == 0.0:  # a density shown as a unit weight
            shown = f"{value * gravity / 1e3:.6g}"
        else:
            shown = f"{value / factor:.6g}"
        groups.setdefault(group, []).append(FormField(group, path, label, unit, factor, shown, _CHOICES.get(path)))
    return list(groups.items())
