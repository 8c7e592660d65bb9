"""The case model: every input of one tunnel-contact computation (SPEC §2).

A :class:`CaseSpec` is immutable, rejects unknown fields, has a default for every
value (``CaseSpec()`` is the default case) and checks physical sense with
messages that start with the dotted path of the offending field, e.g.
``geometry.depth: cover above the tunnel is -0.2 m; ...``.
"""
from __future__ import annotations

import hashlib
import json
import math
import sys
from typing import Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .design import section_errors
from .sizing import MAX_ELEMENTS, estimated_elements

__all__ = ["CaseSpec", "MAX_ELEMENTS", "canonical_json", "content_id"]

#: Physical bounds, wide but real: soft soil to steel, and a Poisson ratio far enough
#: below 1/2 that plane-strain elasticity stays well conditioned (volumetric locking).
MIN_YOUNG, MAX_YOUNG = 1.0e5, 1.0e12
MAX_POISSON = 0.49
MAX_DENSITY = 2.0e4
#: Friction and dilatancy angles (deg), permeability (m/s) and number of strata accepted.
MAX_FRICTION_ANGLE = 70.0
MIN_PERMEABILITY, MAX_PERMEABILITY = 1.0e-13, 1.0e-1
MAX_LAYERS = 20
MAX_SEGMENTS = 24
#: Largest lining / ground stiffness ratio the factorization and contact solve handle.
MAX_STIFFNESS_RATIO = 1.0e6


def canonical_json(model: BaseModel) -> str:
    """Defaults filled, keys sorted, no whitespace: the text a model's id hashes."""
    return json.dumps(model.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))


def content_id(text: str) -> str:
    """Stable 16-hex-digit id of a canonical text (first digits of its sha256)."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def is_number(value) -> bool:
    """Whether ``value`` is a number as JSON has them (a bool is not one)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _first_message(exc: Exception) -> str:
    """``field: reason`` of the first error of a validation error (named as :mod:`solver.errors` names it)."""
    from .errors import field_errors

    errors = field_errors(exc) if hasattr(exc, "errors") else [("", str(exc))]
    field, reason = errors[0]
    return f"{field}: {reason}" if field else reason


def _ignorable(value) -> bool:
    """Whether ``value`` of a field its model ignores may be replaced by the canonical one: a
    finite number (anything else is left for validation to refuse)."""
    return is_number(value) and math.isfinite(value)


def canonical_number(value):
    """``value`` with one form per number: ``-0.0`` is ``0.0`` (one case, one id); a subnormal
    float (below 2.2e-308 in magnitude, e.g. 5e-324) is refused: no physical input is that
    small, and dividing by one overflows. Anything else is returned unchanged."""
    if isinstance(value, float):
        if value == 0.0:
            return 0.0
        if math.isfinite(value) and abs(value) < sys.float_info.min:
            raise ValueError(f"{value!r} is a subnormal number (below {sys.float_info.min:.3g} in magnitude); "
                             "give 0 or a physical value")
    return value


class _Frozen(BaseModel):
    # allow_inf_nan=False: NaN, Infinity and overflowing literals such as 1e400 are
    # refused with the field's name instead of failing later in the solver.
    # strict: a number is a number. Lax validation took JSON ``true`` as 1.0 (a 1 m
    # lining) and the string "0.5" as 0.5; an integer field takes integers only.
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False, strict=True)

    @field_validator("*", mode="before")
    @classmethod
    def _one_form_per_number(cls, value):
        return canonical_number(value)


class Geometry(_Frozen):
    """Tunnel geometry in metres (half model, axis at ``(0, -depth)``)."""

    inner_radius: float = Field(2.5, ge=0.1, le=50.0, description="lining inner radius a (m)")
    thickness: float = Field(0.3, gt=0, description="lining thickness t (m)")
    depth: float = Field(15.0, gt=0, le=5000.0, description="depth of the tunnel axis below the surface (m)")
    width: float = Field(40.0, gt=0, le=10000.0, description="ground model width from the symmetry axis (m)")
    height: float = Field(50.0, gt=0, le=10000.0, description="ground model height (m)")
    gap: float = Field(0.0, ge=0, description="initial radial clearance g0 between lining and ground (m)")

    @property
    def outer_radius(self) -> float:
        """Lining outer radius b = a + t (m)."""
        return self.inner_radius + self.thickness

    @property
    def hole_radius(self) -> float:
        """Radius of the excavation in the ground, b + g0 (m)."""
        return self.outer_radius + self.gap

    @model_validator(mode="after")
    def _fits(self) -> "Geometry":
        r = self.hole_radius
        if self.thickness > 0.5 * self.inner_radius:
            raise ValueError(
                f"thickness: {self.thickness} m exceeds half the inner radius ({0.5 * self.inner_radius:.4g} m); "
                "the lining forces assume a ring, not a thick cylinder")
        if self.thickness < 0.005 * self.inner_radius:
            raise ValueError(
                f"thickness: {self.thickness} m is under 0.5 % of the inner radius; such a membrane "
                "is outside the plane-strain ring model")
        if self.gap > 0.1 * self.inner_radius:
            raise ValueError(
                f"gap: {self.gap} m exceeds 10 % of inner_radius; the small-displacement "
                "contact model does not hold for such clearances")
        cover = self.depth - r
        if cover <= 0.25 * r:
            raise ValueError(
                f"depth: cover above the tunnel is {cover:.4g} m; it must exceed a quarter "
                f"of the excavation radius ({0.25 * r:.4g} m)")
        below = self.height - self.depth - r
        if below <= 0.25 * r:
            raise ValueError(
                f"height: room below the tunnel is {below:.4g} m; it must exceed a quarter "
                f"of the excavation radius ({0.25 * r:.4g} m)")
        beside = self.width - r
        if beside <= 0.25 * r:
            raise ValueError(
                f"width: room beside the tunnel is {beside:.4g} m; it must exceed a quarter "
                f"of the excavation radius ({0.25 * r:.4g} m)")
        return self


class Material(_Frozen):
    """Isotropic linear elastic material (plane strain)."""

    young: float = Field(ge=MIN_YOUNG, le=MAX_YOUNG, description="Young's modulus E (Pa)")
    poisson: float = Field(ge=0, le=MAX_POISSON, description="Poisson ratio")
    density: float = Field(ge=0, le=MAX_DENSITY, description="mass density (kg/m^3)")


class Strength(_Frozen):
    """Mohr–Coulomb strength and flow (SPEC §1.5) and the stiffness gradient and permeability of
    §1.4: the round-3 fields shared by the ground and each of its layers."""

    model: Literal["elastic", "mohr-coulomb"] = Field(
        "elastic", description="'elastic' or 'mohr-coulomb' (elastic-perfectly plastic)")
    cohesion: float = Field(0.0, ge=0, le=1.0e9, description="Mohr-Coulomb cohesion c (Pa)")
    friction_angle: float = Field(30.0, ge=0, le=MAX_FRICTION_ANGLE, description="friction angle phi (deg)")
    dilatancy: float = Field(0.0, ge=0, le=MAX_FRICTION_ANGLE, description="dilatancy angle psi (deg), 0 <= psi <= phi")
    tensile_strength: float = Field(0.0, ge=0, le=1.0e9, description="tension cut-off (Pa), at most c cot(phi)")
    young_gradient: float = Field(
        0.0, ge=0, le=1.0e10, description="increase of E with depth below the layer's top (Pa/m)")
    permeability: float = Field(
        1.0e-6, ge=MIN_PERMEABILITY, le=MAX_PERMEABILITY, description="hydraulic conductivity k (m/s)")

    @model_validator(mode="before")
    @classmethod
    def _strength_only_when_plastic(cls, data):
        # an elastic ground ignores its strength: one physical case, one id
        if isinstance(data, dict) and data.get("model", "elastic") == "elastic":
            data = {**data, **{k: v for k, v in STRENGTH_DEFAULTS.items()
                               if k not in data or _ignorable(data[k])}}
        return data

    @model_validator(mode="after")
    def _strength(self):
        if self.model != "mohr-coulomb":
            return self
        if self.dilatancy > self.friction_angle:
            raise ValueError(f"dilatancy: {self.dilatancy} deg exceeds the friction angle "
                             f"({self.friction_angle} deg); 0 <= psi <= phi")
        if self.cohesion <= 0 and self.friction_angle <= 0:
            raise ValueError("cohesion: a Mohr-Coulomb ground needs cohesion > 0 or friction_angle > 0")
        if self.friction_angle > 0:
            apex = self.cohesion / math.tan(math.radians(self.friction_angle))
            if self.tensile_strength > apex * (1 + 1e-12):
                raise ValueError(f"tensile_strength: {self.tensile_strength:.6g} Pa exceeds c cot(phi) = "
                                 f"{apex:.6g} Pa, the apex of the Mohr-Coulomb cone")
        return self


#: Round-3 strength fields at their defaults (what an elastic ground records).
STRENGTH_DEFAULTS = {"cohesion": 0.0, "friction_angle": 30.0, "dilatancy": 0.0, "tensile_strength": 0.0}


class Layer(_Frozen):
    """One horizontal stratum (SPEC §1.4): a field it omits takes the ``ground`` value (filled
    by :class:`Ground`, so the canonical JSON states every layer in full)."""

    thickness: float = Field(0.0, ge=0, le=10000.0, description="layer thickness (m); the last layer's is ignored")
    young: Optional[float] = Field(None, ge=MIN_YOUNG, le=MAX_YOUNG, description="Young's modulus at the layer's top (Pa)")
    poisson: Optional[float] = Field(None, ge=0, le=MAX_POISSON, description="Poisson ratio")
    density: Optional[float] = Field(None, ge=0, le=MAX_DENSITY, description="bulk density (kg/m^3; saturated below the table)")
    lateral_ratio: Optional[float] = Field(None, ge=0, le=10.0, description="K0 of the layer (default loads.lateral_ratio)")
    young_gradient: Optional[float] = Field(None, ge=0, le=1.0e10, description="increase of E with depth (Pa/m)")
    permeability: Optional[float] = Field(None, ge=MIN_PERMEABILITY, le=MAX_PERMEABILITY, description="k (m/s)")
    model: Optional[Literal["elastic", "mohr-coulomb"]] = None
    cohesion: Optional[float] = Field(None, ge=0, le=1.0e9, description="cohesion c (Pa)")
    friction_angle: Optional[float] = Field(None, ge=0, le=MAX_FRICTION_ANGLE, description="friction angle (deg)")
    dilatancy: Optional[float] = Field(None, ge=0, le=MAX_FRICTION_ANGLE, description="dilatancy angle (deg)")
    tensile_strength: Optional[float] = Field(None, ge=0, le=1.0e9, description="tension cut-off (Pa)")


#: The fields a layer inherits from ``ground`` (``lateral_ratio`` from ``loads``).
LAYER_FIELDS = ("young", "poisson", "density", "young_gradient", "permeability", "model", "cohesion",
                "friction_angle", "dilatancy", "tensile_strength")


class Ground(Material, Strength):
    young: float = Field(5.0e7, ge=MIN_YOUNG, le=MAX_YOUNG, description="ground Young's modulus (Pa)")
    poisson: float = Field(0.3, ge=0, le=MAX_POISSON, description="ground Poisson ratio")
    density: float = Field(2000.0, ge=0, le=MAX_DENSITY, description="ground density (kg/m^3)")
    layers: tuple[Layer, ...] = Field(
        (), max_length=MAX_LAYERS, description="horizontal strata from the surface down (empty: one layer of ground)")

    @field_validator("layers", mode="before")
    @classmethod
    def _layers_list(cls, v):
        return tuple(v) if isinstance(v, list) else v  # a JSON list (strict mode takes tuples only)

    @model_validator(mode="after")
    def _fill_layers(self) -> "Ground":
        # every layer states every field, so one physical case has one canonical JSON
        filled = []
        for i, layer in enumerate(self.layers):
            given = {k: v for k, v in layer.model_dump().items() if v is not None}
            values = {k: getattr(self, k) for k in LAYER_FIELDS} | given
            try:
                Strength.model_validate({k: values[k] for k in Strength.model_fields})
            except ValueError as exc:  # the layer's own strength checks, named by its index
                raise ValueError(f"layers.{i}.{_first_message(exc)}") from None
            if values["model"] == "elastic":
                values |= STRENGTH_DEFAULTS
            filled.append(Layer.model_validate(values | {"thickness": layer.thickness,
                                                         "lateral_ratio": given.get("lateral_ratio")}))
        for i, layer in enumerate(filled[:-1]):
            if layer.thickness <= 0:
                raise ValueError(f"layers.{i}.thickness: must be > 0 (only the last layer, which reaches "
                                 "the model's bottom, may give none)")
        if filled:  # the last layer's thickness is ignored: recorded as 0
            filled[-1] = filled[-1].model_copy(update={"thickness": 0.0})
        object.__setattr__(self, "layers", tuple(filled))
        return self


class Joints(_Frozen):
    """Longitudinal joints of a segmental lining (SPEC §1.6); ``count = 0`` is a monolithic ring."""

    count: int = Field(0, ge=0, le=MAX_SEGMENTS, description="segments in the full ring (0: monolithic)")
    offset: float = Field(0.0, ge=0, lt=360.0, description="angle of the first joint from the crown (deg)")
    contact_height: Optional[float] = Field(
        None, gt=0, description="height a of the contact strip centred on the mid-surface (m; default: the thickness)")
    shear: Literal["bonded", "coulomb"] = Field("bonded", description="tangential law across the strip")
    friction: float = Field(0.0, ge=0, le=10.0, description="Coulomb coefficient across a joint ('coulomb')")

    @model_validator(mode="before")
    @classmethod
    def _ignored_when_monolithic(cls, data):
        # a monolithic ring ignores the joints' other fields; bonded joints ignore friction
        if isinstance(data, dict):
            if data.get("count", 0) == 0:
                data = {k: v for k, v in data.items() if k == "count" or not _ignorable(v)} | \
                    ({"shear": "bonded"} if data.get("shear") in ("bonded", "coulomb") else {})
            if data.get("shear", "bonded") == "bonded" and _ignorable(data.get("friction")):
                data = {**data, "friction": 0.0}
        return data

    @model_validator(mode="after")
    def _pattern(self) -> "Joints":
        n = self.count
        if n == 0:
            return self
        if n < 3:
            raise ValueError(f"count: {n} segments cannot form a ring that holds; at least 3")
        if not any(abs(self.offset - o) <= 1e-9 for o in (0.0, 180.0 / n)):
            raise ValueError(f"offset: {self.offset} deg makes the pattern of {n} segments unsymmetric about "
                             f"the vertical axis; use 0 or {180.0 / n:.6g}")
        if self.shear == "coulomb" and self.friction <= 0:
            raise ValueError("friction: joints.shear 'coulomb' needs joints.friction > 0")
        return self


class Lining(Material):
    young: float = Field(3.0e10, ge=MIN_YOUNG, le=MAX_YOUNG, description="lining Young's modulus (Pa)")
    poisson: float = Field(0.2, ge=0, le=MAX_POISSON, description="lining Poisson ratio")
    density: float = Field(
        2500.0, gt=0, le=MAX_DENSITY,
        description="lining density (kg/m^3); must be > 0: the floating lining needs weight")
    joints: Joints = Joints()


class Water(_Frozen):
    """Groundwater (SPEC §1.4): a hydrostatic table and how the lining treats it."""

    table: Optional[float] = Field(None, ge=0, description="depth of the water table below the surface (m); null: dry")
    unit_weight: float = Field(9810.0, ge=5000.0, le=20000.0, description="unit weight of water gamma_w (N/m^3)")
    lining: Literal["watertight", "drained"] = Field(
        "watertight", description="'watertight': water pressure on the lining; 'drained': seepage into the tunnel")

    @model_validator(mode="before")
    @classmethod
    def _ignored_when_dry(cls, data):
        if isinstance(data, dict) and data.get("table") is None:
            data = {k: v for k, v in data.items() if k == "table" or not _ignorable(v)}
            if data.get("lining") in ("watertight", "drained"):
                data = {**data, "lining": "watertight"}
        return data


class Loads(_Frozen):
    surface_load: float = Field(1.0e5, ge=0, le=1.0e9, description="uniform downward pressure on y = 0 (Pa)")
    gravity: float = Field(
        9.81, ge=1.0, le=100.0,
        description="gravitational acceleration, downward (m/s^2), 1 to 100 (the Moon's 1.6 to a centrifuge's)")
    lateral_ratio: float = Field(
        0.5, ge=0, le=10.0,
        description="K0: horizontal / vertical geostatic stress (the in-situ state, and a 'pressure' side)")


class Excavation(_Frozen):
    """How the tunnel is built (SPEC §1.1)."""

    method: Literal["deconfinement", "wished-in-place"] = Field(
        "deconfinement",
        description="'deconfinement': in-situ stress, excavation, lining placed after a release "
                    "of lambda_d; 'wished-in-place': the paper's model, both bodies stress-free")
    deconfinement: float = Field(
        0.3, ge=0, le=1,
        description="lambda_d: fraction of the excavation load released before the lining is placed "
                    "(no meaning for 'wished-in-place', where it is recorded as 0)")

    @model_validator(mode="before")
    @classmethod
    def _deconfinement_only_when_staged(cls, data):
        # as interface.friction: a value the model ignores must not split one physical case
        # into several ids (nor be kept in the record as if it had acted)
        if isinstance(data, dict) and data.get("method") == "wished-in-place" \
                and ("deconfinement" not in data or _ignorable(data["deconfinement"])):
            data = {**data, "deconfinement": 0.0}
        return data


class Interface(_Frozen):
    """Contact model on the ground-lining interface (SPEC §1.2)."""

    model: Literal["frictionless", "coulomb", "bonded"] = "frictionless"
    friction: float = Field(0.0, ge=0, le=10.0, description="Coulomb coefficient mu (required > 0 for 'coulomb')")

    @model_validator(mode="before")
    @classmethod
    def _friction_only_for_coulomb(cls, data):
        # friction is ignored by the other models (SPEC §2): dropping it keeps one id per
        # physical case (a bonded case with friction 0.3 is the bonded case)
        if isinstance(data, dict) and data.get("model", "frictionless") != "coulomb" and _ignorable(data.get("friction")):
            data = {**data, "friction": 0.0}
        return data

    @model_validator(mode="after")
    def _friction_needed(self) -> "Interface":
        if self.model == "coulomb" and self.friction <= 0:
            raise ValueError("friction: interface.model 'coulomb' needs interface.friction > 0")
        return self


class Design(_Frozen):
    """EN 1992-1-1 section check of the lining (SPEC §1.3), per metre of tunnel."""

    concrete_strength: float = Field(3.0e7, ge=1.2e7, le=9.0e7, description="fck (Pa), C12 to C90")
    steel_strength: float = Field(5.0e8, ge=2.0e8, le=7.0e8, description="fyk (Pa)")
    reinforcement_area: float = Field(
        1.5e-3, ge=0, le=0.05,
        description="As per face (m^2/m), symmetric (default: 14 mm bars at 100 mm); 0 means plain concrete")
    axis_distance: float = Field(0.05, gt=0, le=0.5, description="reinforcement axis distance from each face (m)")
    load_factor: float = Field(1.35, gt=0, le=10.0, description="gamma_F: design actions are gamma_F times N and M")


class Boundaries(_Frozen):
    side: Literal["fixed", "roller", "pressure"] = "roller"
    bottom: Literal["fixed", "roller"] = "fixed"


class MeshSettings(_Frozen):
    interface_size: float = Field(0.1, ge=1e-3, description="element size along the interface (m)")
    far_size: float = Field(4.0, gt=0, le=1000.0, description="element size far from the tunnel (m)")


class SolverSettings(_Frozen):
    inner: Literal["active-set", "uzawa"] = "active-set"
    tolerance: float = Field(1e-8, ge=1e-14, le=1e-2,
                             description="relative KKT tolerance (no finer than double precision resolves, 1e-14)")
    max_iterations: int = Field(100_000, ge=1, le=10_000_000, description="inner iteration cap per bolt")
    load_steps: int = Field(
        10, ge=1, le=1000, description="increments per construction stage (Mohr-Coulomb ground)")
    bolt: Union[Literal["auto"], float] = Field(
        "auto", description="'auto' (bolt-point search) or a bolt position theta in degrees [0, 180]")

    @field_validator("bolt", mode="before")
    @classmethod
    def _bolt_kind(cls, v):
        # one clear error instead of one per branch of the union
        if v == "auto" or is_number(v):
            return v
        raise ValueError(f"bolt: expected 'auto' or a position in degrees, got {v!r}")

    @field_validator("bolt")
    @classmethod
    def _bolt_range(cls, v):
        if v != "auto" and not (0.0 <= float(v) <= 180.0):
            raise ValueError(f"bolt: theta {v} deg is outside [0, 180]")
        return v


def _round3_defaults() -> dict[str, dict]:
    defaults = {
        "ground": {k: Strength.model_fields[k].default for k in Strength.model_fields} | {"layers": []},
        "lining": {"joints": Joints().model_dump(mode="json")},
        "solver": {"load_steps": SolverSettings.model_fields["load_steps"].default},
        "water": Water().model_dump(mode="json"),
    }
    return defaults


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
        from .strata import geostatic_errors, strata

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
        return any(layer.model == "mohr-coulomb" for layer in (self.ground, *self.ground.layers))

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
            solver = solver.model_copy(update={"load_steps": SolverSettings.model_fields["load_steps"].default})
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
        n = estimated_elements(self)
        if n > MAX_ELEMENTS:
            raise ValueError(
                f"mesh.interface_size: this mesh would have about {n:,} elements, over the cap "
                f"of {MAX_ELEMENTS:,}; use a larger mesh.interface_size or mesh.far_size")
        return self

    def canonical_json(self) -> str:
        """Defaults filled, keys sorted, no whitespace: the text the case id hashes.

        Round-3 fields (SPEC §2: strata, water, plasticity, joints, load steps) are left out
        while they hold their defaults, so every case that gives none of them keeps its id.
        """
        data = self.model_dump(mode="json")
        for section, fields in ROUND3_DEFAULTS.items():
            for name, default in fields.items():
                if data[section].get(name, default) == default:
                    data[section].pop(name, None)
        if data["water"] == {}:
            del data["water"]
        return json.dumps(data, sort_keys=True, separators=(",", ":"))

    @property
    def case_id(self) -> str:
        """Stable 16-hex-digit id of the physical case (sha256 of the canonical JSON)."""
        return content_id(self.canonical_json())


#: Round-3 fields and their defaults: left out of the canonical JSON while at them.
ROUND3_DEFAULTS = _round3_defaults()


