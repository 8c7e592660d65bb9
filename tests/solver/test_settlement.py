"""Settlements that mean something (SPEC §3): ground loss, the Gaussian trough, the FE surface's
honesty warnings."""
from __future__ import annotations

import json

import numpy as np
import pytest

from solver import CaseSpec
from solver.model import TunnelModel
from solver.run import run_case
from solver.results.settlement import gaussian_trough, ground_loss, with_trough_width

COARSE = {"interface_size": 0.1, "far_size": 4.0}


def test_ground_loss_of_a_uniform_convergence_and_of_a_rigid_translation():
    spec = CaseSpec.model_validate({"mesh": COARSE})
    model = TunnelModel(spec)
    iface, p = model.mesh.interface, model.mesh.ground.p
    r = spec.geometry.hole_radius
    delta = 1e-3
    u = np.zeros_like(p)
    u[:, iface.ground_node] = delta * iface.normal  # every wall point moves delta towards the axis
    assert ground_loss(u, iface.ground_node, iface.normal, iface.weight, r) == pytest.approx(2 * delta / r, rel=1e-6)
    lift = np.zeros_like(p)
    lift[1] = 0.01
    assert abs(ground_loss(lift, iface.ground_node, iface.normal, iface.weight, r)) < 1e-9


def test_gaussian_trough_holds_the_ground_loss():
    x = np.linspace(-200.0, 200.0, 40001)
    s, s_max = gaussian_trough(x, 0.01, 3.0, 20.0, 0.5)
    assert np.trapezoid(s, x) == pytest.approx(0.01 * np.pi * 9.0, rel=1e-9)
    assert s.max() == pytest.approx(s_max) and s_max == pytest.approx(0.01 * np.pi * 9.0 / (np.sqrt(2 * np.pi) * 10.0))
    # half the width factor, the same volume in a trough twice as deep
    assert gaussian_trough(x, 0.01, 3.0, 20.0, 0.25)[1] == pytest.approx(2 * s_max)


@pytest.fixture(scope="module")
def two_sizes():
    small = run_case(CaseSpec.model_validate({"mesh": COARSE}))
    large = run_case(CaseSpec.model_validate({"geometry": {"width": 160.0, "height": 200.0},
                                              "mesh": {"interface_size": 0.1, "far_size": 10.0}}))
    return small, large


def test_ground_loss_does_not_depend_on_the_models_walls_but_the_fe_surface_does(two_sizes):
    small, large = two_sizes
    assert float(large["ground_loss"]) == pytest.approx(float(small["ground_loss"]), rel=0.03)
    assert float(small["ground_loss"]) > 0
    # the FE surface above the tunnel settles in the small model and heaves in the large one
    assert float(small["axis_settlement"]) > 0 > float(large["axis_settlement"])
    assert float(large["max_surface_heave"]) >= -float(large["axis_settlement"]) > 0
    warnings = json.loads(large.attrs["warnings"])
    assert any("heaves" in w and "Gaussian trough" in w for w in warnings)
    assert not any("heaves" in w for w in json.loads(small.attrs["warnings"]))


def test_stored_gaussian_trough_and_its_width_factor(two_sizes):
    small, _ = two_sizes
    x, g = small["surface_x"].values, small["gaussian_settlement"].values
    r = 2.8
    volume = 2 * np.trapezoid(g, x)  # both halves, truncated at the model's side (40 m = 5.3 i)
    assert volume == pytest.approx(float(small["ground_loss"]) * np.pi * r**2, rel=2e-3)
    assert float(small["gaussian_max_settlement"]) == pytest.approx(g[0])
    assert small["gaussian_settlement"].attrs["trough_width_factor"] == 0.5
    sand = with_trough_width(small, 0.3)
    assert float(sand["gaussian_max_settlement"]) == pytest.approx(float(small["gaussian_max_settlement"]) * 0.5 / 0.3)
    with pytest.raises(ValueError, match="trough_width_factor"):
        with_trough_width(small, 0.0)
