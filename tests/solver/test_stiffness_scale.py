"""A sweep over the ground's stiffness shares one model: the ground's stiffness is linear in its
moduli, so a case whose moduli are the model's times α solves on the model's factorization with
K⁺ / α. Exact: every result equals a model built for the case itself."""
from __future__ import annotations

import numpy as np
import pytest

from solver import CaseSpec
from solver.results.dataset import to_dataset
from solver.model import TunnelModel, model_key

COARSE = {"mesh": {"interface_size": 0.15, "far_size": 6.0}}
LAYERS = [{"thickness": 6.0, "young": 2.0e7, "density": 1900.0, "young_gradient": 1.0e6},
          {"thickness": 0.0, "young": 1.2e8, "density": 2100.0}]
FIELDS = ("max_thrust", "max_abs_moment", "max_contact_pressure", "crown_settlement", "contact_extent",
          "max_utilization", "ground_loss", "plastic_area")


def _spec(scale: float, **extra) -> CaseSpec:
    base = {**COARSE, **extra}
    if "ground" in base and "layers" in base["ground"]:
        layers = [{**l, "young": l["young"] * scale, **({"young_gradient": l["young_gradient"] * scale}
                                                        if "young_gradient" in l else {})}
                  for l in base["ground"]["layers"]]
        base["ground"] = {**base["ground"], "layers": layers}
    else:
        base["ground"] = {**base.get("ground", {}), "young": 5.0e7 * scale}
    return CaseSpec.model_validate(base)


@pytest.mark.parametrize("extra", [
    {},
    {"interface": {"model": "coulomb", "friction": 0.4}},
    {"interface": {"model": "bonded"}, "water": {"table": 3.0}},
    {"ground": {"layers": LAYERS}},
    {"ground": {"model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 28.0, "tensile_strength": 1.0e4}},
], ids=["frictionless", "coulomb", "bonded-water", "layers", "mohr-coulomb"])
def test_a_case_on_a_scaled_model_is_the_case_on_its_own(extra):
    shared = TunnelModel(_spec(1.0, **extra))
    for scale in (0.4, 2.5):
        spec = _spec(scale, **extra)
        assert model_key(spec) == shared.key  # one model serves them
        on_shared = to_dataset(shared, shared.solve(spec), software_version="test")
        own_model = TunnelModel(spec)
        own = to_dataset(own_model, own_model.solve(spec), software_version="test")
        for name in FIELDS:
            if name in own:
                assert float(on_shared[name]) == pytest.approx(float(own[name]), rel=1e-8, abs=1e-12), (name, scale)
        for name in ("displacement_x", "contact_pressure", "thrust", "moment", "effective_stress_xx"):
            np.testing.assert_allclose(on_shared[name].values, own[name].values, rtol=1e-7,
                                       atol=1e-9 * float(np.max(np.abs(own[name].values))), err_msg=name)


def test_different_stiffness_ratios_do_not_share_a_model():
    a = CaseSpec.model_validate({**COARSE, "ground": {"layers": LAYERS}})
    other = [dict(LAYERS[0]), {**LAYERS[1], "young": 2.4e8}]
    b = CaseSpec.model_validate({**COARSE, "ground": {"layers": other}})
    assert model_key(a) != model_key(b)
    assert model_key(CaseSpec.model_validate({**COARSE, "lining": {"young": 2e10}})) != model_key(
        CaseSpec.model_validate(COARSE))
