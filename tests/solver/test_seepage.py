"""Unconfined steady seepage towards a drained lining (issue 37, SPEC §1.4, §9.2).

The phreatic surface is found by the solve (relative permeability k_r(ψ), Picard iterations):
checked are the Picard fixed point, the mass balance, pore pressures that are never negative
and zero above the phreatic surface, the table as a mesh line (the same answer as a ground split
into two identical layers there), and the confined closed form where nothing draws down.
"""
from __future__ import annotations

import numpy as np
import pytest

import solver.ground.water as water
import solver.stages.loads as stage_fns
from solver import CaseSpec
from solver.model import TunnelModel
from solver.run import run_case

DRAINED = {"water": {"table": 3.0, "lining": "drained"}}


@pytest.fixture(scope="module")
def drained():
    spec = CaseSpec.model_validate(DRAINED)
    model = TunnelModel(spec)
    return spec, model, stage_fns.seepage(model, spec)


def test_the_picard_iterate_is_a_fixed_point_and_the_water_balances(drained):
    spec, model, seep = drained
    sm = model.seepage_model(3.0, np.array([spec.ground.permeability]))
    assert 1 < seep.iterations < water.MAX_ITERATIONS
    # one more (unrelaxed) iteration from the answer: the saturated pressure heads move by under
    # 5 cm (0.5 kPa against up to 470 kPa; the phreatic surface's elements flip k_r), the inflow by 3e-4
    A = sm.matrix(sm.kr_of(seep.head))
    held = (A[sm.hole] @ seep.head) < 0
    again = sm._linear(A, held)
    psi, psi_again = np.maximum(seep.head - sm.y, 0), np.maximum(again - sm.y, 0)
    assert np.max(np.abs(psi_again - psi)) < 0.05
    assert -2.0 * float(np.sum((A[sm.hole] @ again)[held])) == pytest.approx(seep.inflow, rel=1e-3)
    # mass balance: what enters across the far field leaves into the tunnel
    assert seep.inflow > 0
    assert seep.outflow == pytest.approx(seep.inflow, rel=1e-6)
    # no water enters the ground from the tunnel: the drain's released nodes are dry
    psi_hole = seep.head[sm.hole] - sm.y[sm.hole]
    assert np.all(psi_hole <= 1e-9)


def test_pore_pressure_is_never_negative_and_zero_above_the_phreatic_surface(drained):
    spec, model, seep = drained
    y = model.mesh.ground.p[1]
    assert seep.pore.min() >= 0.0
    dry = seep.head < y
    assert dry.sum() > 100 and np.all(seep.pore[dry] == 0.0)
    # the drawdown: the ground above the crown, under the table before, is dry now
    x = model.mesh.ground.p[0]
    crown = spec.geometry.depth - spec.geometry.hole_radius
    above = (x < 0.5) & (-y > 3.5) & (-y < crown - 0.5)
    assert np.all(seep.pore[above] == 0.0)
    # the phreatic surface crosses the far side at the table and falls towards the tunnel
    ds = run_case(spec, model=model)
    depth = ds["phreatic_depth"].values
    assert depth[-1] == pytest.approx(3.0, abs=1e-3)
    assert np.all(np.diff(depth) <= 1e-9)
    assert float(ds["phreatic_drawdown"]) == pytest.approx(depth[0] - 3.0)
    assert float(ds["phreatic_drawdown"]) > crown - 3.0
    assert ds["pore_pressure"].values.min() >= 0.0


def test_the_table_is_a_mesh_line_two_identical_layers_there_give_the_same_answer():
    one = run_case(CaseSpec.model_validate(DRAINED))
    two = run_case(CaseSpec.model_validate({**DRAINED, "ground": {"layers": [{"thickness": 3.0},
                                                                             {"thickness": 0.0}]}}))
    assert float(one["water_inflow"]) == pytest.approx(float(two["water_inflow"]), rel=1e-12)
    for name in ("displacement_x", "displacement_y"):
        np.testing.assert_allclose(one[name].values, two[name].values, rtol=0,
                                   atol=1e-10 * np.abs(two[name].values).max())
    # the table meets the model's side at a node: the hydrostatic kink is on element edges
    y = np.unique(np.round(one["node_y"].values, 9))
    assert np.any(np.abs(y + 3.0) < 1e-9)


def test_without_drawdown_the_inflow_is_the_confined_closed_form():
    """A table at the surface is held there (ponded ground): the pressure is ≥ 0 everywhere, so the
    unconfined solve is the confined one and Q = 2πkH / arccosh(H/r) within 3 % (measured 1.8 %):
    the closed form holds the wall at one head, a drained wall is at zero pressure (its head
    varies by ±r), and the model ends 150 m away."""
    depth = 15.0
    spec = CaseSpec.model_validate({"geometry": {"width": 150.0, "height": 150.0, "depth": depth},
                                    "water": {"table": 0.0, "lining": "drained"},
                                    "mesh": {"interface_size": 0.1, "far_size": 10.0}})
    model = TunnelModel(spec)
    seep = stage_fns.seepage(model, spec)
    r, k = spec.geometry.hole_radius, 1e-6
    closed = 2 * np.pi * k * depth / np.arccosh(depth / r)
    assert seep.inflow == pytest.approx(closed, rel=0.03)
    assert seep.iterations == 2  # nothing dries: k_r is 1 everywhere from the first solve
    assert np.all(seep.head - model.mesh.ground.p[1] >= -1e-9)
    assert seep.outflow == pytest.approx(seep.inflow, rel=1e-9)


def test_the_phreatic_sampler_finds_a_sloping_water_surface_exactly(drained):
    """A head field linear in x and y (P2 holds it exactly) has its phreatic surface, ψ = h - y = 0,
    on the straight line z = a + b x; the sampler, built once from the mesh, finds it at every vertical
    clear of the excavation to round-off (linear between samples is exact for ψ linear in z), for any
    such field; and a field wet to the surface gives depth 0, one dry to the bottom NaN."""
    spec, model, _ = drained
    mesh, g = model.mesh.ground, spec.geometry
    x = np.linspace(0.0, 0.5 * g.width, 23)
    x = x[np.abs(x - model.mesh.center[0]) > g.hole_radius + 1.0]  # verticals clear of the hole
    sampler = water.phreatic_sampler(mesh, x, height=g.height, center=model.mesh.center, radius=g.hole_radius,
                                     step=0.5 * spec.mesh.interface_size)
    px, py = mesh.p
    for a, b in ((2.0, 0.1), (7.5, -0.05), (0.3, 0.0)):
        head = -a - b * px  # ψ = h - y vanishes at y = -a - b x
        np.testing.assert_allclose(sampler.depth(head), a + b * x, rtol=0, atol=1e-9)
    assert np.all(sampler.depth(np.full(px.size, 1.0)) == 0.0)          # ψ > 0 at the surface
    assert np.all(np.isnan(sampler.depth(py - 1.0)))                     # ψ = -1 everywhere: dry
