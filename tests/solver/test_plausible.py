"""Mistakes that used to pass silently (issue 39, item 10): implausible values warn, unknown fields
are named with the closest known one."""
from __future__ import annotations

import json

import pytest
from pydantic import ValidationError

from solver import CaseSpec, run_case
from solver.errors import field_errors
from solver.spec.plausible import PLAUSIBLE, plausibility_warnings

COARSE = {"interface_size": 0.25, "far_size": 8.0}


def test_default_case_is_plausible():
    assert plausibility_warnings(CaseSpec()) == []


@pytest.mark.parametrize("case, field, words", [
    ({"ground": {"density": 20.0}}, "ground.density", "kN/m³ typed as a density"),
    ({"loads": {"surface_load": 100.0}}, "loads.surface_load", "kPa typed as Pa"),
    ({"lining": {"density": 24.0}}, "lining.density", "kN/m³"),
    ({"ground": {"young": 5e5}}, "ground.young", "MPa or kPa"),
    ({"ground": {"layers": [{"thickness": 8.0, "density": 19.0}, {}]}}, "ground.layers.0.density", "kg/m³"),
    ({"settlement": {"volume_loss": 0.1}}, "settlement.volume_loss", "fraction"),
])
def test_implausible_values_warn_naming_the_field(case, field, words):
    spec = CaseSpec.model_validate(case)  # accepted: a warning, not a refusal
    warnings = plausibility_warnings(spec)
    assert len(warnings) == 1 and warnings[0].startswith(field + ":") and words in warnings[0]


def test_a_hoek_brown_grounds_own_tension_cut_off_is_not_taken_for_a_slip():
    """Weak rock's default cut-off s σci / m_b is tens of Pa: filled in, not typed, so no warning (before:
    "ground.tensile_strength: 0.0872 kPa … kPa typed as Pa?" on every such case); a typed 50 Pa still warns."""
    rock = {"model": "hoek-brown", "young": 2.3e8, "ucs": 3.57e5, "gsi": 32.9, "mi": 14.2, "disturbance": 0.44}
    spec = CaseSpec.model_validate({"ground": rock, "loads": {"lateral_ratio": 1.0}})
    assert spec.ground.tensile_strength < 100.0  # below the plausible range's floor
    assert plausibility_warnings(spec) == []
    typed = CaseSpec.model_validate({"ground": {**rock, "tensile_strength": 50.0}, "loads": {"lateral_ratio": 1.0}})
    assert [w.split(":")[0] for w in plausibility_warnings(typed)] == ["ground.tensile_strength"]


def test_zero_is_plausible_where_the_input_may_be_absent():
    spec = CaseSpec.model_validate({"loads": {"surface_load": 0.0}, "design": {"reinforcement_area": 0.0}})
    assert plausibility_warnings(spec) == []
    assert all(r.low < r.high for r in PLAUSIBLE.values())


def test_density_typed_in_kn_per_m3_warns_in_the_result():
    ds = run_case(CaseSpec.model_validate({"mesh": COARSE, "ground": {"density": 20.0}}))
    warnings = json.loads(ds.attrs["warnings"])
    assert any(w.startswith("ground.density: 20 kg/m³") for w in warnings)


@pytest.mark.parametrize("case, field, suggestion", [
    ({"ground": {"densty": 2000.0}}, "ground.densty", "density"),
    ({"geomtry": {"depth": 20.0}}, "geomtry", "geometry"),
    ({"ground": {"layers": [{"thickness": 5.0, "yung": 1e7}, {}]}}, "ground.layers.0.yung", "young"),
    # these two were dropped silently: a dry case and a monolithic ring ignore their other fields
    ({"water": {"tabel": 5.0}}, "water.tabel", "table"),
    ({"lining": {"joints": {"cont": 6}}}, "lining.joints.cont", "count"),
    ({"design": {"crack_limit": 2e-4}}, "design.crack_limit", "crack_width_limit"),
])
def test_unknown_fields_say_did_you_mean(case, field, suggestion):
    with pytest.raises(ValidationError) as info:
        CaseSpec.model_validate(case)
    assert field_errors(info.value) == [(field, f"unknown field; did you mean {suggestion!r}?")]


def test_unknown_field_without_a_close_one():
    with pytest.raises(ValidationError) as info:
        CaseSpec.model_validate({"ground": {"zzzz": 1.0}})
    assert field_errors(info.value) == [("ground.zzzz", "unknown field")]


def test_ground_near_failure_in_situ_is_said_and_names_the_field():
    """The relative shear stress of the in-situ state at the tunnel's axis (τ over the radius of the circle
    whose centre touches the Mohr–Coulomb line): at 0.85 or more the ground is near failure before the
    excavation. Of issue 36's seeded samples (weak and wide, 48 cases) it names exactly the four that cost
    90–210 elastic ones; a layer's own K0 is named as its field; elastic or strong ground says nothing."""
    import math

    from bench.ground import sample_cases

    def named(case):
        return [w.split(":")[0] for w in plausibility_warnings(CaseSpec.model_validate(case))
                if "shear strength" in w]

    near = {"ground": {"model": "mohr-coulomb", "young": 4.31e7, "cohesion": 6992.2, "friction_angle": 23.91,
                       "dilatancy": 2.35}, "loads": {"lateral_ratio": 0.446}, "excavation": {"deconfinement": 0.485}}
    assert named(near) == ["loads.lateral_ratio"]
    text = plausibility_warnings(CaseSpec.model_validate(near))[0]
    sv = 2000.0 * 9.81 * 15.0 + CaseSpec().loads.surface_load  # the default surcharge too
    phi = math.radians(23.91)
    expected = 0.5 * (1 - 0.446) * sv / (6992.2 * math.cos(phi) + 0.5 * (1 + 0.446) * sv * math.sin(phi))
    assert f"mobilizes {expected:.0%}" in text and "15 m deep" in text
    assert named({**near, "ground": {**near["ground"], "cohesion": 3.0e4}}) == []  # stronger: not near
    assert named({"loads": {"lateral_ratio": 0.446}}) == []  # elastic ground
    layered = {"ground": {**near["ground"], "layers": [{"thickness": 5.0}, {"lateral_ratio": 0.446}]}}
    assert named(layered) == ["ground.layers.1.lateral_ratio"]
    flagged = []
    for family in ("weak", "wide"):
        for i, case in enumerate(sample_cases(24, family)):
            try:
                if named(case):
                    flagged.append((family, i))
            except ValidationError:
                pass
    assert flagged == [("weak", 0), ("weak", 3), ("weak", 4), ("wide", 16)]
