"""Case parameters as dotted paths and as flat names.

A parameter of a case is addressed by its dotted path ``<section>.<field>``
(``ground.young``, ``geometry.gap``). In combined results and tables it appears
under its flat name ``<section>_<field>`` (``ground_young``, ``geometry_gap``),
with one exception that follows the contract's wording (SPEC §3, §4): the lining
thickness lives in ``geometry.thickness`` but is named ``lining_thickness``, and
the dotted path ``lining.thickness`` is accepted as an alias of
``geometry.thickness``.
"""
from __future__ import annotations

import json
import re
from functools import lru_cache
from typing import Any

from pydantic import BaseModel

from solver.spec import ROUND3_DEFAULTS, CaseSpec

from .units import parameter_unit

#: Alternative dotted paths accepted in sweeps -> canonical path in :class:`CaseSpec`.
PATH_ALIASES: dict[str, str] = {"lining.thickness": "geometry.thickness"}
#: Canonical paths whose flat name is not ``<section>_<field>``.
FLAT_NAME_OVERRIDES: dict[str, str] = {"geometry.thickness": "lining_thickness"}


#: CF units (UDUNITS spelling, SI as in SPEC §2) and long name of every case parameter, by
#: canonical path; units None for a choice (a string such as ``interface.model``).
#: Combined results, tables and the command line take parameter units from here alone.
PARAMETER_ATTRS: dict[str, tuple[str | None, str]] = {
    "geometry.inner_radius": ("m", "lining inner radius"),
    "geometry.thickness": ("m", "lining thickness"),
    "geometry.depth": ("m", "depth of the tunnel axis below the surface"),
    "geometry.width": ("m", "ground model width from the symmetry axis"),
    "geometry.height": ("m", "ground model height"),
    "geometry.gap": ("m", "initial radial clearance between lining and ground"),
    "ground.young": ("Pa", "ground Young's modulus"),
    "ground.poisson": ("1", "ground Poisson ratio"),
    "ground.density": ("kg m-3", "ground density"),
    "lining.young": ("Pa", "lining Young's modulus"),
    "lining.poisson": ("1", "lining Poisson ratio"),
    "lining.density": ("kg m-3", "lining density"),
    "loads.surface_load": ("Pa", "uniform surface load"),
    "loads.gravity": ("m s-2", "gravitational acceleration"),
    "loads.lateral_ratio": ("1", "lateral earth pressure ratio K0"),
    "excavation.method": (None, "excavation method"),
    "excavation.deconfinement": ("1", "deconfinement ratio released before lining placement"),
    "excavation.face_distance": ("m", "distance behind the face at which the lining is installed"),
    "excavation.ldp": (None, "longitudinal displacement profile"),
    "geometry.section.shape": (None, "shape of the section's intrados"),
    "geometry.section.arcs": (None, "arcs of a polycentric section, crown to invert (radius, angle)"),
    "geometry.section.width": ("m", "width of the elliptical intrados"),
    "geometry.section.height": ("m", "height of the elliptical intrados"),
    "geometry.section.crown_radius": ("m", "horseshoe crown arc radius"),
    "geometry.section.crown_angle": ("degree", "horseshoe crown arc angle"),
    "geometry.section.side_radius": ("m", "horseshoe side arc radius"),
    "geometry.section.side_angle": ("degree", "horseshoe side arc angle"),
    "interface.model": (None, "interface contact model"),
    "interface.friction": ("1", "interface Coulomb friction coefficient"),
    "boundaries.side": (None, "side boundary condition"),
    "boundaries.bottom": (None, "bottom boundary condition"),
    "mesh.interface_size": ("m", "element size along the interface"),
    "mesh.far_size": ("m", "element size far from the tunnel"),
    "solver.inner": (None, "inner contact solver"),
    "solver.tolerance": ("1", "relative KKT tolerance"),
    "solver.max_iterations": ("1", "inner iteration cap per bolt"),
    "solver.plastic_tolerance": ("1", "yielding ground's out-of-balance force over the increment's load"),
    "solver.bolt": ("degree", "bolt position theta"),
    "design.concrete_strength": ("Pa", "concrete characteristic strength fck"),
    "design.steel_strength": ("Pa", "reinforcement characteristic yield strength fyk"),
    "design.reinforcement_area": ("m2 m-1", "reinforcement area per face per metre of tunnel"),
    "design.axis_distance": ("m", "reinforcement axis distance from each face"),
    "design.load_factor": ("1", "partial factor on actions gamma_F"),
    # third round (SPEC §1.4-§1.6)
    "ground.model": (None, "ground constitutive model"),
    "ground.cohesion": ("Pa", "ground cohesion"),
    "ground.friction_angle": ("degree", "ground friction angle"),
    "ground.dilatancy": ("degree", "ground dilatancy angle"),
    "ground.tensile_strength": ("Pa", "ground tensile strength (tension cut-off)"),
    "ground.ucs": ("Pa", "ground intact rock uniaxial compressive strength (Hoek-Brown sigma_ci)"),
    "ground.gsi": ("1", "ground geological strength index (Hoek-Brown GSI)"),
    "ground.mi": ("1", "ground intact rock constant (Hoek-Brown m_i)"),
    "ground.disturbance": ("1", "ground disturbance factor (Hoek-Brown D)"),
    "ground.young_gradient": ("Pa m-1", "increase of the ground Young's modulus with depth"),
    "ground.permeability": ("m s-1", "ground hydraulic conductivity"),
    "lining.joints.count": ("1", "number of segments in the ring"),
    "lining.joints.offset": ("degree", "angle of the first joint from the crown"),
    "lining.joints.contact_height": ("m", "height of the joints' contact strip"),
    "lining.joints.shear": (None, "tangential law across the joints"),
    "lining.joints.friction": ("1", "joint Coulomb friction coefficient"),
    "solver.load_steps": ("1", "load increments per construction stage"),
    "solver.mesh_check": (None, "also solve on a mesh refined once and report the changes"),
    "water.table": ("m", "depth of the water table below the surface"),
    "water.unit_weight": ("N m-3", "unit weight of water"),
    "water.lining": (None, "water condition of the lining"),
    # fourth round (SPEC §9.3)
    "design.crack_width_limit": ("m", "largest characteristic crack width that passes"),
    "design.bar_diameter": ("m", "bar diameter of each face (crack spacing)"),
    "settlement.volume_loss": ("1", "volume loss of the design trough (null: the case's ground loss)"),
    "settlement.trough_width_factor": ("1", "trough width factor K of the design trough (i = K z0)"),
}

#: Units and long names of a layer's fields (path ``ground.layers.<i>.<field>``).
LAYER_ATTRS: dict[str, tuple[str | None, str]] = {
    "thickness": ("m", "layer thickness"),
    "lateral_ratio": ("1", "layer K0"),
    **{path.split(".", 1)[1]: (units, "layer " + name.removeprefix("ground "))
       for path, (units, name) in PARAMETER_ATTRS.items() if path.startswith("ground.")},
}
_LAYER_PATH = re.compile(r"^ground\.layers\.(\d+)\.(\w+)$")
#: An arc of a polycentric section (SPEC §9.4), ``geometry.section.arcs.<i>.radius|angle``.
_ARC_PATH = re.compile(r"^geometry\.section\.arcs\.(\d+)\.(radius|angle)$")


def canonical_path(path: str) -> str:
    """The :class:`CaseSpec` path ``path`` stands for (resolving aliases)."""
    return PATH_ALIASES.get(path, path)


@lru_cache(maxsize=None)  # called for every parameter of every case combined
def flat_name(path: str) -> str:
    """Flat name of a dotted parameter path: ``ground.young`` -> ``ground_young``."""
    path = canonical_path(path)
    return FLAT_NAME_OVERRIDES.get(path, path.replace(".", "_"))


@lru_cache(maxsize=1)
def _leaf_paths() -> tuple[str, ...]:
    def leaves(model: type[BaseModel], prefix: str):
        for name, info in model.model_fields.items():
            kind = info.annotation
            if isinstance(kind, type) and issubclass(kind, BaseModel):
                yield from leaves(kind, f"{prefix}{name}.")
            elif f"{prefix}{name}" not in ("ground.layers", "name"):  # list items by index; a name is no input
                yield f"{prefix}{name}"
    return tuple(leaves(CaseSpec, ""))


def parameter_paths() -> list[str]:
    """Every leaf path of :class:`CaseSpec` (``<section>.<field>``, ``lining.joints.count``);
    a layer's fields are reached by index, ``ground.layers.<i>.<field>`` (:func:`is_parameter`)."""
    return list(_leaf_paths())


def is_parameter(path: str, base: dict[str, Any] | None = None) -> bool:
    """Whether the canonical ``path`` is a parameter of the case dict ``base`` (a layer's field
    needs the layer in ``base``)."""
    layer = _LAYER_PATH.match(path)
    if layer:
        layers = ((base or {}).get("ground") or {}).get("layers") or []
        return int(layer.group(1)) < len(layers) and layer.group(2) in LAYER_ATTRS
    arc = _ARC_PATH.match(path)
    if arc:
        arcs = (((base or {}).get("geometry") or {}).get("section") or {}).get("arcs") or []
        return int(arc.group(1)) < len(arcs)
    return path in _leaf_paths()


def parameter_attrs(name: str, *, numeric: bool = True) -> dict[str, str]:
    """``units`` and ``long_name`` of a case parameter (:data:`PARAMETER_ATTRS`).

    ``name`` is a flat name (``lining_thickness``) or a dotted path. ``numeric=False``
    (values stored as text, e.g. ``solver.bolt`` mixing ``auto`` and angles) drops the
    units. An unknown name (a parameter of an older case model) gets a generic long name.
    """
    path = _paths_by_flat_name().get(name, canonical_path(name))
    layer = _LAYER_PATH.match(path) or re.match(r"^ground_layers_(\d+)_(\w+)$", name)
    arc = _ARC_PATH.match(path) or re.match(r"^geometry_section_arcs_(\d+)_(radius|angle)$", name)
    if layer and layer.group(2) in LAYER_ATTRS:
        units, long_name = LAYER_ATTRS[layer.group(2)]
        long_name = f"{long_name} (layer {layer.group(1)})"
    elif arc:
        units = "m" if arc.group(2) == "radius" else "degree"
        long_name = f"{arc.group(2)} of arc {arc.group(1)} of the polycentric section"
    else:
        units, long_name = PARAMETER_ATTRS.get(path, (None, f"case parameter {name}"))
    return {"units": units, "long_name": long_name} if numeric and units else {"long_name": long_name}


@lru_cache(maxsize=1)
def _paths_by_flat_name() -> dict[str, str]:
    return {flat_name(p): p for p in parameter_paths()}


def parameter_path(flat: str) -> str:
    """The dotted path of a flat parameter name (the name itself if it is none)."""
    return _paths_by_flat_name().get(flat, flat)


def shown_parameter_unit(name: str) -> tuple[str, float]:
    """``(unit, factor from SI)`` in which tables and figures show parameter ``name`` (flat):
    :func:`workflows.units.parameter_unit` of its path (MPa, kPa, mm, m, %, ...); ``("", 1.0)``
    for a choice or a parameter without units."""
    units = parameter_attrs(name).get("units")
    return parameter_unit(parameter_path(name), units) if units else ("", 1.0)


def with_round3_defaults(data: dict[str, Any]) -> dict[str, Any]:
    """A case dict with the round-3 fields its canonical JSON leaves out at their defaults
    (:data:`solver.spec.ROUND3_DEFAULTS`) put back, so that a monolithic and a segmental case,
    or a dry and a wet one, have the same parameters (``lining_joints_count`` 0 and 6). The
    layers are not: a one-layer ground has none (``ground.layers.<i>`` are parameters of
    layered cases alone)."""
    filled = dict(data)
    for section, fields in ROUND3_DEFAULTS.items():
        missing = {name: default for name, default in fields.items()
                   if name != "layers" and name not in filled.get(section, {})}
        if missing:
            filled[section] = {**filled.get(section, {}), **missing}
    return filled


def flat_parameters(spec: CaseSpec | dict[str, Any] | str) -> dict[str, Any]:
    """All parameters of a case as ``{flat name: value}``.

    ``spec`` may be a :class:`CaseSpec`, its ``model_dump(mode="json")`` or its
    canonical JSON text (the ``case_spec`` attribute of a result), whose round-3 fields at
    their defaults are filled in (:func:`with_round3_defaults`).
    """
    if isinstance(spec, CaseSpec):
        data = spec.model_dump(mode="json")
    else:
        data = with_round3_defaults(json.loads(spec) if isinstance(spec, str) else spec)
    flat: dict[str, Any] = {}

    def walk(value, path):
        if isinstance(value, dict):
            for key, item in value.items():
                walk(item, f"{path}.{key}" if path else key)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for i, item in enumerate(value):
                walk(item, f"{path}.{i}")
        elif "." in path:
            flat[flat_name(path)] = value
    walk(data, "")
    return flat


def set_parameter(data: dict[str, Any], path: str, value: Any) -> None:
    """Set the canonical dotted ``path`` (list items by index) in the case dict ``data``, in place."""
    *parents, last = path.split(".")
    for key in parents:
        data = data[int(key)] if isinstance(data, list) else data.setdefault(key, {})
    data[last] = value


def varying_parameters(cases: list[dict[str, Any]]) -> list[str]:
    """Flat names whose value is not the same in all ``cases`` (flat dicts), in path order."""
    if not cases:
        return []
    names = list(cases[0])
    return [n for n in names if any(c.get(n) != cases[0].get(n) for c in cases[1:])]
