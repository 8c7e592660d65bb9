"""Sections beyond the circle solved end to end (SPEC §9.4): a circle entered as two arcs is the
circle, Inglis's elliptical hole, and a lined horseshoe's free-body equilibrium."""
from __future__ import annotations

import numpy as np
import pytest
from skfem import Basis, ElementTriP2, Functional

from solver import CaseSpec, run_case
from solver.model import TunnelModel

HORSESHOE = {"geometry": {"section": {"shape": "horseshoe", "crown_radius": 5.5, "crown_angle": 100.0,
                                      "side_radius": 3.5, "side_angle": 50.0},
                          "thickness": 0.3, "depth": 25.0, "width": 60.0, "height": 70.0},
             "mesh": {"interface_size": 0.2}}


def test_circle_as_two_arcs_is_the_circle():
    """The polycentric path (polylines through the arcs, edge nodes on the true curve, cuts
    normal to the mid-surface) against today's circle at the default mesh: N, M, λ within 0.1 %
    (their ground meshes differ: gmsh meshes the ground from polylines, not arcs)."""
    base = {}
    circle = run_case(CaseSpec.model_validate(base))
    arcs = run_case(CaseSpec.model_validate({**base, "geometry": {"section": {
        "shape": "polycentric", "arcs": [{"radius": 2.5, "angle": 90.0}, {"angle": 90.0}]}}}))
    theta = circle["theta"].values
    for name in ("thrust", "moment", "contact_pressure"):
        other = np.interp(theta, arcs["theta"].values, arcs[name].values)
        scale = np.max(np.abs(circle[name].values))
        assert np.max(np.abs(other - circle[name].values)) < 1e-3 * scale, name


P = 1.0e5
T = 0.02  # a thin lining: the excavation, its offset, is the ellipse W × H to a few 0.1 %


def _inglis_case(W: float, H: float, K: float) -> dict:
    """Weightless ground under far-field p (vertical) and Kp, the hole W × H fully released,
    the lining carrying only its own (small) weight."""
    return {"geometry": {"section": {"shape": "ellipse", "width": W - 2 * T, "height": H - 2 * T}, "thickness": T,
                         "depth": 60.0, "width": 60.0, "height": 120.0},
            "ground": {"density": 0.0, "young": 1.0e8, "poisson": 0.25},
            "lining": {"density": 1.0}, "design": {"reinforcement_area": 0.0, "axis_distance": 0.005},
            "loads": {"surface_load": P, "lateral_ratio": K}, "excavation": {"deconfinement": 1.0},
            "mesh": {"interface_size": 0.05, "far_size": 6.0}}


def _wall_hoop(ds, W: float, H: float, where: str, h: float) -> float:
    """The hoop stress (compression positive) at the wall's crown or side: the ground's face
    stresses within six sizes of the wall fitted by a quadratic in the distance from it
    (and the lateral offset), taken at the wall."""
    f = ds["face_nodes"].values
    x = ds["node_x"].values[f].mean(axis=1)
    y = ds["node_y"].values[f].mean(axis=1) + 60.0
    if where == "crown":
        d, s, lat = y - H / 2, ds["stress_xx"].values, x
    else:
        d, s, lat = x - W / 2, ds["stress_yy"].values, y
    sel = (ds["body"].values == 0) & (np.abs(lat) < 3 * h) & (d > 0) & (d < 6 * h)
    A = np.stack([np.ones(sel.sum()), d[sel], d[sel] ** 2, lat[sel] ** 2], axis=1)
    return -float(np.linalg.lstsq(A, s[sel], rcond=None)[0][0])


@pytest.mark.slow
@pytest.mark.parametrize("K", [0.5, 1.0])
@pytest.mark.parametrize("W, H", [(4.0, 8.0), (6.0, 6.0), (8.0, 4.0)])
def test_inglis_elliptical_hole(W, H, K):
    ds = run_case(CaseSpec.model_validate(_inglis_case(W, H, K)))
    crown, side = _wall_hoop(ds, W, H, "crown", 0.05), _wall_hoop(ds, W, H, "side", 0.05)
    exact_crown, exact_side = P * (K - 1 + 2 * K * H / W), P * (1 - K + 2 * W / H)
    # within 2 % of the larger of the two (the crown's is 0 for K = 0.5, W/H = 2)
    scale = max(abs(exact_crown), abs(exact_side))
    assert abs(crown - exact_crown) < 0.02 * scale
    assert abs(side - exact_side) < 0.02 * abs(exact_side)


@Functional
def _first_moment(w):
    return w.x[0]


@Functional
def _area(w):
    return 1.0 + 0.0 * w.x[0]


@pytest.mark.parametrize("variant", [
    {},
    {"interface": {"model": "coulomb", "friction": 0.4}, "water": {"table": 12.0, "lining": "watertight"}},
    {"ground": {"model": "mohr-coulomb", "cohesion": 4.0e4, "friction_angle": 30.0, "dilatancy": 5.0},
     "excavation": {"deconfinement": 0.5}},
], ids=["elastic", "coulomb-water", "mohr-coulomb"])
def test_horseshoe_free_body_equilibrium(variant):
    """The half lining as a free body: the interface tractions (with friction and water where the
    case has them), its weight and the cut forces at crown and invert balance, horizontally,
    vertically and in moment, to round-off; the contact answer is one (KKT)."""
    spec = CaseSpec.model_validate({**HORSESHOE, **variant})
    model = TunnelModel(spec)
    ds = run_case(spec, model=model)
    w, nx, ny = ds["weight"].values, ds["normal_x"].values, ds["normal_y"].values
    lam, s, water = ds["contact_pressure"].values, ds["shear_traction"].values, ds["water_pressure"].values
    fx = w * ((lam + water) * nx - s * ny)
    fy = w * ((lam + water) * ny + s * nx)
    x, y = ds["interface_x"].values, ds["interface_y"].values + spec.geometry.depth
    N, M = ds["thrust"].values, ds["moment"].values
    weight = float(ds["lining_weight"])
    basis = Basis(model.mesh.lining.skfem_mesh(), ElementTriP2())
    area = _area.assemble(basis)
    assert weight == pytest.approx(area * spec.lining.density * spec.loads.gravity, rel=1e-12)
    centroid_x = _first_moment.assemble(basis) / area
    assert abs(N[0] + N[-1] + fx.sum()) < 1e-8 * N[0]  # (2e-9 measured with water: its quadrature)
    assert abs(fy.sum() - weight) < 1e-8 * np.abs(fy).sum()
    t = spec.geometry.thickness
    terms = [np.sum(x * fy - y * fx), -weight * centroid_x, -(y[0] - t / 2) * N[0], -(y[-1] + t / 2) * N[-1],
             M[0], -M[-1]]
    assert abs(sum(terms)) < 1e-8 * max(abs(v) for v in terms)
    assert float(ds["kkt_residual"]) < 1e-8  # and the contact answer is one


def _tangent_point_moments(ds) -> np.ndarray:
    """M at the horseshoe's tangent points (turning angles 100° and 150°, vertex stations)."""
    phi = np.degrees(np.arctan2(-ds["normal_x"].values, -ds["normal_y"].values))
    return np.array([float(ds["moment"][np.argmin(np.abs(phi - b))]) for b in (100.0, 150.0)])


@pytest.mark.slow
def test_horseshoe_moments_converge_at_the_tangent_points():
    """Where the radius changes the moment jumps in slope; halving the mesh moves it < 0.5 %."""
    coarse = _tangent_point_moments(run_case(CaseSpec.model_validate(HORSESHOE)))
    fine = _tangent_point_moments(run_case(CaseSpec.model_validate({**HORSESHOE, "mesh": {"interface_size": 0.1}})))
    assert np.all(np.abs(coarse - fine) < 0.005 * np.abs(fine))


SOFT_OVER_STIFF = {"layers": [{"thickness": 13.8, "young": 3.0e7, "density": 1900.0, "lateral_ratio": 0.6},
                              {"thickness": 2.6, "young": 1.5e8, "density": 2100.0, "lateral_ratio": 0.45},
                              {"thickness": 0.0, "young": 6.0e8, "density": 2300.0, "lateral_ratio": 0.5}]}


def test_layers_cut_a_circle_entered_as_two_arcs_as_they_cut_the_circle():
    """Two layer lines through the excavation (1.2 m above and 1.4 m below the axis of a 2.8 m
    hole) with contrasting stiffness: the polycentric path's bands (the lines meeting the profile
    at a station found on the true curve) give the circle's N and M within 0.2 % of their largest
    values, the contact pressure within 0.5 % (measured 0.32 %: next to a line, where the pressure
    kinks, the two paths space their stations differently). A band given the wrong layer moves
    them by tens of per cent."""
    circle = run_case(CaseSpec.model_validate({"ground": SOFT_OVER_STIFF}))
    arcs = run_case(CaseSpec.model_validate({"ground": SOFT_OVER_STIFF, "geometry": {"section": {
        "shape": "polycentric", "arcs": [{"radius": 2.5, "angle": 90.0}, {"angle": 90.0}]}}}))
    theta = circle["theta"].values
    for name, tol in (("thrust", 2e-3), ("moment", 2e-3), ("contact_pressure", 5e-3)):
        other = np.interp(theta, arcs["theta"].values, arcs[name].values)
        scale = np.max(np.abs(circle[name].values))
        assert np.max(np.abs(other - circle[name].values)) < tol * scale, name


def test_layer_lines_and_a_drained_table_through_a_horseshoe():
    """A horseshoe cut by a layer line and a drained case's water table: each line meets the
    excavation at an interface station (on the true curve, at the line's depth), every ground
    triangle lies in the band its layer says, and the lining stays a balanced free body with the
    water on it."""
    from solver.ground.strata import band_layers, mesh_lines

    spec = CaseSpec.model_validate({**HORSESHOE, "ground": {"layers": [
        {"thickness": 23.0, "young": 5.0e7, "density": 1900.0}, {"thickness": 0.0, "young": 2.0e8}]},
        "water": {"table": 26.5, "lining": "drained"}})
    lines = mesh_lines(spec)
    assert lines == [23.0, 26.5]
    model = TunnelModel(spec)
    mesh = model.mesh
    ground = mesh.ground
    depth_of_station = -ground.p[1, mesh.interface.ground_node]
    for z in lines:
        assert np.min(np.abs(depth_of_station - z)) < 1e-9
    centroid = -ground.p[1, ground.t[:3]].mean(axis=0)
    edges = np.r_[0.0, lines, spec.geometry.height]
    band = np.searchsorted(edges, centroid) - 1
    assert np.array_equal(band_layers(spec)[band], mesh.ground_band)
    ds = run_case(spec, model=model)
    w, nx, ny = ds["weight"].values, ds["normal_x"].values, ds["normal_y"].values
    lam, s, water = ds["contact_pressure"].values, ds["shear_traction"].values, ds["water_pressure"].values
    fx = w * ((lam + water) * nx - s * ny)
    fy = w * ((lam + water) * ny + s * nx)
    N = ds["thrust"].values
    assert abs(N[0] + N[-1] + fx.sum()) < 1e-9 * N[0]
    assert abs(fy.sum() - float(ds["lining_weight"])) < 1e-9 * np.abs(fy).sum()
    assert float(ds["phreatic_drawdown"]) > 0.0


@pytest.mark.slow
def test_the_readme_horseshoe_example_reproduces():
    """README "Sections beyond the circle": `examples/horseshoe.json` to its printed digits: the found
    installation (R* 1.31, u* 0.47, λd 0.56), the thrust's range, the crown and invert rows, the side
    arc's peak moment (+31.1 at θ ≈ 117°) and the invert arc's least (−18.9 at θ ≈ 148°), η 0.43."""
    import json
    from pathlib import Path

    example = json.loads((Path(__file__).parents[2] / "examples" / "horseshoe.json").read_text())
    ds = run_case(CaseSpec.model_validate(example))
    found = json.loads(ds.attrs["installation"])
    assert (round(found["plastic_radius_ratio"], 2), round(float(ds["ldp_ratio"]), 2),
            round(float(ds["deconfinement"]), 2)) == (1.31, 0.47, 0.56)
    theta, N, M = ds["theta"].values, ds["thrust"].values / 1e3, ds["moment"].values / 1e3
    assert (round(N.min()), round(N.max())) == (944, 1013)
    crown, invert = int(np.argmin(np.abs(theta))), int(np.argmin(np.abs(theta - 180.0)))
    assert (round(N[crown]), round(M[crown], 1), round(N[invert]), round(M[invert], 1)) == (944, -6.1, 1013, -12.8)
    peak, least = int(np.argmax(M)), int(np.argmin(M))
    assert round(M[peak], 1) == 31.1 and abs(theta[peak] - 117.0) < 2.0
    assert round(M[least], 1) == -18.9 and abs(theta[least] - 148.0) < 2.0
    assert round(float(ds["max_utilization"]), 2) == 0.43
