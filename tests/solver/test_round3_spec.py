"""The third round's case fields (SPEC §1.4-§1.6, §2): ids of older cases kept, one id per
physical case, every mistake named by its field, and the in-situ state of the strata."""
from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from solver import CaseSpec
from solver.errors import field_errors
from solver.ground.strata import geostatic_state, layer_at, strata

#: Ids of cases computed before the third round (main at a9d4fa0): they must not change.
OLD_IDS = {
    "{}": "508fa556c92d5dfc",
    '{"geometry": {"thickness": 0.25}}': "b40288c84f624ac5",
    '{"interface": {"model": "coulomb", "friction": 0.3}}': "eee9571a068cccf8",
    '{"excavation": {"method": "wished-in-place"}}': "e9b9b34f1543ebe8",
}


@pytest.mark.parametrize("text, case_id", OLD_IDS.items())
def test_cases_without_round3_fields_keep_their_ids(text, case_id):
    spec = CaseSpec.model_validate_json(text)
    assert spec.case_id == case_id
    assert "water" not in spec.canonical_json() and "layers" not in spec.canonical_json()


@pytest.mark.parametrize("extra", [
    {"ground": {"cohesion": 5e3, "friction_angle": 20.0}},          # elastic ground ignores strength
    {"water": {"unit_weight": 10000.0, "lining": "drained"}},      # dry ground ignores the water's fields
    {"ground": {"permeability": 1e-4}},                            # only a drained lining seeps
    {"solver": {"load_steps": 40}},                                # an elastic case has one step
    {"solver": {"plastic_tolerance": 1e-5}},                       # ... and no plastic iteration
    {"lining": {"joints": {"count": 0, "offset": 30.0}}},          # a monolithic ring has no joints
    {"water": {"table": None}},
])
def test_ignored_values_do_not_split_a_case(extra):
    assert CaseSpec.model_validate(extra).case_id == CaseSpec().case_id


def test_layers_are_filled_and_a_stated_default_is_the_same_case():
    two = {"ground": {"young": 3e7, "layers": [{"thickness": 6.0, "young": 2e7}, {"density": 1900.0}]}}
    spec = CaseSpec.model_validate(two)
    top, bottom = spec.ground.layers
    assert (top.young, top.density, bottom.young, bottom.density) == (2e7, 2000.0, 3e7, 1900.0)
    assert bottom.thickness == 0.0 and top.lateral_ratio is None
    same = {"ground": {"young": 3e7, "layers": [{"thickness": 6.0, "young": 2e7, "lateral_ratio": 0.5},
                                                  {"density": 1900.0, "young": 3e7, "thickness": 12.0}]}}
    assert CaseSpec.model_validate(same).case_id == spec.case_id
    assert CaseSpec.model_validate({"lining": {"joints": {"count": 6, "contact_height": 0.3}}}).case_id == \
        CaseSpec.model_validate({"lining": {"joints": {"count": 6}}}).case_id


@pytest.mark.parametrize("data, field", [
    ({"ground": {"layers": [{"thickness": 0.0}, {}]}}, "ground.layers.0.thickness"),
    ({"ground": {"layers": [{"thickness": 30.0}, {"thickness": 25.0}, {}]}}, "ground.layers.1.thickness"),
    ({"ground": {"layers": [{"thickness": 5.0}, {"young": -1.0}]}}, "ground.layers.1.young"),
    ({"ground": {"layers": [{"thickness": 5.0}, {"lateral_ratio": 11.0}]}}, "ground.layers.1.lateral_ratio"),
    ({"ground": {"layers": [{"thickness": 5.0, "permeability": 1.0}, {}]}}, "ground.layers.0.permeability"),
    ({"water": {"table": 50.0}}, "water.table"),
    ({"water": {"table": 3.0, "lining": "leaky"}}, "water.lining"),
    ({"ground": {"model": "mohr-coulomb", "cohesion": 1e4, "dilatancy": 35.0}}, "ground.dilatancy"),
    ({"ground": {"model": "mohr-coulomb", "cohesion": 1e3, "friction_angle": 30.0, "tensile_strength": 1e4}},
     "ground.tensile_strength"),
    ({"ground": {"layers": [{"thickness": 5.0, "model": "mohr-coulomb", "friction_angle": 30.0,
                             "lateral_ratio": 0.1}, {}]}}, "ground.layers.0.lateral_ratio"),
    ({"ground": {"model": "mohr-coulomb", "friction_angle": 30.0}, "loads": {"lateral_ratio": 0.2}},
     "loads.lateral_ratio"),
    ({"lining": {"joints": {"count": 6, "offset": 10.0}}}, "lining.joints.offset"),
    ({"lining": {"joints": {"count": 2}}}, "lining.joints.count"),
    ({"lining": {"joints": {"count": 6, "contact_height": 0.4}}}, "lining.joints.contact_height"),
    ({"lining": {"joints": {"count": 6, "contact_height": 0.0}}}, "lining.joints.contact_height"),
    ({"lining": {"joints": {"count": 6}}, "solver": {"bolt": 90.0}}, "solver.bolt"),
])
def test_mistakes_are_named_by_their_field(data, field):
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate(data)
    assert [f for f, _ in field_errors(err.value)] == [field]


@pytest.mark.parametrize("count", [7, 11, 13])
def test_a_typed_half_joint_spacing_is_the_symmetric_pattern(count):
    """180/n as a person types it (six significant digits, as the refusal prints it) is the
    symmetric pattern: accepted, stored as 180/n, the same case and id as 180/n itself; a value
    off by more than the typing's rounding is still refused naming the field."""
    exact = CaseSpec.model_validate({"lining": {"joints": {"count": count, "offset": 180.0 / count}}})
    typed = CaseSpec.model_validate({"lining": {"joints": {"count": count, "offset": float(f"{180.0 / count:.6g}")}}})
    assert typed.lining.joints.offset == 180.0 / count and typed.case_id == exact.case_id
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate({"lining": {"joints": {"count": count, "offset": round(180.0 / count, 2)}}})
    assert [f for f, _ in field_errors(err.value)] == ["lining.joints.offset"]


def test_admissible_k0_of_a_cohesionless_layer_is_between_ka_and_kp():
    phi = 30.0
    ka, kp = (1 - np.sin(np.radians(phi))) / (1 + np.sin(np.radians(phi))), 1 / ((1 - 0.5) / 1.5)
    for k0, ok in ((ka * 1.01, True), (ka * 0.99, False), (kp * 0.99, True), (kp * 1.01, False)):
        data = {"ground": {"model": "mohr-coulomb", "friction_angle": phi}, "loads": {"lateral_ratio": k0}}
        if ok:
            CaseSpec.model_validate(data)
        else:
            with pytest.raises(ValidationError, match="lateral_ratio"):
                CaseSpec.model_validate(data)


def test_geostatic_state_is_built_layer_by_layer_in_effective_stress():
    spec = CaseSpec.model_validate({
        "loads": {"surface_load": 2e4, "lateral_ratio": 0.5},
        "ground": {"layers": [{"thickness": 8.0, "density": 1800.0, "lateral_ratio": 0.7},
                              {"density": 2100.0}]},
        "water": {"table": 3.0}})
    layers = strata(spec)
    assert [(s.top, s.bottom, s.k0) for s in layers] == [(0.0, 8.0, 0.7), (8.0, 50.0, 0.5)]
    z = np.array([0.0, 3.0, 8.0, 20.0])
    st = geostatic_state(spec, layers, z)
    g, gw = 9.81, 9810.0
    sv = np.array([2e4, 2e4 + 1800 * g * 3, 2e4 + 1800 * g * 8, 2e4 + 1800 * g * 8 + 2100 * g * 12])
    u = gw * np.maximum(z - 3.0, 0)
    np.testing.assert_allclose(st["sigma_v"], sv, rtol=1e-14)
    np.testing.assert_allclose(st["pore"], u, rtol=1e-14)
    np.testing.assert_allclose(st["effective_h"], np.array([0.7, 0.7, 0.5, 0.5]) * (sv - u), rtol=1e-14)
    np.testing.assert_allclose(st["sigma_h"], st["effective_h"] + u, rtol=1e-14)
    assert list(layer_at(layers, z)) == [0, 0, 1, 1]
