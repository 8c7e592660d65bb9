"""Mesh sizing of a case: element layers, interface segments, size field and the element estimate.

These functions only read ``spec.geometry`` and ``spec.mesh`` (anything with those two
attributes will do), so :mod:`solver.spec` can validate the mesh size before a
:class:`~solver.spec.CaseSpec` exists and :mod:`solver.mesh` builds exactly what was estimated.
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Any, NamedTuple

#: Largest mesh (triangles, both bodies) a case may ask for.
MAX_ELEMENTS = 600_000


class _SizeOnly(NamedTuple):
    """The parts of a case that fix the mesh size (duck-types CaseSpec for the helpers below)."""

    geometry: Any
    mesh: Any


def lining_layers(spec) -> int:
    """Element layers through the lining thickness: at least four, and at most half an
    interface element thick (P1 triangles are too stiff in bending when coarse across
    the thickness; the lining is a small part of the DOFs)."""
    return max(4, math.ceil(2.0 * spec.geometry.thickness / spec.mesh.interface_size - 1e-9))


def interface_segments(spec) -> int:
    """Segments of the interface per quarter circle (crown-springline, springline-invert)."""
    g = spec.geometry
    return max(4, math.ceil(0.5 * math.pi * g.hole_radius / spec.mesh.interface_size - 1e-9))


def size_field_distances(spec) -> tuple[float, float]:
    """Distances from the interface over which the size grows from interface to far size (m)."""
    r = spec.geometry.hole_radius
    return 0.25 * r, 0.25 * r + 12.0 * (spec.mesh.far_size - spec.mesh.interface_size) + r


def estimated_elements(spec) -> int:
    """Triangles the mesh of ``spec`` will have, estimated without meshing (within ~30 %).

    The ground count integrates 4/(sqrt(3) h^2) over the domain with the same size
    field gmsh uses; the lining is structured. Cached per (geometry, mesh): the
    service validates every submission with it.
    """
    return _estimated_elements(spec.geometry, spec.mesh)


@lru_cache(maxsize=4096)
def _estimated_elements(g, m) -> int:
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
