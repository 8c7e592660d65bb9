"""Layered, water-bearing ground (SPEC §1.4): each test fails for a wrong answer.

Closed forms: the in-situ state of each layer (the discrete layered ground with its hole is
in exact equilibrium away from the excavation), Archimedes' buoyancy of the watertight lining
(fully and partly below the table), the half ring's horizontal equilibrium with the water on
its extrados, and the steady inflow of a deep drained tunnel under a constant head,
Q = 2πkH / arccosh(H/r).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from solver import CaseSpec
from solver.model import TunnelModel, model_key, shared_model
from solver.run import run_case
from solver.ground.strata import geostatic_state, strata
import solver.stages.loads as stage_fns

COARSE = {"interface_size": 0.1, "far_size": 4.0}
TWO_LAYERS = [{"thickness": 6.0, "young": 2.0e7, "density": 1900.0, "lateral_ratio": 0.6},
              {"thickness": 0.0, "young": 1.2e8, "density": 2100.0, "lateral_ratio": 0.45, "young_gradient": 2.0e6}]


def _spec(**parts) -> CaseSpec:
    return CaseSpec.model_validate({"mesh": COARSE, **parts})


@pytest.fixture(scope="module")
def watertight():
    spec = _spec(ground={"layers": TWO_LAYERS}, water={"table": 3.0})
    model = TunnelModel(spec)
    return model, model.solve(spec), run_case(spec, model=model)


def test_a_layer_line_through_the_tunnel_is_drawn_and_two_equal_layers_give_the_homogeneous_answer():
    one = run_case(_spec())
    for thickness in (6.0, 14.0):  # above the crown; through the tunnel at 14 m
        two = run_case(_spec(ground={"layers": [{"thickness": thickness}, {"thickness": 0.0}]}))
        for name in ("max_thrust", "max_abs_moment", "max_contact_pressure", "crown_settlement"):
            assert float(two[name]) == pytest.approx(float(one[name]), rel=5e-3), (thickness, name)
        layer = two["layer"].values[two["body"].values == 0]
        assert set(np.unique(layer)) == {0, 1}
    # the line through the tunnel meets the excavation at a node of both bodies
    theta = np.degrees(np.arccos((15.0 - 14.0) / 2.8))
    assert np.min(np.abs(two["theta"].values - theta)) < 1e-6


def test_layered_in_situ_state_is_in_exact_discrete_equilibrium(watertight):
    """The excavation load (what the in-situ state leaves unbalanced on the ground with its hole)
    vanishes at every free node off the excavation boundary: the layers' geostatic stress, with
    K0 jumping at the layer line and E growing with depth, and the water's effective release."""
    model, _, _ = watertight
    spec = model_spec = _spec(ground={"layers": TWO_LAYERS}, water={"table": 3.0})
    body = model.ground.body
    r = body.restrict(stage_fns.excavation_load(model, model_spec))
    node = body.node_of_dof()
    on_hole = np.isin(node, model.mesh.interface.ground_node)
    assert np.abs(r[~on_hole]).max() <= 1e-9 * np.abs(r).max()
    assert np.abs(r[on_hole]).max() > 1e3
    assert spec.water.table == 3.0


def test_far_from_the_tunnel_the_stored_state_is_each_layers_geostatic_one(watertight):
    model, _, ds = watertight
    spec = CaseSpec.model_validate(json.loads(ds.attrs["case_spec"]))
    faces = ds["face_nodes"].values
    x, y = ds["node_x"].values[faces].mean(axis=1), ds["node_y"].values[faces].mean(axis=1)
    far = (ds["body"].values == 0) & (np.hypot(x, y + spec.geometry.depth) > 12.0)
    layer = ds["layer"].values[far]
    assert set(np.unique(layer)) == {0, 1}
    st = geostatic_state(spec, strata(spec), -y[far], layer)
    # pore pressure: hydrostatic below the table, where no face straddles it
    clear = np.abs(-y[far] - 3.0) > 3.0
    np.testing.assert_allclose(ds["pore_pressure"].values[far][clear], st["pore"][clear], rtol=1e-9, atol=1e-6)
    scale = st["sigma_v"]
    for name, expected in (("effective_stress_yy", -st["effective_v"]), ("effective_stress_xx", -st["effective_h"]),
                           ("stress_yy", -st["sigma_v"]), ("stress_xx", -st["sigma_h"])):
        err = np.abs(ds[name].values[far][clear] - expected[clear]) / scale[clear]
        assert np.median(err) < 0.02, name
    # total = effective - pore everywhere in the ground
    g = ds["body"].values == 0
    np.testing.assert_allclose(ds["stress_xx"].values[g], ds["effective_stress_xx"].values[g] - ds["pore_pressure"].values[g],
                               rtol=0, atol=1e-6)


def test_watertight_buoyancy_is_archimedes_and_the_lining_balance_holds(watertight):
    model, sol, ds = watertight
    b = 2.8
    assert sol.water_uplift == pytest.approx(9810.0 * np.pi * b**2 / 2.0, rel=1e-6)
    balance = sol.F2 + float(np.sum(model.mesh.interface.normal[1] * model.mesh.interface.weight * sol.lam))
    assert abs(balance) <= 1e-8 * max(abs(sol.F2), sol.lining_weight)
    assert float(ds["lining_weight"]) == pytest.approx(sol.lining_weight)
    # water pressure on the extrados: hydrostatic at each interface node
    y = ds["interface_y"].values
    np.testing.assert_allclose(ds["water_pressure"].values, 9810.0 * (-y - 3.0), rtol=1e-12)


def test_a_table_through_the_lining_buoys_it_by_the_submerged_part_only():
    depth, b = 15.0, 2.8
    table = depth - 1.0  # 1 m above the axis
    spec = _spec(water={"table": table})
    sol = TunnelModel(spec).solve(spec)
    h = 1.0  # the table's height above the axis
    above = b**2 * np.arccos(h / b) - h * np.sqrt(b**2 - h**2)  # circular segment above the table
    assert sol.water_uplift == pytest.approx(9810.0 * (np.pi * b**2 - above) / 2.0, rel=1e-6)


def test_ring_equilibrium_with_water_on_the_extrados(watertight):
    """The half ring held at crown and invert: N(0) + N(180) equals the horizontal resultant of
    the contact pressure and the water pressure on its extrados (frictionless: no shear)."""
    model, sol, ds = watertight
    spec = CaseSpec.model_validate(json.loads(ds.attrs["case_spec"]))
    iface = model.mesh.interface
    contact = float(np.sum(iface.weight * sol.lam * -iface.normal[0]))
    water_x = stage_fns.water_on_lining(model, spec.water.table, spec.water.unit_weight)[model.lining.body.dof_of_node[0]].sum()
    thrust = ds["thrust"].values
    assert thrust[0] + thrust[-1] == pytest.approx(contact - water_x, rel=2e-3)
    assert -water_x > 0.3 * contact  # the water is a large part of the load


def test_a_light_lining_under_water_floats_up_against_the_crown():
    spec = _spec(lining={"density": 300.0}, water={"table": 0.0})
    sol = TunnelModel(spec).solve(spec)
    assert sol.F2 > 0 and sol.admissible
    assert sol.trials[0].theta == 0.0  # the search starts at the crown for an upward load
    assert sol.lam.min() >= 0


def test_drained_inflow_matches_the_deep_tunnel_closed_form():
    depth = 15.0
    spec = CaseSpec.model_validate({"geometry": {"width": 150.0, "height": 150.0, "depth": depth},
                                    "water": {"table": 0.0, "lining": "drained"},
                                    "mesh": {"interface_size": 0.1, "far_size": 10.0}})
    model = TunnelModel(spec)
    seep = stage_fns.seepage(model, spec)
    r, k = spec.geometry.hole_radius, 1e-6
    closed = 2 * np.pi * k * depth / np.arccosh(depth / r)
    # 1.8 %: the closed form holds the tunnel wall at one head, a drained wall is at zero pressure
    assert seep.inflow == pytest.approx(closed, rel=0.03)
    # twice the permeability, twice the flow
    spec2 = spec.model_copy(update={"ground": spec.ground.model_copy(update={"permeability": 2e-6})})
    assert stage_fns.seepage(model, spec2).inflow == pytest.approx(2 * seep.inflow, rel=1e-9)
    u0 = 9810.0 * np.maximum(-model.mesh.ground.p[1], 0.0)
    assert seep.pore.min() >= 0 and np.all(seep.pore <= u0 + 1e-6)
    assert np.all(seep.pore[model.mesh.interface.ground_node] == 0)


def test_drained_case_stores_inflow_and_no_water_on_the_lining():
    ds = run_case(_spec(water={"table": 3.0, "lining": "drained"}))
    assert float(ds["water_inflow"]) > 0
    assert np.all(ds["water_pressure"].values == 0)
    g = ds["body"].values == 0
    pore = ds["pore_pressure"].values[g]
    assert pore.min() >= 0 and pore.max() > 1e5
    assert float(ds["converged"]) == 1


def test_a_sweep_over_the_table_and_k0_reuses_one_model_bit_for_bit():
    base = _spec(ground={"layers": TWO_LAYERS}, water={"table": 3.0})
    others = [base.model_copy(update={"water": base.water.model_copy(update={"table": 8.0})}),
              base.model_copy(update={"loads": base.loads.model_copy(update={"lateral_ratio": 0.8})})]
    model = shared_model(base)
    # a drained case's table is a mesh line (SPEC §9.2): its own model, shared by its K0 sweep
    drained = base.model_copy(update={"water": base.water.model_copy(update={"lining": "drained"})})
    assert model_key(drained) != model_key(base)
    assert model_key(drained.model_copy(update={"loads": base.loads.model_copy(update={"lateral_ratio": 0.8})})) \
        == model_key(drained)
    for spec in others:
        assert model_key(spec) == model_key(base) and shared_model(spec) is model
        together, alone = run_case(spec, model=model), run_case(spec)
        for name in ("displacement_y", "stress_xx", "pore_pressure", "contact_pressure", "thrust"):
            np.testing.assert_array_equal(together[name].values, alone[name].values, err_msg=name)


@pytest.mark.parametrize("data, field", [
    ({"water": {"table": 2.0}, "excavation": {"method": "wished-in-place"}}, "water.table"),
    ({"water": {"table": 60.0}}, "water.table"),
    ({"water": {"table": 2.0, "lining": "leaky"}}, "water.lining"),
    ({"ground": {"layers": [{"thickness": 30.0}, {"thickness": 30.0}, {"thickness": 0}]}}, "ground.layers.1.thickness"),
    ({"ground": {"layers": [{"thickness": 6.0}, {"thickness": 0, "permeability": 5.0}]}}, "ground.layers.1.permeability"),
    ({"ground": {"layers": [{"thickness": 6.0, "lateral_ratio": -0.1}, {"thickness": 0}]}}, "ground.layers.0.lateral_ratio"),
])
def test_bad_water_and_layer_input_names_the_field(data, field):
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        CaseSpec.model_validate(data)


@pytest.mark.parametrize("parts, field", [
    ({"ground": {"density": 0.0}, "water": {"table": 0.0}}, "ground.density"),
    ({"ground": {"density": 900.0}, "water": {"table": 3.0}}, "ground.density"),
    ({"ground": {"model": "mohr-coulomb", "density": 500.0}, "water": {"table": 0.0}}, "ground.density"),
    ({"ground": {"layers": [{"thickness": 6.0}, {"density": 800.0}]}, "water": {"table": 2.0}},
     "ground.layers.1.density"),
])
def test_ground_lighter_than_water_below_the_table_is_refused(parts, field):
    """Effective vertical tension below the table (the skeleton would float) is refused for every
    ground, elastic or yielding, naming the layer's density; dry, the same ground is accepted."""
    from pydantic import ValidationError

    from solver.errors import field_errors

    with pytest.raises(ValidationError) as info:
        _spec(**parts)
    where, reason = field_errors(info.value)[0]
    assert where == field and "heavier than water" in reason and "(tension)" in reason
    _spec(**{k: v for k, v in parts.items() if k != "water"})  # dry: accepted
