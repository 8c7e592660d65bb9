"""Yielding ground over a sample of the parameter space, not one tuned case (issue 36, SPEC §9.1):
every admissible case of a seeded sample of weak soft ground converges, or fails as a named collapse."""
from __future__ import annotations

import json

import pytest
from pydantic import ValidationError

from bench.ground import sample_cases
from solver import CaseSpec
from solver.errors import GroundCollapseError
from solver.run import run_case


@pytest.mark.slow
def test_a_seeded_sample_of_weak_soft_ground_converges_throughout():
    """16 cases of ``bench.ground``'s weak family (c′ 1–15 kPa, φ′ 20–32°, ψ 0–5°, λd 0.2–0.6, K0 0.4–0.7,
    E 30–150 MPa; another seed than the bench's) on a mesh a little coarser than the default. Before the
    arc-length steps, three of the first 32 of this sequence stalled (cases 5, 25 and 29); each case here
    converges with a yielded zone and a ground loss, or collapses saying what the ground held."""
    mesh = {"interface_size": 0.15, "far_size": 6.0}
    outcomes, yielded = [], []
    for case in sample_cases(16, "weak", seed=7):
        try:
            spec = CaseSpec.model_validate({**case, "mesh": mesh})
        except ValidationError:  # an in-situ state outside the yield surface is refused, as it should be
            outcomes.append("refused")
            continue
        try:
            ds = run_case(spec)
        except GroundCollapseError as err:
            assert "held" in str(err) or "levels out at λ" in str(err) or "peaks at λ" in str(err)
            outcomes.append("collapse")
            continue
        assert float(ds["ground_loss"]) > 0
        yielded.append(float(ds["stage1_plastic_area"]))
        warnings = ds.attrs["warnings"]
        warnings = json.loads(warnings) if isinstance(warnings, str) else warnings
        outcomes.append("retried" if any(w.startswith("solver.plastic_tolerance") for w in warnings) else "converged")
    assert outcomes.count("refused") <= 2 and len(outcomes) == 16
    assert outcomes[5] == "converged"  # the case that stalled before
    assert sum(a > 1.0 for a in yielded) >= 4  # a sample of weak ground, not of elastic cases
