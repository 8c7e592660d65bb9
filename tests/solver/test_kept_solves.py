"""Solves kept on a built model (:class:`solver.build.Kept`): a case's mechanics
(:meth:`solver.model.TunnelModel.solve`: a design sweep works out only its checks) and yielding ground's
stage 1 (:func:`solver.stages.plastic._first_stage`: a sweep whose cases differ only in what stage 2
depends on, the lining's weight or the interface, solves the unsupported ground's release once), each
with the answer of a fresh model; anything they depend on solves them again."""
from __future__ import annotations

import numpy as np
import pytest

import solver.stages.plastic as plastic
from solver import CaseSpec
from solver.fe.flexibility import rows_of_model
from solver.model import TunnelModel
from solver.run import run_case

COARSE = {"interface_size": 0.15, "far_size": 6.0}
BASE = {"ground": {"model": "mohr-coulomb", "cohesion": 1.0e4, "friction_angle": 28.0},
        "interface": {"model": "coulomb", "friction": 0.3}, "mesh": COARSE}


def _case(**parts) -> CaseSpec:
    case = {key: dict(value) for key, value in BASE.items()}
    for part, values in parts.items():
        case[part] = {**case.get(part, {}), **values}
    return CaseSpec.model_validate(case)


def _calls(monkeypatch, module, name: str) -> list:
    """The calls made of ``module.name`` from here on (one entry each)."""
    calls = []
    real = getattr(module, name)

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counting)
    return calls


@pytest.fixture
def counted(monkeypatch):
    """The number of stage-1 solves made (calls of :func:`solver.stages.plastic._stage_one`)."""
    return _calls(monkeypatch, plastic, "_stage_one")


def _same(a, b) -> None:
    """Two results of one case, bit for bit where it matters (every name is in both: a name missing
    from the result fails, it is not skipped)."""
    for name in ("displacement_x", "displacement_y", "contact_pressure", "moment", "effective_stress_xx"):
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
    if "plastic" in b:
        for name in ("plastic", "stage1_plastic"):
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
    for name in ("max_abs_moment", "plastic_area", "stage1_plastic_area", "max_utilization"):
        assert float(a[name]) == float(b[name]), name


def test_a_sweep_over_what_stage_two_depends_on_solves_stage_one_once(counted):
    """(Not the design: the case's whole mechanics are kept for that, the next test.)"""
    first = _case()
    model = TunnelModel(first)
    run_case(first, model=model)
    assert len(counted) == 1
    others = [_case(lining={"density": 2000.0}), _case(interface={"friction": 0.6}),
              _case(interface={"friction": 0.45}, solver={"tolerance": 1e-9})]
    kept = [run_case(case, model=model) for case in others]
    assert len(counted) == 1  # the unsupported ground's release was solved once
    for case, ds in zip(others, kept):
        _same(ds, run_case(case))  # a fresh model's answer, exactly
    assert len(counted) == 1 + len(others)
    assert float(kept[0]["stage1_plastic_area"]) > 0  # the ground did yield before the lining went in


def test_what_stage_one_depends_on_solves_it_again(counted):
    first = _case()
    model = TunnelModel(first)
    base = run_case(first, model=model)
    changed = [_case(ground={"cohesion": 1.2e4}), _case(loads={"lateral_ratio": 0.6}),
               _case(excavation={"deconfinement": 0.4}), _case(solver={"plastic_tolerance": 5e-3}),
               _case(interface={"model": "frictionless", "friction": 0.0})]
    for case in changed:
        assert model.accepts(case)
        ds = run_case(case, model=model)
        assert float(ds["stage1_plastic_area"]) != float(base["stage1_plastic_area"]) or \
            not np.array_equal(ds["displacement_x"].values, base["displacement_x"].values)
    assert len(counted) == 1 + len(changed)


def test_the_key_leaves_out_exactly_what_stage_two_alone_depends_on():
    rows = rows_of_model("coulomb")
    key = plastic.stage_one_key(_case(), rows, 0.01)
    same = [_case(lining={"density": 2000.0}), _case(interface={"friction": 0.6}),
            _case(design={"concrete_strength": 4.0e7}), _case(settlement={"volume_loss": 0.01}),
            _case(solver={"tolerance": 1e-9})]
    for case in same:
        assert plastic.stage_one_key(case, rows, 0.01) == key
    other = [_case(ground={"dilatancy": 2.0}), _case(water={"table": 5.0}), _case(solver={"load_steps": 20}),
             _case(geometry={"gap": 0.01}, interface={"model": "frictionless", "friction": 0.0})]
    for case in other:
        assert plastic.stage_one_key(case, rows_of_model(case.interface.model), 0.01) != key
    assert plastic.stage_one_key(_case(), rows, 0.005) != key  # a retry's tighter stop test
    assert plastic.stage_one_key(_case(), rows_of_model("frictionless"), 0.01) != key  # other rounding


def test_a_stage_one_that_failed_fails_the_next_case_alike_without_solving_it_again(counted, monkeypatch):
    import solver.stages.path as path
    from solver.errors import NotConvergedError

    monkeypatch.setattr(path, "MAX_STEP_ITERATIONS", 2)  # every stage 1 runs out of iterations
    first = _case()
    model = TunnelModel(first)
    with pytest.raises(NotConvergedError) as one:
        run_case(first, model=model)
    solved = len(counted)
    # at the asked stop test, its two associated twins (Radenkovic's bounds, which stall too: nothing known) and
    # once more at a tighter stop test
    assert solved == 4
    with pytest.raises(NotConvergedError) as two:
        run_case(_case(lining={"density": 2000.0}), model=model)
    assert len(counted) == solved
    assert str(two.value) == str(one.value) and "ran out" in str(two.value)


def test_the_kept_history_cannot_be_written_into(counted):
    first = _case()
    model = TunnelModel(first)
    run_case(first, model=model)
    (u1, _, _, _), histories = model.kept.values("stage one")[0]
    assert not u1.flags.writeable
    for history in histories:
        assert not history["sigma"].flags.writeable and not history["grad"].flags.writeable


@pytest.fixture
def solved(monkeypatch):
    """The number of mechanical solves made (calls of :func:`solver.model.solve_case`)."""
    import solver.model as model_module

    return _calls(monkeypatch, model_module, "solve_case")


@pytest.mark.parametrize("ground", [{}, BASE["ground"]], ids=["elastic", "yielding"])
def test_a_design_sweep_solves_the_mechanics_once_and_checks_each_design(solved, ground):
    first = _case(ground=ground) if ground else CaseSpec.model_validate({"mesh": COARSE})
    model = TunnelModel(first)
    base = run_case(first, model=model)
    designs = [{"reinforcement_area": 0.0}, {"reinforcement_area": 5.0e-3, "concrete_strength": 5.0e7},
               {"load_factor": 1.5, "crack_width_limit": 2.0e-4}]
    cases = [first.model_copy(update={"design": first.design.model_copy(update=d), "name": f"design {i}"})
             for i, d in enumerate(designs)]
    cases.append(first.model_copy(update={"settlement": first.settlement.model_copy(update={"volume_loss": 0.01})}))
    kept = [run_case(case, model=model) for case in cases]
    assert len(solved) == 1  # one mechanical solve for the sweep
    for case, ds in zip(cases, kept):
        np.testing.assert_array_equal(ds["displacement_x"].values, base["displacement_x"].values)
        fresh = run_case(case)
        _same(ds, fresh)
        assert "max_utilization" in fresh and "design_max_settlement" in fresh
        for name in ("max_utilization", "max_crack_width", "design_max_settlement"):
            if name in fresh:
                assert float(ds[name]) == float(fresh[name]) or np.isnan(float(fresh[name])), name
        assert ds.attrs.get("name") == fresh.attrs.get("name")
    # the checks are each design's own: plain concrete is used more than the heavily reinforced section
    assert float(kept[0]["max_utilization"]) > float(kept[1]["max_utilization"])
    assert float(kept[3]["design_max_settlement"]) != float(base["design_max_settlement"])
    again = run_case(first, model=model)  # the kept solution was not changed by the others' results
    _same(again, base)
    assert float(again["max_utilization"]) == float(base["max_utilization"])


def test_a_failed_solve_fails_a_design_variant_alike_but_a_time_limit_is_not_kept(solved, monkeypatch):
    import solver.stages.path as path
    from solver.errors import NotConvergedError
    from solver.limits import TimeLimitExceeded

    first = _case()
    model = TunnelModel(first)
    with monkeypatch.context() as m:
        m.setattr(path, "MAX_STEP_ITERATIONS", 2)
        with pytest.raises(NotConvergedError) as one:
            run_case(first, model=model)
    with pytest.raises(NotConvergedError) as two:
        run_case(first.model_copy(update={"design": first.design.model_copy(update={"load_factor": 1.5})}),
                 model=model)
    assert len(solved) == 1 and str(two.value) == str(one.value)
    other = _case(ground={"cohesion": 2.0e4})
    with pytest.raises(TimeLimitExceeded):
        run_case(other, model=model, time_limit_seconds=1e-9)
    assert float(run_case(other, model=model)["max_abs_moment"]) > 0  # solved in full, not the kept failure
    assert len(solved) == 3
