"""The geometry, lining, water, loads, stages, interface, design and numerical settings of a case."""
from __future__ import annotations

from functools import lru_cache
from typing import Literal, Optional, Union

import numpy as np

from pydantic import Field, field_validator, model_validator

from ..geometry.section import equal_area_radius
from ..ground.ldp import PROFILES
from .canonical import MAX_DENSITY, MAX_POISSON, MAX_SEGMENTS, MAX_YOUNG, MIN_YOUNG, _Frozen, _ignorable, is_number
from .ground import Material
from .section import Section


class Geometry(_Frozen):
    """Tunnel geometry in metres (half model, axis at ``(0, -depth)``)."""

    inner_radius: float = Field(2.5, ge=0.1, le=50.0, description="lining inner radius a (m)")
    thickness: float = Field(0.3, gt=0, description="lining thickness t (m)")
    depth: float = Field(15.0, gt=0, le=5000.0, description="depth of the tunnel axis below the surface (m)")
    width: float = Field(40.0, gt=0, le=10000.0, description="ground model width from the symmetry axis (m)")
    height: float = Field(50.0, gt=0, le=10000.0, description="ground model height (m)")
    gap: float = Field(0.0, ge=0, description="initial radial clearance g0 between lining and ground (m)")
    section: Section = Field(Section(), description="the intrados's shape (SPEC §9.4); circle: inner_radius")

    @property
    def circle(self) -> bool:
        """Whether the section is a circle of radius ``inner_radius`` (every case before §9.4)."""
        return self.section.shape == "circle"

    def profile(self, offset: float = 0.0):
        """The intrados moved ``offset`` (m) along its outward normal, as a
        :class:`~solver.geometry.section.Profile` centred on the section's centre."""
        return _profile(self.section, self.inner_radius, offset)

    @property
    def outer_radius(self) -> float:
        """Lining outer radius b = a + t (m); for another shape, the radius of the circle of the
        extrados's area."""
        if self.circle:
            return self.inner_radius + self.thickness
        return equal_area_radius(self.profile(self.thickness))

    @property
    def hole_radius(self) -> float:
        """Radius of the excavation in the ground, b + g0 (m); for another shape, the radius of
        the circle of the excavated area (the extrados's offset by the gap)."""
        if self.circle:
            return self.outer_radius + self.gap
        return equal_area_radius(self.profile(self.thickness + self.gap))

    @property
    def hole_extent(self) -> tuple[float, float, float]:
        """The excavation's reach from the section's centre (m): up to the crown, down to the
        invert, sideways (the hole radius three times for a circle)."""
        if self.circle:
            r = self.hole_radius
            return r, r, r
        return _extent(self.section, self.inner_radius, self.thickness + self.gap)

    @model_validator(mode="after")
    def _fits(self) -> "Geometry":
        if not self.circle:  # the intrados is the section's: inner_radius is its equal-area radius
            radius = equal_area_radius(_profile(self.section, 1.0, 0.0))
            if not 0.1 <= radius <= 50.0:  # the bounds of inner_radius, which the canonical JSON holds
                raise ValueError(f"section: the intrados encloses the area of a circle of radius {radius:.4g} m, "
                                 "outside [0.1, 50] m")
            object.__setattr__(self, "inner_radius", radius)
        up, down, side = self.hole_extent
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
        cover = self.depth - up
        if cover <= 0.25 * r:
            raise ValueError(
                f"depth: cover above the tunnel is {cover:.4g} m; it must exceed a quarter "
                f"of the excavation radius ({0.25 * r:.4g} m)")
        below = self.height - self.depth - down
        if below <= 0.25 * r:
            raise ValueError(
                f"height: room below the tunnel is {below:.4g} m; it must exceed a quarter "
                f"of the excavation radius ({0.25 * r:.4g} m)")
        beside = self.width - side
        if beside <= 0.25 * r:
            raise ValueError(
                f"width: room beside the tunnel is {beside:.4g} m; it must exceed a quarter "
                f"of the excavation radius ({0.25 * r:.4g} m)")
        return self


@lru_cache(maxsize=256)
def _profile(section: Section, inner_radius: float, offset: float):
    return section.profile(inner_radius).offset_by(offset)


@lru_cache(maxsize=256)
def _extent(section: Section, inner_radius: float, offset: float) -> tuple[float, float, float]:
    hole = _profile(section, inner_radius, offset)
    p = hole.points(np.linspace(0.0, np.pi, 2001))
    return float(p[1, 0]), float(-p[1, -1]), float(p[0].max())


#: A joint offset this close to 180/n (deg) is taken as 180/n: what a person types for 180/7.
OFFSET_TOLERANCE = 1e-4


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
                # unknown keys are kept, for the error that names them (a typo is not ignorable)
                data = {k: v for k, v in data.items() if k == "count" or k not in cls.model_fields
                        or not _ignorable(v)} | \
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
        half = 180.0 / n
        if abs(self.offset - half) <= OFFSET_TOLERANCE and self.offset != half:
            # 180/7 typed as 25.7143 (as the message below prints it) is the pattern meant: one case, one id
            object.__setattr__(self, "offset", half)
        if not any(abs(self.offset - o) <= 1e-9 for o in (0.0, half)):
            raise ValueError(f"offset: {self.offset} deg makes the pattern of {n} segments unsymmetric about "
                             f"the vertical axis; use 0 or {half:.6g}")
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
            data = {k: v for k, v in data.items() if k == "table" or k not in cls.model_fields or not _ignorable(v)}
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
    """How the tunnel is built (SPEC §1.1), and where the lining is installed (§9.5)."""

    method: Literal["deconfinement", "wished-in-place"] = Field(
        "deconfinement",
        description="'deconfinement': in-situ stress, excavation, lining placed after a release "
                    "of lambda_d; 'wished-in-place': the paper's model, both bodies stress-free")
    deconfinement: Optional[float] = Field(
        0.3, ge=0, le=1,
        description="lambda_d: fraction of the excavation load released before the lining is placed "
                    "(no meaning for 'wished-in-place', where it is recorded as 0; found, not given, "
                    "with face_distance)")
    face_distance: Optional[float] = Field(
        None, ge=0, le=1000.0,
        description="distance behind the face at which the lining is installed (m); lambda_d is then "
                    "found from the longitudinal displacement profile 'ldp' and the ground reaction curve")
    ldp: Literal[PROFILES] = Field(
        "vlachopoulos-diederichs", description="longitudinal displacement profile for face_distance")

    @model_validator(mode="before")
    @classmethod
    def _deconfinement_only_when_staged(cls, data):
        # as interface.friction: a value the model ignores must not split one physical case
        # into several ids (nor be kept in the record as if it had acted)
        if not isinstance(data, dict):
            return data
        if data.get("method") == "wished-in-place" \
                and ("deconfinement" not in data or _ignorable(data["deconfinement"])):
            data = {**data, "deconfinement": 0.0}
        if data.get("face_distance") is None:
            if "ldp" in data and data["ldp"] in PROFILES:  # the profile only serves a face distance
                data = {**data, "ldp": "vlachopoulos-diederichs"}
        elif data.get("method", "deconfinement") == "deconfinement":
            if data.get("deconfinement") is not None:
                raise ValueError(
                    "deconfinement: give excavation.deconfinement or excavation.face_distance, not both "
                    "(with a face distance the deconfinement is found from the longitudinal displacement "
                    "profile and the ground reaction curve)")
            data = {**data, "deconfinement": None}
        return data

    @model_validator(mode="after")
    def _stage_defined(self) -> "Excavation":
        if self.face_distance is not None and self.method != "deconfinement":
            raise ValueError("face_distance: a face distance needs excavation.method = 'deconfinement' (the "
                             "'wished-in-place' lining is placed before any release)")
        if self.face_distance is None and self.deconfinement is None:
            raise ValueError("deconfinement: a number from 0 to 1 (or give excavation.face_distance)")
        return self


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
    load_factor: float = Field(
        1.35, gt=0, le=10.0,
        description="gamma_F: design actions gamma_F M and gamma_F V with the worse of gamma_F N and 1.0 N")
    crack_width_limit: float = Field(
        0.3e-3, gt=0, le=0.01, description="largest characteristic crack width w_k that passes (m; EN 1992-1-1 7.3.1)")
    bar_diameter: float = Field(
        0.014, ge=0.006, le=0.05, description="diameter phi of the bars of each face (m), for the crack spacing (7.11)")


class Settlement(_Frozen):
    """The design surface trough (SPEC §9.3): Gaussian, after O'Reilly & New (1982)."""

    volume_loss: Optional[float] = Field(
        None, gt=0, le=0.2,
        description="volume loss V_L of the design trough (1, e.g. 0.01 for 1 %); null: the case's own ground_loss")
    trough_width_factor: float = Field(
        0.5, ge=0.05, le=2.0, description="K of the trough width i = K z0 (0.5 clays, 0.25-0.35 sands)")


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
    plastic_tolerance: float = Field(
        1e-2, ge=1e-6, le=0.1,
        description="yielding ground's stop test: out-of-balance force over the load increment's (1e-6 to 0.1)")
    bolt: Union[Literal["auto"], float] = Field(
        "auto", description="'auto' (bolt-point search) or a bolt position theta in degrees [0, 180]")
    mesh_check: bool = Field(
        False, description="also solve on a mesh refined once (every size halved) and report the relative "
                           "changes of the key results (mesh_change_*; a warning above 1 %)")

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
