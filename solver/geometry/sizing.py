"""Mesh sizing of a case: element layers, interface segments, size field and the element estimate.

These functions only read ``spec.geometry`` and ``spec.mesh`` (anything with those two
attributes will do), so :mod:`solver.spec` can validate the mesh size before a
:class:`~solver.spec.CaseSpec` exists and :mod:`solver.geometry.mesh` builds exactly what was estimated.
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Any, NamedTuple

#: Largest mesh (triangles, both bodies) a case may ask for. Quadratic triangles carry
#: about four times the unknowns of linear ones: 300 000 of them are about 1.2 M DOF, the
#: budget the linear cap (600 000) had. Measured: 37 700 triangles (153k DOF) peak at
#: 1.1 GB and 11 s, so the cap stays within a worker of several GB.
MAX_ELEMENTS = 300_000


class _SizeOnly(NamedTuple):
    """The parts of a case that fix the mesh size (duck-types CaseSpec for the helpers below)."""

    geometry: Any
    mesh: Any


#: Layers of quadratic elements through the lining thickness, at least (tunable for studies).
MIN_LINING_LAYERS = 2


def lining_layers(spec) -> int:
    """Quadratic element layers through the lining thickness: at least
    :data:`MIN_LINING_LAYERS`, and at most one interface element thick (P2 triangles
    represent the linear bending strain across a layer exactly)."""
    return max(MIN_LINING_LAYERS, math.ceil(spec.geometry.thickness / spec.mesh.interface_size - 1e-9))


def interface_segments(spec) -> int:
    """Segments of the interface per quarter circle (crown-springline, springline-invert)."""
    g = spec.geometry
    return max(4, math.ceil(0.5 * math.pi * g.hole_radius / spec.mesh.interface_size - 1e-9))


def size_field_distances(spec) -> tuple[float, float]:
    """Distances from the interface over which the size grows from interface to far size (m).

    The growth (1/6 of the size per metre) suits quadratic elements: against the
    slower growth (1/12) P1 needed, the default case's lining forces change by less
    than 2e-5 with 37 % fewer nodes (measured, README)."""
    r = spec.geometry.hole_radius
    return 0.25 * r, 0.25 * r + 6.0 * (spec.mesh.far_size - spec.mesh.interface_size) + r


#: Triangles gmsh makes per ideal equilateral triangle of the size field (measured on graded
#: and uniform meshes up to 3e5 triangles: at most 1.09, see tests/solver/test_sizing.py), with a margin.
MESHER_FACTOR = 1.25


def estimated_elements(spec) -> int:
    """An upper bound of the triangles in the mesh of ``spec``, without meshing.

    The lining is structured: its count is exact. The ground count is bounded by the
    integral of the ideal triangle density ``4 / (sqrt(3) h^2)`` of the size field ``h``
    (the one gmsh is given, a function of the distance ``s = r - R`` to the excavation of
    radius ``R``), computed in closed form:

    ``int_ground rho dA <= rho_far |ground| + pi int_R^(R + d_max) (rho(r) - rho_far) r dr``

    since ``rho - rho_far`` vanishes beyond the refined band and the ground within a
    radius ``r`` of the axis lies in a half disc. This holds for any domain: the band
    need not fit in it. gmsh's distance field samples the curve, which can only overstate
    the distance and so only lower the density. :data:`MESHER_FACTOR` covers the
    mesher's excess over the ideal count. Cached per (geometry, mesh): the service
    validates every submission with it.
    """
    return _estimated_elements(spec.geometry, spec.mesh)


@lru_cache(maxsize=4096)
def _estimated_elements(g, m) -> int:
    spec = _SizeOnly(geometry=g, mesh=m)
    lining = 2 * (2 * interface_segments(spec)) * lining_layers(spec)
    R = g.hole_radius
    area = g.width * g.height - 0.5 * math.pi * R * R
    d_min, d_max = size_field_distances(spec)
    ground = ground_density_integral(R, area, m.interface_size, m.far_size, d_min, d_max)
    total = lining + MESHER_FACTOR * ground
    # bounds of the case model keep this finite; never let an overflow escape as an error
    return int(total) if math.isfinite(total) and total < 2.0**62 else 2**62


def ground_density_integral(R: float, area: float, size_min: float, size_max: float,
                            d_min: float, d_max: float) -> float:
    """Upper bound of the ideal triangle count of a ground of ``area`` m^2 around a half
    excavation of radius ``R`` m, with the threshold size field of :func:`size_field_distances`
    (``size_min`` up to ``d_min`` from the excavation, linear to ``size_max`` at ``d_max``).
    """
    c = 4.0 / math.sqrt(3.0)
    rho_min, rho_max = c / size_min**2, c / size_max**2  # densities near and far
    # refined ring s in [0, d_min] around the excavation
    band = (rho_min - rho_max) * (R * d_min + 0.5 * d_min**2)
    width = d_max - d_min
    grow = size_max - size_min
    if grow > 1e-3 * size_min and width > 0:
        # graded ring: h = size_min + k (s - d_min), r = R + s; substitute u = h
        k = grow / width
        r0 = R + d_min
        a = r0 - size_min / k
        band += (c * a * (1.0 / size_min - 1.0 / size_max) + (c / k) * math.log(size_max / size_min)
                 - rho_max * (r0 * grow + 0.5 * grow**2 / k)) / k
    else:  # (almost) uniform: bound the density by its largest value
        band += (rho_min - rho_max) * (r0 := R + d_min) * width + (rho_min - rho_max) * 0.5 * width**2
    return rho_max * area + math.pi * band


def check_mesh_size(n_elements: int) -> None:
    """Refuse a generated mesh over :data:`MAX_ELEMENTS` (the run-time half of the cap)."""
    if n_elements > MAX_ELEMENTS:
        from ..errors import SolverError

        raise SolverError(
            f"mesh.interface_size: the mesh has {n_elements:,} elements, over the cap of "
            f"{MAX_ELEMENTS:,}; use a larger mesh.interface_size or mesh.far_size")


def ground_size_field(spec, hole, *, sampling: int) -> None:
    """The ground's element size in the current gmsh model: ``interface_size`` at the excavation
    boundary (the curves ``hole``, sampled ``sampling`` times each) growing to ``far_size`` over
    :func:`size_field_distances`, as the background mesh size."""
    import gmsh

    m = spec.mesh
    d_min, d_max = size_field_distances(spec)
    fields = gmsh.model.mesh.field
    dist = fields.add("Distance")
    fields.setNumbers(dist, "CurvesList", list(hole))
    fields.setNumber(dist, "Sampling", sampling)
    thr = fields.add("Threshold")
    fields.setNumber(thr, "InField", dist)
    fields.setNumber(thr, "SizeMin", m.interface_size)
    fields.setNumber(thr, "SizeMax", m.far_size)
    fields.setNumber(thr, "DistMin", d_min)
    fields.setNumber(thr, "DistMax", d_max)
    fields.setAsBackgroundMesh(thr)
