"""The mesh-size estimate is an upper bound for any domain, and the cap also holds at run time."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from solver import CaseSpec, SolverError
from solver.errors import field_errors
from solver.geometry.mesh import build_mesh
from solver.geometry.sizing import (MAX_ELEMENTS, MESHER_FACTOR, check_mesh_size, estimated_elements,
                           ground_density_integral, size_field_distances)

#: The body of issue 10 that the old sampled estimate let through (1.14 M triangles).
BYPASS = {"mesh": {"interface_size": 0.0025, "far_size": 2000},
          "geometry": {"thickness": 0.1, "width": 20000, "height": 40000, "depth": 20000}}
#: The same trick within the geometry bounds: the old estimate (a 200 x 250 sample grid that
#: misses the refined band) said 211 k triangles; the ideal count alone is over 1.1 M.
BYPASS_IN_BOUNDS = {"mesh": {"interface_size": 0.004, "far_size": 1000},
                    "geometry": {"thickness": 0.1, "width": 10000, "height": 10000, "depth": 5000},
                    "design": {"axis_distance": 0.02}}


def test_the_bypass_body_is_refused_naming_the_mesh_size():
    with pytest.raises(ValidationError):
        CaseSpec.model_validate(BYPASS)
    with pytest.raises(ValidationError) as info:
        CaseSpec.model_validate(BYPASS_IN_BOUNDS)
    [(field, reason)] = field_errors(info.value)
    assert field == "mesh.interface_size" and "over the cap" in reason


@pytest.mark.parametrize("case", [
    {},
    {"mesh": {"interface_size": 0.5, "far_size": 0.5}},  # uniform
    {"geometry": {"width": 2000, "height": 4000, "depth": 2000},  # band far smaller than the domain
     "mesh": {"interface_size": 0.05, "far_size": 200}},
    {"geometry": {"width": 8, "height": 20, "depth": 10},  # band far larger than the domain
     "mesh": {"interface_size": 0.05, "far_size": 1000}},
])
def test_estimate_bounds_what_gmsh_makes(case):
    spec = CaseSpec.model_validate(case)
    mesh = build_mesh(spec)
    actual = mesh.ground.t.shape[1] + mesh.lining.t.shape[1]
    estimate = estimated_elements(spec)
    assert actual <= estimate <= 2 * actual


def _quadrature(R, width, height, depth, size_min, size_max, d_min, d_max, n=1500):
    """The ideal triangle count of the ground by midpoint quadrature in polar coordinates."""
    c = 4 / math.sqrt(3)
    total = 0.0
    r_edges = np.linspace(R, math.hypot(width, max(depth, height - depth)), n + 1)
    t_edges = np.linspace(-math.pi / 2, math.pi / 2, n + 1)  # x >= 0
    r, t = np.meshgrid(0.5 * (r_edges[1:] + r_edges[:-1]), 0.5 * (t_edges[1:] + t_edges[:-1]))
    x, y = r * np.cos(t), -depth + r * np.sin(t)
    inside = (x <= width) & (y <= 0) & (y >= -height)
    s = r - R
    h = size_min + np.clip((s - d_min) / (d_max - d_min), 0, 1) * (size_max - size_min)
    cell = r * np.diff(r_edges)[0] * np.diff(t_edges)[0]
    total = float(np.sum(np.where(inside, c / h**2 * cell, 0.0)))
    return total


def test_closed_form_is_exact_when_the_band_fits_and_an_upper_bound_otherwise():
    for width, height, depth, far in ((400.0, 400.0, 200.0, 8.0), (30.0, 40.0, 20.0, 40.0)):
        R, size_min = 2.8, 0.1
        g = type("G", (), dict(hole_radius=R))
        m = type("M", (), dict(interface_size=size_min, far_size=far))
        d_min, d_max = size_field_distances(type("S", (), dict(geometry=g, mesh=m)))
        area = width * height - 0.5 * math.pi * R**2
        bound = ground_density_integral(R, area, size_min, far, d_min, d_max)
        exact = _quadrature(R, width, height, depth, size_min, far, d_min, d_max)
        fits = R + d_max < min(width, depth, height - depth)
        assert bound >= 0.99 * exact  # (the quadrature is good to a few 0.1 %)
        if fits:
            assert bound == pytest.approx(exact, rel=2e-3)


@pytest.mark.parametrize("mesh", [{"interface_size": 1e-300}, {"far_size": 1e308},
                                  {"interface_size": 0.001, "far_size": 0.001}])
def test_extreme_sizes_are_refused_without_overflow(mesh):
    with pytest.raises(ValidationError) as info:
        CaseSpec.model_validate({"mesh": mesh, "geometry": {"width": 10000, "height": 10000, "depth": 5000}})
    assert all(field.startswith("mesh.") for field, _ in field_errors(info.value))


def test_run_time_cap_refuses_a_mesh_over_it():
    check_mesh_size(MAX_ELEMENTS)
    with pytest.raises(SolverError, match="mesh.interface_size"):
        check_mesh_size(MAX_ELEMENTS + 1)
    assert MESHER_FACTOR >= 1.0
