"""The case: every input of one tunnel-contact computation (SPEC §2), and its id."""
from __future__ import annotations

import json
from typing import Optional

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..geometry.sizing import MAX_ELEMENTS, estimated_elements
from ..ground.strata import geostatic_errors, strata
from ..lining.design import section_errors
from .canonical import MAX_STIFFNESS_RATIO, _Frozen, content_id
from .ground import HOEK_BROWN_DEFAULTS, LAYER_FIELDS, Ground, Strength
from .section import Section
from .parts import (Boundaries, Design, Excavation, Geometry, Interface, Joints, Lining, Loads, MeshSettings,
                    Settlement, SolverSettings, Water)


#: The solver's fields only a case whose ground yields uses (an elastic case has them at their defaults).
PLASTIC_SOLVER_FIELDS = ("load_steps", "plastic_tolerance")


def _round3_defaults() -> dict[str, dict]:
    defaults = {
        "ground": {k: Strength.model_fields[k].default for k in Strength.model_fields} | {"layers": []},
        "lining": {"joints": Joints().model_dump(mode="json")},
        "solver": {k: SolverSettings.model_fields[k].default for k in PLASTIC_SOLVER_FIELDS} | {"mesh_check": False},
        "water": Water().model_dump(mode="json"),
        # fourth round (SPEC §9.4, §9.5): the section's shape, the face distance and its profile
        "geometry": {"section": Section().model_dump(mode="json")},
        "excavation": {"face_distance": None, "ldp": Excavation.model_fields["ldp"].default},
    }
    return defaults


def _round4_defaults() -> dict[str, dict]:
    design = Design.model_fields
    return {
        "design": {k: design[k].default for k in ("crack_width_limit", "bar_diameter")},
        "settlement": Settlement().model_dump(mode="json"),
    }


#: Longest case name (characters).
MAX_NAME = 120


class CaseSpec(_Frozen):
    """One tunnel-contact case (SPEC §2). ``CaseSpec()`` is the default case."""

    geometry: Geometry = Geometry()
    ground: Ground = Ground()
    lining: Lining = Lining()
    loads: Loads = Loads()
    excavation: Excavation = Excavation()
    interface: Interface = Interface()
    boundaries: Boundaries = Boundaries()
    mesh: MeshSettings = MeshSettings()
    solver: SolverSettings = SolverSettings()
    design: Design = Design()
    water: Water = Water()
    settlement: Settlement = Settlement()
    name: Optional[str] = Field(None, max_length=MAX_NAME, description="what people call the case: stored "
                                "with it, shown in every list and report, outside its id")

    @field_validator("name")
    @classmethod
    def _printable(cls, value):
        if value is not None and not value.isprintable():
            raise ValueError("name: a control character (line break, tab, ...) cannot be shown in a list; "
                             "give one line of text")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> "CaseSpec":
        self._ground_fits()
        self._canonical_round3()
        if self.interface.model == "bonded" and self.geometry.gap > 0:
            # [u]ν = 0 with a clearance would glue the lining to ground it never reaches
            raise ValueError(
                f"geometry.gap: {self.geometry.gap} m of clearance cannot be bonded (a bonded "
                "interface ties lining and ground where they stand, so gap must be 0); use "
                "'frictionless' or 'coulomb', whose contact closes the gap first")
        ratio = self.lining.young / min([self.ground.young, *(layer.young for layer in self.ground.layers)])
        if not 1.0 / MAX_STIFFNESS_RATIO <= ratio <= MAX_STIFFNESS_RATIO:
            raise ValueError(
                f"lining.young: lining / ground stiffness ratio {ratio:.3g} is outside "
                f"[{1 / MAX_STIFFNESS_RATIO:g}, {MAX_STIFFNESS_RATIO:g}]")
        d = self.design  # the section's own rules live with the design check
        errors = section_errors(self.geometry.thickness, d.reinforcement_area, d.axis_distance)
        if errors:
            field, reason = errors[0]
            raise ValueError(f"{field}: {reason}")
        return self._mesh_fits()

    def _ground_fits(self) -> None:
        """Strata inside the model, the table above its bottom, the joints' strip inside the lining,
        and the in-situ state of every yielding layer inside its yield surface (SPEC §1.4-§1.6)."""
        height, layers = self.geometry.height, self.ground.layers
        reach = 0.0
        for i, layer in enumerate(layers[:-1]):
            reach += layer.thickness
            if reach >= height:
                raise ValueError(
                    f"ground.layers.{i}.thickness: the layers down to this one reach {reach:.6g} m, at or "
                    f"below the model's bottom ({height:.6g} m below the surface); the last layer must "
                    "reach the bottom")
        if self.water.table is not None and self.excavation.method == "wished-in-place":
            raise ValueError("water.table: groundwater needs excavation.method = 'deconfinement' (the "
                             "'wished-in-place' method starts from a stress-free ground, which has no "
                             "hydrostatic pore pressure to start from)")
        if self.water.table is not None and self.water.table >= height:
            raise ValueError(f"water.table: {self.water.table:.6g} m is at or below the model's bottom "
                             f"({height:.6g} m)")
        a = self.lining.joints.contact_height
        if a is not None and a > self.geometry.thickness * (1 + 1e-12):
            raise ValueError(f"lining.joints.contact_height: {a:.6g} m exceeds the lining thickness "
                             f"({self.geometry.thickness:.6g} m)")
        if self.lining.joints.count and self.solver.bolt != "auto":
            raise ValueError("solver.bolt: a fixed bolt is the monolithic lining's; a segmental lining's segments are "
                             "held by bolt sets the solver searches (leave solver.bolt 'auto')")
        errors = geostatic_errors(self, strata(self))
        if errors:
            field, reason = errors[0]
            raise ValueError(f"{field}: {reason}")

    @property
    def plastic(self) -> bool:
        """Whether any layer of the ground can yield (the staged plastic solve is needed)."""
        return any(layer.model != "elastic" for layer in (self.ground, *self.ground.layers))

    @property
    def drained(self) -> bool:
        """Whether water seeps into a drained lining (the seepage solve is needed)."""
        return self.water.table is not None and self.water.lining == "drained"

    def _canonical_round3(self) -> None:
        """Values the case ignores take their defaults, so one physical case has one id:
        permeabilities unless the lining drains, load steps unless the ground yields, a joint
        strip as high as the lining (the default)."""
        ground, solver, lining, loads = self.ground, self.solver, self.lining, self.loads
        if len(ground.layers) == 1:  # one layer is the ground itself
            (only,) = ground.layers
            ground = ground.model_copy(update={**{f: getattr(only, f) for f in LAYER_FIELDS}, "layers": ()})
            if only.lateral_ratio is not None:
                loads = loads.model_copy(update={"lateral_ratio": only.lateral_ratio})
        k0 = loads.lateral_ratio  # a layer's K0 equal to the case's is the inherited one
        ground = ground.model_copy(update={"layers": tuple(
            layer.model_copy(update={"lateral_ratio": None}) if layer.lateral_ratio == k0 else layer
            for layer in ground.layers)})
        if not self.drained:
            k = Strength.model_fields["permeability"].default
            ground = ground.model_copy(update={"permeability": k, "layers": tuple(
                layer.model_copy(update={"permeability": k}) for layer in ground.layers)})
        if not self.plastic:
            defaults = {k: SolverSettings.model_fields[k].default for k in PLASTIC_SOLVER_FIELDS}
            solver = solver.model_copy(update=defaults)
        a = lining.joints.contact_height
        if a is not None and abs(a - self.geometry.thickness) <= 1e-12 * self.geometry.thickness:
            lining = lining.model_copy(update={"joints": lining.joints.model_copy(update={"contact_height": None})})
        for name, value in (("ground", ground), ("solver", solver), ("lining", lining), ("loads", loads)):
            object.__setattr__(self, name, value)

    def _mesh_fits(self) -> "CaseSpec":
        g, m = self.geometry, self.mesh
        if m.far_size < m.interface_size:
            raise ValueError(
                f"mesh.far_size: {m.far_size} m is smaller than mesh.interface_size ({m.interface_size} m)")
        if m.interface_size > g.outer_radius / 4:
            raise ValueError(
                f"mesh.interface_size: {m.interface_size} m is too coarse for the lining "
                f"(at most outer radius / 4 = {g.outer_radius / 4:.4g} m)")
        if not g.circle:  # the curves' sharpest bend must span a few interface elements
            hole = g.profile(g.thickness + g.gap)
            sharpest = float(1.0 / np.max(hole.curvature(np.linspace(0.0, np.pi, 721))))
            if m.interface_size > 0.5 * sharpest:
                raise ValueError(
                    f"mesh.interface_size: {m.interface_size} m is too coarse for the section's sharpest bend "
                    f"(radius {sharpest:.4g} m on the excavation; at most half of it)")
        n = estimated_elements(self)
        if n > MAX_ELEMENTS:
            raise ValueError(
                f"mesh.interface_size: this mesh would have about {n:,} elements, over the cap "
                f"of {MAX_ELEMENTS:,}; use a larger mesh.interface_size or mesh.far_size")
        return self

    def canonical_json(self) -> str:
        """Defaults filled, keys sorted, no whitespace: the text the case id hashes.

        Round-3 fields (SPEC §2: strata, water, plasticity, joints, load steps) and round-4 ones
        (SPEC §9.3: crack width limit, bar diameter, design trough; §9.4-9.5: the section, the face
        distance) are left out while they hold their defaults, so every case that gives none of them
        keeps its id; ``name`` is never in it. A face-distance case carries no deconfinement: it is found.
        """
        data = self.model_dump(mode="json", exclude={"name"})
        for section, fields in (*ROUND3_DEFAULTS.items(), *ROUND4_DEFAULTS.items()):
            for name, default in fields.items():
                if data[section].get(name, default) == default:
                    data[section].pop(name, None)
        for layer in data["ground"].get("layers", []):  # SPEC §9.1's fields, absent while at their defaults
            for name, default in HOEK_BROWN_DEFAULTS.items():
                if layer.get(name, default) == default:
                    layer.pop(name, None)
        for section in ("water", "settlement"):
            if data[section] == {}:
                del data[section]
        if self.excavation.face_distance is not None:  # found, not given (SPEC §9.5)
            data["excavation"].pop("deconfinement", None)
        return json.dumps(data, sort_keys=True, separators=(",", ":"))

    def named_json(self) -> str:
        """The canonical JSON with the case's ``name`` (if any): what is handed on and recorded, so the
        name travels with the case while its id stays the hash of :meth:`canonical_json`."""
        text = self.canonical_json()
        return text if self.name is None else text[:-1] + "," + json.dumps({"name": self.name}, separators=(",", ":"))[1:]

    @property
    def case_id(self) -> str:
        """Stable 16-hex-digit id of the physical case (sha256 of the canonical JSON)."""
        return content_id(self.canonical_json())


#: Round-3 and round-4 fields and their defaults: left out of the canonical JSON while at them.
ROUND3_DEFAULTS = _round3_defaults()
ROUND4_DEFAULTS = _round4_defaults()
