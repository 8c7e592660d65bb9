"""The face's distance instead of a guessed deconfinement (SPEC §9.5): the longitudinal
displacement profiles, λd found on the case's own ground reaction curve, and the case's record."""
from __future__ import annotations

import json
import math

import pytest
from pydantic import ValidationError

from solver import CaseSpec, run_case
from solver.errors import field_errors
from solver.ground import ldp
from solver.stages.face import invert_curve

# Each profile's value written out by hand at X* = -2, 0, 1, 4 (R* = 2 for Vlachopoulos &
# Diederichs, ν = 0.25 for Unlu & Gercek), from the published formulas, not the module's code.
_E = math.e
_VD_FACE = _E ** -0.3 / 3  # u0* = exp(-0.15 R*)/3, R* = 2
_UG_FACE = 0.22 * 0.25 + 0.19  # 0.245
_UG_B = 0.39 * 0.25 + 0.65  # 0.7475
EXPECTED = {
    "vlachopoulos-diederichs": {-2: _VD_FACE * _E ** -2, 0: _VD_FACE, 1: 1 - (1 - _VD_FACE) * _E ** -0.75,
                                4: 1 - (1 - _VD_FACE) * _E ** -3},
    "panet": {0: 0.25, 1: 0.25 + 0.75 * (1 - (0.75 / 1.75) ** 2), 4: 0.25 + 0.75 * (1 - (0.75 / 4.75) ** 2)},
    "hoek": {-2: (1 + _E ** (2 / 1.1)) ** -1.7, 0: 2 ** -1.7, 1: (1 + _E ** (-1 / 1.1)) ** -1.7,
             4: (1 + _E ** (-4 / 1.1)) ** -1.7},
    "unlu-gercek": {-2: _UG_FACE * _E ** (-2 * (0.73 * 0.25 + 0.81)), 0: _UG_FACE,
                    1: _UG_FACE + (0.81 - 0.055) * (1 - (_UG_B / (_UG_B + 1)) ** 2),
                    4: _UG_FACE + (0.81 - 0.055) * (1 - (_UG_B / (_UG_B + 4)) ** 2)},
}


@pytest.mark.parametrize("profile", ldp.PROFILES)
@pytest.mark.parametrize("x", [-2, 0, 1, 4])
def test_closed_forms(profile, x):
    if x not in EXPECTED[profile]:  # Panet's profile starts at the face
        with pytest.raises(ValueError, match="behind the face"):
            ldp.ldp_ratio(profile, x)
        return
    got = ldp.ldp_ratio(profile, float(x), plastic_ratio=2.0, poisson=0.25)
    assert got == pytest.approx(EXPECTED[profile][x], rel=1e-12)


def test_profiles_rise_to_one():
    """Every profile grows with the distance behind the face and tends to the full convergence."""
    for profile in ldp.PROFILES:
        values = [ldp.ldp_ratio(profile, x) for x in (0.0, 0.5, 1.0, 2.0, 5.0, 50.0)]
        assert all(b > a for a, b in zip(values, values[1:]))
        assert 0.97 < values[-1] <= 1.0
    # a larger plastic zone delays the convergence (Vlachopoulos & Diederichs)
    assert ldp.vlachopoulos_diederichs(1.0, 3.0) < ldp.vlachopoulos_diederichs(1.0, 1.0)


def test_invert_curve():
    # a straight line is inverted exactly; a convex curve between its points monotonically
    assert invert_curve([(0.5, 1.0), (1.0, 2.0)], 1.5) == pytest.approx(0.75)
    curve = [(f, f**3 + f) for f in (0.25, 0.5, 0.75, 1.0)]
    found = invert_curve(curve, 0.8**3 + 0.8)
    assert found == pytest.approx(0.8, abs=2e-3)


def test_spec_refuses_both_and_keeps_ids():
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate({"excavation": {"face_distance": 1.5, "deconfinement": 0.3}})
    assert field_errors(err.value)[0][0] == "excavation.deconfinement"
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate({"excavation": {"face_distance": 1.5, "method": "wished-in-place"}})
    assert field_errors(err.value)[0][0] == "excavation.face_distance"
    spec = CaseSpec.model_validate({"excavation": {"face_distance": 1.5}})
    data = json.loads(spec.canonical_json())
    assert data["excavation"] == {"face_distance": 1.5, "method": "deconfinement"}
    assert CaseSpec.model_validate_json(spec.canonical_json()).case_id == spec.case_id
    assert CaseSpec.model_validate({"excavation": {"face_distance": 1.5, "ldp": "hoek"}}).case_id != spec.case_id
    # a profile without a face distance is ignored: the case is the default one, with its id
    assert CaseSpec.model_validate({"excavation": {"ldp": "panet"}}).case_id == CaseSpec().case_id
    assert "face_distance" not in CaseSpec().canonical_json()


def test_elastic_deconfinement_is_the_profile():
    """Elastic ground: the ground reaction curve is a straight line, so λd = u*(x)."""
    spec = CaseSpec.model_validate({"excavation": {"face_distance": 2.8, "ldp": "panet"},
                                    "mesh": {"interface_size": 0.2}})
    ds = run_case(spec)
    expected = 0.25 + 0.75 * (1 - (0.75 / (0.75 + 2.8 / 2.8)) ** 2)  # X* = x / (b + g0) = 1
    assert float(ds["ldp_ratio"]) == pytest.approx(expected, rel=1e-12)
    assert float(ds["deconfinement"]) == pytest.approx(expected, rel=1e-12)
    assert ds.attrs["case_id"] == spec.case_id
    assert "deconfinement" not in json.loads(ds.attrs["case_spec"])["excavation"]
    # the same case with that λd given is the same solution
    given = CaseSpec.model_validate({"excavation": {"deconfinement": expected}, "mesh": {"interface_size": 0.2}})
    other = run_case(given)
    assert float(other["max_abs_moment"]) == pytest.approx(float(ds["max_abs_moment"]), rel=1e-9)
    assert float(other["ldp_ratio"]) == 0.0  # no profile used


MC = {"ground": {"model": "mohr-coulomb", "cohesion": 1.0e5, "friction_angle": 30.0, "dilatancy": 10.0},
      "loads": {"lateral_ratio": 1.0}, "mesh": {"interface_size": 0.2}}


@pytest.mark.slow
def test_yielding_ground_reaches_the_profiles_convergence():
    """Mohr–Coulomb ground: the stage-1 wall convergence at the found λd is u*(x)·u_max, u_max
    taken from a separate case released fully before its lining is placed."""
    full = run_case(CaseSpec.model_validate({**MC, "excavation": {"deconfinement": 1.0}}))
    u_max = json.loads(full.attrs["ground_reaction_curve"])[-1]["wall_convergence_m"]
    ds = run_case(CaseSpec.model_validate({**MC, "excavation": {"face_distance": 2.8}}))
    found = json.loads(ds.attrs["installation"])
    assert found["plastic_radius_ratio"] > 1.1  # a real plastic zone enters the profile
    assert found["full_release_convergence_m"] == pytest.approx(u_max, rel=1e-6)
    ratio = ldp.vlachopoulos_diederichs(1.0, found["plastic_radius_ratio"])
    assert float(ds["ldp_ratio"]) == pytest.approx(ratio, rel=1e-12)
    reached = json.loads(ds.attrs["ground_reaction_curve"])[-1]
    assert reached["released"] == pytest.approx(float(ds["deconfinement"]), rel=1e-12)
    assert reached["wall_convergence_m"] == pytest.approx(ratio * u_max, rel=0.01)
    assert float(ds["deconfinement"]) > ratio  # the curve bends: more convergence per share released


def test_a_built_model_solves_the_full_release_once():
    """Cases on one built model that differ only in their face distance or profile share one
    full-release solve (a sweep over the construction sequence), with the answer of a fresh model."""
    from solver.model import TunnelModel

    near = CaseSpec.model_validate({**MC, "excavation": {"face_distance": 1.0}})
    far = CaseSpec.model_validate({**MC, "excavation": {"face_distance": 3.0, "ldp": "hoek"}})
    model = TunnelModel(near)
    run_case(near, model=model)
    shared = run_case(far, model=model)
    assert len(model.kept.values("release")) == 1
    alone = run_case(far)
    assert float(shared["deconfinement"]) == float(alone["deconfinement"])
    assert float(shared["max_abs_moment"]) == float(alone["max_abs_moment"])


@pytest.mark.slow
def test_the_readme_face_distance_row_reproduces():
    """README "The face's distance": the example sweep's 1.5 m row (u*, λd, N, M, λ, yielded area) and
    R* = 1.20 R at full release, to their printed digits (the table had gone stale: R* was 1.35 R)."""
    from pathlib import Path

    example = json.loads((Path(__file__).parents[2] / "examples" / "face-distance-sweep.json").read_text())
    ds = run_case(CaseSpec.model_validate(example["base"]))  # its face distance: 1.5 m
    installation = json.loads(ds.attrs["installation"])
    assert round(installation["plastic_radius_ratio"], 2) == 1.20
    assert round(1e3 * installation["full_release_convergence_m"], 1) == 29.9
    assert (round(float(ds["ldp_ratio"]), 3), round(float(ds["deconfinement"]), 3)) == (0.636, 0.767)
    assert (round(float(ds["max_thrust"]) / 1e3), round(float(ds["max_abs_moment"]) / 1e3, 1),
            round(float(ds["max_contact_pressure"]) / 1e3)) == (223, 12.8, 94)
    assert float(ds["plastic_area"]) == pytest.approx(1.58, rel=0.03)  # the points at yield: the stop test's reach


def test_a_full_release_that_does_not_converge_is_not_called_a_collapse(monkeypatch):
    """The full release can fail by a collapse of the ground or by a stalled iteration (the stage-1
    message says which, with what the ground held): the face distance's error names the field and
    both ways out, and does not assert a collapse (it did, for a stall at 1.03 times the tolerance)."""
    import solver.stages.face as face
    from solver.errors import NotConvergedError

    def stalls(*args, **kwargs):
        raise NotConvergedError("solver.load_steps: the yielding ground did not reach equilibrium in stage 1, "
                                "increment 10 of 10 (out-of-balance force 72.3 N/m > 70.4 ...)")

    monkeypatch.setattr(face, "release_unsupported", stalls)
    with pytest.raises(NotConvergedError) as info:
        face._full_release(None, CaseSpec(), None)
    text = str(info.value)
    assert text.startswith("excavation.face_distance: the full release") and "did not reach equilibrium" in text
    assert "collapses" not in text and "solver.plastic_tolerance" in text and "72.3 N/m > 70.4" in text
