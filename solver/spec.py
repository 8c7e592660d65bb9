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
from functools import lru_cache
from typing import Literal, NamedTuple, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

#: Largest mesh (triangles, both bodies) a case may ask for; ~1.2 M DOF.
MAX_ELEMENTS = 600_000


def canonical_json(model: BaseModel) -> str:
    """Defaults filled, keys sorted, no whitespace: the text a model's id hashes."""
    return json.dumps(model.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))


def content_id(text: str) -> str:
    """Stable 16-hex-digit id of a canonical text (first digits of its sha256)."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Geometry(_Frozen):
    """Tunnel geometry in metres (half model, axis at ``(0, -depth)``)."""

    inner_radius: float = Field(2.5, gt=0, description="lining inner radius a (m)")
    thickness: float = Field(0.3, gt=0, description="lining thickness t (m)")
    depth: float = Field(15.0, gt=0, description="depth of the tunnel axis below the surface (m)")
    width: float = Field(40.0, gt=0, description="ground model width from the symmetry axis (m)")
    height: float = Field(50.0, gt=0, description="ground model height (m)")
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

    young: float = Field(gt=0, description="Young's modulus E (Pa)")
    poisson: float = Field(ge=0, lt=0.5, description="Poisson ratio, in [0, 0.5)")
    density: float = Field(ge=0, description="mass density (kg/m^3)")


class Ground(Material):
    young: float = Field(5.0e7, gt=0, description="ground Young's modulus (Pa)")
    poisson: float = Field(0.3, ge=0, lt=0.5, description="ground Poisson ratio")
    density: float = Field(2000.0, ge=0, description="ground density (kg/m^3)")


class Lining(Material):
    young: float = Field(3.0e10, gt=0, description="lining Young's modulus (Pa)")
    poisson: float = Field(0.2, ge=0, lt=0.5, description="lining Poisson ratio")
    density: float = Field(
        2500.0, gt=0,
        description="lining density (kg/m^3); must be > 0: the floating lining needs weight")


class Loads(_Frozen):
    surface_load: float = Field(1.0e5, ge=0, description="uniform downward pressure on y = 0 (Pa)")
    gravity: float = Field(
        9.81, gt=0, description="gravitational acceleration, downward (m/s^2); > 0 so the lining has weight")
    lateral_ratio: float = Field(
        0.5, ge=0, description="K0: horizontal / vertical geostatic stress on a 'pressure' side")


class Boundaries(_Frozen):
    side: Literal["fixed", "roller", "pressure"] = "fixed"
    bottom: Literal["fixed", "roller"] = "fixed"


class MeshSettings(_Frozen):
    interface_size: float = Field(0.05, gt=0, description="element size along the interface (m)")
    far_size: float = Field(4.0, gt=0, description="element size far from the tunnel (m)")


class SolverSettings(_Frozen):
    inner: Literal["active-set", "uzawa"] = "active-set"
    tolerance: float = Field(1e-8, gt=0, le=1e-2, description="relative KKT tolerance")
    max_iterations: int = Field(100_000, ge=1, le=10_000_000, description="inner iteration cap per bolt")
    bolt: Union[Literal["auto"], float] = Field(
        "auto", description="'auto' (bolt-point search) or a bolt position theta in degrees [0, 180]")

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
    boundaries: Boundaries = Boundaries()
    mesh: MeshSettings = MeshSettings()
    solver: SolverSettings = SolverSettings()

    @model_validator(mode="after")
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


class _SizeOnly(NamedTuple):
    """The parts of a case that fix the mesh size (duck-types CaseSpec for the helpers below)."""

    geometry: Geometry
    mesh: MeshSettings


def lining_layers(spec: CaseSpec) -> int:
    """Element layers through the lining thickness: at least four, and at most half an
    interface element thick (P1 triangles are too stiff in bending when coarse across
    the thickness; the lining is a small part of the DOFs)."""
    return max(4, math.ceil(2.0 * spec.geometry.thickness / spec.mesh.interface_size - 1e-9))


def interface_segments(spec: CaseSpec) -> int:
    """Segments of the interface per quarter circle (crown-springline, springline-invert)."""
    g = spec.geometry
    return max(4, math.ceil(0.5 * math.pi * g.hole_radius / spec.mesh.interface_size - 1e-9))


def size_field_distances(spec: CaseSpec) -> tuple[float, float]:
    """Distances from the interface over which the size grows from interface to far size (m)."""
    r = spec.geometry.hole_radius
    return 0.25 * r, 0.25 * r + 12.0 * (spec.mesh.far_size - spec.mesh.interface_size) + r


def estimated_elements(spec: CaseSpec) -> int:
    """Triangles the mesh of ``spec`` will have, estimated without meshing (within ~30 %).

    The ground count integrates 4/(sqrt(3) h^2) over the domain with the same size
    field gmsh uses; the lining is structured. Cached per (geometry, mesh): the
    service validates every submission with it.
    """
    return _estimated_elements(spec.geometry, spec.mesh)


@lru_cache(maxsize=4096)
def _estimated_elements(g: Geometry, m: MeshSettings) -> int:
    import numpy as np

    spec = _SizeOnly(geometry=g, mesh=m)
    lining = 2 * (2 * interface_segments(spec)) * lining_layers(spec)
    d_min, d_max = size_field_distances(spec)
    nx, ny = 200, 250
    xs = (np.arange(nx) + 0.5) * g.width / nx
    ys = -(np.arange(ny) + 0.5) * g.height / ny
    x, y = np.meshgrid(xs, ys)
    dist = np.hypot(x, y + g.depth) - g.hole_radius
    inside = dist < 0
    frac = np.clip((dist - d_min) / (d_max - d_min), 0.0, 1.0)
    h = m.interface_size + frac * (m.far_size - m.interface_size)
    density = 4.0 / (math.sqrt(3.0) * h**2)
    cell = (g.width / nx) * (g.height / ny)
    ground = float(np.sum(np.where(inside, 0.0, density)) * cell)
    return int(lining + ground)
