"""A case's time limit (solver.limits): every solver loop gives up past it with the reason,
the limit does not outlive its block, and a stopped case is a failed case, never a result."""
from __future__ import annotations

import pytest

import solver.limits as limits
from solver import SolverError
from solver.run import run_case
from solver.spec import CaseSpec
from workflows import ResultStore

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


@pytest.mark.parametrize("extra, where", [
    ({}, "active-set contact iteration"),
    ({"interface": {"model": "coulomb", "friction": 0.3}}, "Coulomb"),
    ({"ground": {"model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 28.0,
                 "tensile_strength": 1.0e4}}, "plastic iteration"),
])
def test_every_solver_loop_stops_past_the_limit_naming_itself(extra, where):
    spec = CaseSpec.model_validate({**COARSE, **extra})
    with pytest.raises(limits.TimeLimitExceeded, match="time limit") as caught:
        run_case(spec, time_limit_seconds=1e-9)
    assert where in str(caught.value) and isinstance(caught.value, SolverError)
    # the limit belonged to that call: the same case solves under the default one
    assert float(run_case(spec)["converged"]) == 1.0


def test_uzawa_checks_the_clock_while_it_iterates(monkeypatch):
    """The Uzawa loop (the runaway of issue 24: an hour for one POST) looks at the clock every
    256 iterations: made never to converge, it is stopped by the limit, not by its 10⁷ cap."""
    import solver.contact.bolt as contact

    monkeypatch.setattr(contact, "dual_kkt", lambda *args, **kwargs: 1.0)  # never converged
    spec = CaseSpec.model_validate({**COARSE, "solver": {"inner": "uzawa", "tolerance": 1e-14,
                                                         "max_iterations": 10_000_000}})
    with pytest.raises(limits.TimeLimitExceeded, match="Uzawa contact iteration after 256 iterations"):
        run_case(spec, time_limit_seconds=1e-9)


def test_a_case_over_its_limit_is_stored_as_failed_with_the_reason(tmp_path, monkeypatch):
    monkeypatch.setenv("TUNNEL_CONTACT_CASE_TIME_LIMIT", "1e-9")
    # a case of its own: one this process solved before is taken from its shared model, in no time
    spec = CaseSpec.model_validate({**COARSE, "loads": {"lateral_ratio": 0.6137}})
    store = ResultStore(tmp_path)
    with pytest.raises(SolverError):
        store.run_and_store(spec)
    assert not store.is_stored(spec.case_id)
    assert "time limit" in store.read_error(spec.case_id)["error"]
