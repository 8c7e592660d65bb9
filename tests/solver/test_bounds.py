"""Radenkovic's bounds of the limit load of ground whose flow is not associated (solver.stages.bounds): the twin
cases' strengths, and a stalled stage 1 past the associated ground's limit told as a collapse with both bounds."""
from __future__ import annotations

import math

import numpy as np
import pytest

from solver import CaseSpec, run_case
from solver.errors import GroundCollapseError, NotConvergedError
from solver.stages import bounds, plastic

COARSE = {"interface_size": 0.3, "far_size": 10.0}
C10 = {"model": "mohr-coulomb", "cohesion": 1.0e4, "friction_angle": 28.0, "dilatancy": 0.0}


@pytest.mark.parametrize("phi, psi", [(28.0, 0.0), (35.0, 10.0), (20.0, 19.0)])
def test_the_twins_are_the_associated_ground_and_radenkovics_reduced_strength(phi, psi):
    """The upper twin keeps c and φ with ψ = φ; the lower takes tan φ* = sin φ cos ψ / (1 - sin φ sin ψ),
    c* = c cos φ cos ψ / (1 - sin φ sin ψ), ψ = φ*: weaker than the ground, with the same apex c cot φ (so the
    tension cut-off stays admissible); an elastic stratum is left as it is."""
    ground = {"model": "mohr-coulomb", "cohesion": 2.0e4, "friction_angle": phi, "dilatancy": psi,
              "tensile_strength": 2.0e4 / math.tan(math.radians(phi)),
              "layers": [{"thickness": 4.0, "model": "elastic"}, {}]}
    upper, lower = bounds.twins(CaseSpec.model_validate({"ground": ground, "loads": {"lateral_ratio": 0.9}}))
    assert upper.ground.layers[1].dilatancy == phi and upper.ground.layers[1].cohesion == 2.0e4
    s, k = math.sin(math.radians(phi)), math.cos(math.radians(psi)) / (1 - math.sin(math.radians(phi))
                                                                      * math.sin(math.radians(psi)))
    reduced = lower.ground.layers[1]
    assert reduced.friction_angle == pytest.approx(math.degrees(math.atan(s * k)), rel=1e-12)
    assert reduced.dilatancy == reduced.friction_angle < phi
    assert reduced.cohesion == pytest.approx(2.0e4 * math.cos(math.radians(phi)) * k, rel=1e-12)
    assert reduced.cohesion < 2.0e4
    apex = reduced.cohesion / math.tan(math.radians(reduced.friction_angle))
    assert apex == pytest.approx(2.0e4 / math.tan(math.radians(phi)), rel=1e-12)
    assert lower.ground.layers[0].model == "elastic" and lower.ground.layers[0] == upper.ground.layers[0]


def test_no_twins_where_the_flow_is_associated_or_the_ground_is_hoek_brown():
    assert bounds.twins(CaseSpec.model_validate({"ground": {**C10, "dilatancy": 28.0}})) is None
    assert bounds.twins(CaseSpec.model_validate({"ground": {"model": "hoek-brown", "young": 5.0e8, "ucs": 1.0e6,
                                                            "gsi": 30.0, "mi": 8.0}})) is None
    assert bounds.twins(CaseSpec.model_validate({})) is None
    # ground at the edge of failure in situ (the least admissible K0 is 0.4815): its reduced strength cannot hold
    # the in-situ state, so no lower twin
    weak = {"model": "mohr-coulomb", "cohesion": 4.0e3, "friction_angle": 20.2, "dilatancy": 3.4}
    upper, lower = bounds.twins(CaseSpec.model_validate({"ground": weak, "loads": {"lateral_ratio": 0.483}}))
    assert upper.ground.dilatancy == 20.2 and lower is None
    assert bounds.twins(CaseSpec.model_validate({"ground": weak, "loads": {"lateral_ratio": 0.6}}))[1] is not None


def _fails_first(monkeypatch, failure: NotConvergedError):
    """Stage 1 of the case itself fails with ``failure`` (scripted, as a stage-1 failure); the twins' stage 1 and any
    retry run as they are. The loads each stage 1 went to."""
    real, calls = plastic._stage_one, []
    failure.unsupported = True

    def stage_one(model, rows, release, ld, steps, tol, *args):
        calls.append(ld)
        if len(calls) == 1:
            raise failure
        return real(model, rows, release, ld, steps, tol, *args)

    monkeypatch.setattr(plastic, "_stage_one", stage_one)
    return calls


def _stalls_first(monkeypatch):
    return _fails_first(monkeypatch, NotConvergedError("solver.load_steps: stage 1 stalled (scripted)"))


def _collapses_first(monkeypatch, peak: float):
    return _fails_first(monkeypatch, GroundCollapseError(
        f"excavation.deconfinement: the unsupported ground collapses in stage 1 (scripted at λ {peak})", peak))


@pytest.mark.slow
def test_a_stall_past_the_associated_grounds_limit_is_a_collapse_within_radenkovics_bounds(monkeypatch):
    """c 10 kPa, φ 28°, ψ 0 released to λd 0.95 (coarse mesh): the same ground with ψ = φ collapses at λ 0.884
    and the reduced-strength one at 0.825, so the ground cannot stand at 0.95 and holds at least 0.825. A stage 1
    that stalls there fails as that collapse, with both bounds (no retry at a tighter stop test); the ground
    itself, solved to λd 0.8 below the lower bound, stands. Below the upper bound nothing is proved and the
    stalled case is solved again as before."""
    import re

    from solver.model import TunnelModel

    case = {"ground": C10, "excavation": {"deconfinement": 0.95}, "mesh": COARSE}
    calls = _stalls_first(monkeypatch)
    spec = CaseSpec.model_validate(case)
    model = TunnelModel(spec)
    with pytest.raises(GroundCollapseError, match=r"^excavation\.deconfinement: the unsupported ground cannot stand "
                                                  r"at λd 0\.95: .* limit load is at least λ 0\.8\d+, .* at most "
                                                  r"λ 0\.88\d+, where the same ground with ψ = φ collapses") as err:
        model.solve(spec)
    assert "stage 1 stalled (scripted)" in str(err.value) and calls == [0.95] * 3  # the case, then both twins
    # a sweep's next case on the model: its stage 1 and the twins' outcomes kept (with the stall's stage and the
    # collapses' loads), the same answer without a solve
    with pytest.raises(GroundCollapseError) as again:
        model.solve(spec.model_copy(update={"lining": spec.lining.model_copy(update={"density": 2000.0})}))
    assert str(again.value).split(". The staged")[0] == str(err.value).split(". The staged")[0] and len(calls) == 3
    lower, upper = (float(v) for v in re.search(r"at least λ ([0-9.]+),.*at most λ ([0-9.]+),", str(err.value))
                    .groups())
    assert 0.8 < lower < upper < 0.9 and err.value.peak == pytest.approx(lower, abs=1e-4)
    monkeypatch.undo()
    ds = run_case(CaseSpec.model_validate({**case, "excavation": {"deconfinement": 0.8}}))  # below the lower bound
    assert float(ds["stage1_plastic_area"]) > 50.0
    # below the associated ground's limit: the stalled case is solved again at half the stop test, its warning
    # saying what the bounds know (both twins stand at λd 0.5: the ground holds it)
    import json

    calls = _stalls_first(monkeypatch)
    ds = run_case(CaseSpec.model_validate({**case, "excavation": {"deconfinement": 0.5}}))
    assert calls == [0.5] * 4 and np.isfinite(float(ds["max_thrust"]))  # the case, both twins, the retry
    warnings = json.loads(ds.attrs["warnings"]) if isinstance(ds.attrs["warnings"], str) else ds.attrs["warnings"]
    assert any("stage 1 stalled (scripted) (its limit load is at least λd 0.5, which associated ground of "
               "Radenkovic's reduced strength holds, beyond λd 0.5, which the same ground with ψ = φ holds: "
               "Radenkovic's bounds)" in w for w in warnings)


@pytest.mark.slow
def test_a_named_collapse_is_checked_against_radenkovics_bounds(monkeypatch):
    """A collapse the path names is raised with the bounds it lies within; one named below what the ground holds
    for certain (the lower bound, less half an increment) is no collapse: the case is solved again, and its warning
    says why (c 10 kPa, φ 28°, ψ 0, coarse mesh: bounds 0.825 and 0.884)."""
    import json

    case = {"ground": C10, "excavation": {"deconfinement": 0.95}, "mesh": COARSE}
    _collapses_first(monkeypatch, 0.86)
    with pytest.raises(GroundCollapseError, match=r"\(scripted at λ 0\.86\) \(with its flow not associated its limit "
                                                  r"load is at least λ 0\.8\d+, .*at most λ 0\.88\d+, .*Radenkovic's "
                                                  r"bounds\)$") as err:
        run_case(CaseSpec.model_validate(case))
    assert err.value.peak == 0.86
    monkeypatch.undo()
    calls = _collapses_first(monkeypatch, 0.4)  # at λd 0.8, below the lower bound: the ground stands
    ds = run_case(CaseSpec.model_validate({**case, "excavation": {"deconfinement": 0.8}}))
    warnings = json.loads(ds.attrs["warnings"]) if isinstance(ds.attrs["warnings"], str) else ds.attrs["warnings"]
    assert any("(scripted at λ 0.4) (not a collapse: the ground holds at least λd 0.8, which associated ground of "
               "Radenkovic's reduced strength holds)" in w for w in warnings)
    assert calls == [0.8, 0.8, 0.8, 0.8]  # the case, both twins, the retry
