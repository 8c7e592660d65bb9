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
from typing import Literal, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .design import section_errors
from .sizing import MAX_ELEMENTS, estimated_elements

__all__ = ["CaseSpec", "MAX_ELEMENTS", "canonical_json", "content_id"]

#: Physical bounds, wide but real: soft soil to steel, and a Poisson ratio far enough
#: below 1/2 that plane-strain elasticity stays well conditioned (volumetric locking).
MIN_YOUNG, MAX_YOUNG = 1.0e5, 1.0e12
MAX_POISSON = 0.49
MAX_DENSITY = 2.0e4
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


def _ignorable(value) -> bool:
    """Whether ``value`` of a field its model ignores may be replaced by the canonical one: a
    finite number (anything else is left for validation to refuse)."""
    return is_number(value) and math.isfinite(value)


class _Frozen(BaseModel):
    # allow_inf_nan=False: NaN, Infinity and overflowing literals such as 1e400 are
    # refused with the field's name instead of failing later in the solver.
    # strict: a number is a number. Lax validation took JSON ``true`` as 1.0 (a 1 m
    # lining) and the string "0.5" as 0.5; an integer field takes integers only.
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False, strict=True)


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


class Ground(Material):
    young: float = Field(5.0e7, ge=MIN_YOUNG, le=MAX_YOUNG, description="ground Young's modulus (Pa)")
    poisson: float = Field(0.3, ge=0, le=MAX_POISSON, description="ground Poisson ratio")
    density: float = Field(2000.0, ge=0, le=MAX_DENSITY, description="ground density (kg/m^3)")


class Lining(Material):
    young: float = Field(3.0e10, ge=MIN_YOUNG, le=MAX_YOUNG, description="lining Young's modulus (Pa)")
    poisson: float = Field(0.2, ge=0, le=MAX_POISSON, description="lining Poisson ratio")
    density: float = Field(
        2500.0, gt=0, le=MAX_DENSITY,
        description="lining density (kg/m^3); must be > 0: the floating lining needs weight")


class Loads(_Frozen):
    surface_load: float = Field(1.0e5, ge=0, le=1.0e9, description="uniform downward pressure on y = 0 (Pa)")
    gravity: float = Field(
        9.81, gt=0, le=100.0,
        description="gravitational acceleration, downward (m/s^2); > 0 so the lining has weight")
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
    tolerance: float = Field(1e-8, gt=0, le=1e-2, description="relative KKT tolerance")
    max_iterations: int = Field(100_000, ge=1, le=10_000_000, description="inner iteration cap per bolt")
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

    @model_validator(mode="after")
    def _consistent(self) -> "CaseSpec":
        if self.interface.model == "bonded" and self.geometry.gap > 0:
            # [u]ν = 0 with a clearance would glue the lining to ground it never reaches
            raise ValueError(
                f"geometry.gap: {self.geometry.gap} m of clearance cannot be bonded (a bonded "
                "interface ties lining and ground where they stand, so gap must be 0); use "
                "'frictionless' or 'coulomb', whose contact closes the gap first")
        ratio = self.lining.young / self.ground.young
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
        """Defaults filled, keys sorted, no whitespace: the text the case id hashes."""
        return canonical_json(self)

    @property
    def case_id(self) -> str:
        """Stable 16-hex-digit id of the physical case (sha256 of the canonical JSON)."""
        return content_id(self.canonical_json())


