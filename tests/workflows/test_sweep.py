"""Sweeps: expansion and its validation, and running on a real 2-process LocalCluster."""
from __future__ import annotations

import os

import numpy as np
import pytest
from pydantic import ValidationError

from solver import CaseSpec
from workflows import MAX_SWEEP_CASES, Sweep, SweepError, expand_sweep, open_case, open_results, run_sweep, tasks
from workflows.result_store import as_store
from workflows.tasks import solve_and_store, solve_and_store_each

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


def sweep(vary, mode="grid", base=COARSE) -> Sweep:
    return Sweep.model_validate({"name": "t", "base": base, "vary": vary, "mode": mode})


@pytest.mark.parametrize("vary, mode, n", [
    ({}, "grid", 1),
    ({"ground.young": [2e7, 5e7, 8e7]}, "grid", 3),
    ({"lining.thickness": [0.2, 0.3, 0.4], "ground.young": [2e7, 5e7]}, "grid", 6),
    ({"lining.thickness": [0.2, 0.3, 0.4], "ground.young": [2e7, 5e7, 8e7]}, "zip", 3),
    ({"geometry.gap": [0.0, 0.01], "boundaries.side": ["fixed", "roller", "pressure"],
      "solver.inner": ["uzawa"]}, "grid", 6),
    ({"ground.young": [2e7, 2e7, 2.0e7]}, "grid", 1),  # the same case is listed once
])
def test_expansion_sizes(vary, mode, n):
    cases = expand_sweep(sweep(vary, mode))
    assert len(cases) == n
    assert len({c.case_id for c in cases}) == n


def test_expanded_values():
    cases = expand_sweep(sweep({"lining.thickness": [0.2, 0.4], "ground.young": [2e7, 5e7]}))
    assert [(c.geometry.thickness, c.ground.young) for c in cases] == [
        (0.2, 2e7), (0.2, 5e7), (0.4, 2e7), (0.4, 5e7)]
    # everything not varied comes from the base
    assert all(c.mesh.interface_size == 0.25 and c.lining == CaseSpec().lining for c in cases)
    zipped = expand_sweep(sweep({"geometry.thickness": [0.2, 0.4], "ground.young": [2e7, 5e7]}, "zip"))
    assert [(c.geometry.thickness, c.ground.young) for c in zipped] == [(0.2, 2e7), (0.4, 5e7)]


def test_all_errors_are_reported_at_once():
    bad = sweep({"geometry.colour": [1], "ground.young": [], "lining.thickness": [0.3, -0.1],
                 "loads.gravity": [9.81, "lots"]})
    with pytest.raises(SweepError) as info:
        expand_sweep(bad)
    errors = dict(info.value.errors)
    assert len(info.value.errors) == 4
    assert "unknown parameter" in errors["geometry.colour"]
    assert "empty" in errors["ground.young"]
    assert "-0.1" in errors["lining.thickness"] and "greater than 0" in errors["lining.thickness"]
    assert "'lots'" in errors["loads.gravity"]
    assert isinstance(info.value, ValueError)
    assert "geometry.colour" in str(info.value) and "lining.thickness" in str(info.value)


def test_unequal_zip_and_too_many_cases_reported_together():
    n = int(np.ceil(np.sqrt(MAX_SWEEP_CASES))) + 1
    big = sweep({"ground.young": list(np.linspace(1e7, 9e7, n)),
                 "lining.young": list(np.linspace(1e10, 4e10, n)), "nope.x": [1]})
    with pytest.raises(SweepError) as info:
        expand_sweep(big)
    paths = [p for p, _ in info.value.errors]
    assert "nope.x" in paths and "vary" in paths
    assert f"{n * n:,} cases" in dict(info.value.errors)["vary"]

    unequal = sweep({"ground.young": [2e7, 5e7], "lining.young": [3e10], "geometry.depth": [1.0]}, "zip")
    with pytest.raises(SweepError) as info:
        expand_sweep(unequal)
    messages = dict(info.value.errors)
    assert set(messages) == {"ground.young", "lining.young", "geometry.depth"}
    assert "zip" in messages["ground.young"]
    assert any("cover above the tunnel" in m for p, m in info.value.errors if p == "geometry.depth")


def test_invalid_combination_is_reported_with_its_case():
    # each value is fine alone; together the mesh is coarser than the lining allows
    with pytest.raises(SweepError) as info:
        expand_sweep(sweep({"geometry.inner_radius": [0.6, 2.5], "mesh.interface_size": [0.1, 0.25]},
                           base={"mesh": {"interface_size": 0.1, "far_size": 8.0}}))
    [(path, message)] = info.value.errors
    assert path == "case" or path.startswith("mesh")
    assert "geometry.inner_radius=0.6" in message and "mesh.interface_size=0.25" in message


def test_sweep_model_rejects_unknown_fields():
    with pytest.raises(ValidationError):
        Sweep.model_validate({"name": "t", "colour": "red"})
    with pytest.raises(ValidationError):
        Sweep.model_validate({"name": "t", "mode": "product"})
    with pytest.raises(ValidationError):
        Sweep.model_validate({"name": "t", "base": {"ground": {"young": -1}}})


def test_task_function(tmp_path):
    spec = CaseSpec.model_validate(COARSE)
    first = solve_and_store(spec.canonical_json(), str(tmp_path))
    assert first["status"] == "done" and first["error"] is None and first["computed"]
    assert first["case_id"] == spec.case_id
    assert first["summary"]["converged"] == 1.0
    assert all(isinstance(v, float) for v in first["summary"].values())
    ds = open_case(tmp_path, spec.case_id)
    assert first["summary"]["max_thrust"] == float(ds["max_thrust"])
    second = solve_and_store(spec.canonical_json(), str(tmp_path))
    assert not second["computed"] and second["summary"] == first["summary"]
    assert first["warnings"] == second["warnings"] == []

    # the solver's warnings travel with the outcome, computed or read back from the file
    warned = CaseSpec.model_validate({**COARSE, "loads": {"surface_load": 1e9}})
    computed = solve_and_store(warned.canonical_json(), str(tmp_path))
    stored = solve_and_store(warned.canonical_json(), str(tmp_path))
    assert computed["computed"] and not stored["computed"]
    assert computed["warnings"] and stored["warnings"] == computed["warnings"]
    assert any("small-displacement" in w or "displacement" in w for w in computed["warnings"]), computed["warnings"]

    # a stored file that cannot be read is computed again, not reported as stored
    path = as_store(tmp_path).case_path(spec.case_id)
    path.write_bytes(path.read_bytes()[:1000])
    healed = solve_and_store(spec.canonical_json(), str(tmp_path))
    assert healed["status"] == "done" and healed["computed"]
    physics = {k: v for k, v in first["summary"].items() if k != "solve_seconds"}
    assert {k: healed["summary"][k] for k in physics} == physics
    assert float(open_case(tmp_path, spec.case_id)["max_thrust"]) == float(ds["max_thrust"])

    failing = CaseSpec.model_validate({**COARSE, "solver": {"inner": "uzawa", "max_iterations": 1}})
    result = solve_and_store(failing.canonical_json(), str(tmp_path))
    assert result["status"] == "failed" and result["summary"] == {}
    assert "NotConvergedError" in result["error"]
    assert as_store(tmp_path).read_error(failing.case_id)["error"] == result["error"]


def test_run_sweep_on_two_worker_processes(tmp_path, client):
    thicknesses = [0.2, 0.25, 0.3, 0.35, 0.3]
    study = sweep({"lining.thickness": thicknesses,
                   "solver.inner": ["active-set"] * 4 + ["uzawa"],
                   "solver.max_iterations": [100_000] * 4 + [1]}, mode="zip")
    results = []
    ids = run_sweep(study, tmp_path, client=client, on_result=results.append)
    expected = [c.case_id for c in expand_sweep(study)]
    assert ids == expected and len(ids) == 5
    by_id = {r["case_id"]: r for r in results}
    assert sorted(by_id) == sorted(ids) and len(results) == 5  # one task per case
    failed = ids[-1]
    assert by_id[failed]["status"] == "failed" and "did not converge" in by_id[failed]["error"]
    assert as_store(tmp_path).error_path(failed).exists() and not as_store(tmp_path).case_path(failed).exists()
    done = ids[:-1]
    assert all(by_id[c]["status"] == "done" and by_id[c]["computed"] for c in done)
    assert as_store(tmp_path).case_ids() == sorted(done)
    # both workers took part
    assert len(client.scheduler_info()["workers"]) == 2

    combined = open_results(tmp_path, done)
    np.testing.assert_array_equal(combined["lining_thickness"], thicknesses[:4])
    for i, case_id in enumerate(done):
        ds = open_case(tmp_path, case_id)
        assert by_id[case_id]["summary"]["max_contact_pressure"] == float(ds["max_contact_pressure"])
        np.testing.assert_allclose(combined["thrust"].isel(case=i).sel(theta=[0.0, 180.0]),
                                   ds["thrust"].values[[0, -1]], rtol=1e-12)

    # the second run computes nothing that is stored; only the failed case is retried
    mtimes = {c: os.stat(as_store(tmp_path).case_path(c)).st_mtime_ns for c in done}
    again = []
    assert run_sweep(study, tmp_path, client=client, on_result=again.append) == ids
    assert [r["case_id"] for r in again] == [failed]
    assert {c: os.stat(as_store(tmp_path).case_path(c)).st_mtime_ns for c in done} == mtimes


def test_run_sweep_skips_everything_stored(tmp_path, client):
    study = sweep({"ground.young": [3e7, 6e7]})
    first = []
    ids = run_sweep(study, tmp_path, client=client, on_result=first.append)
    assert {r["status"] for r in first} == {"done"} and len(first) == 2
    second = []
    assert run_sweep(study, tmp_path, client=client, on_result=second.append) == ids
    assert second == []


def test_each_case_of_a_batch_fails_alone(tmp_path):
    good = CaseSpec.model_validate(COARSE)
    failing = CaseSpec.model_validate({**COARSE, "solver": {"inner": "uzawa", "max_iterations": 1}})
    results = solve_and_store_each([good.named_json(), '{"mesh": 1}', failing.named_json()],
                                   [good.case_id, "0123456789abcdef", failing.case_id], str(tmp_path))
    assert [r["case_id"] for r in results] == [good.case_id, "0123456789abcdef", failing.case_id]
    assert [r["status"] for r in results] == ["done", "failed", "failed"]
    assert "ValidationError" in results[1]["error"] and "did not converge" in results[2]["error"]
    assert as_store(tmp_path).case_ids() == [good.case_id]
    assert as_store(tmp_path).read_error(failing.case_id)["error"] == results[2]["error"]


def _batch_sweep(n: int, failing: int | None = None) -> Sweep:
    """``n`` coarse cases (lining thickness varied), case ``failing`` one that does not converge."""
    bad = [i == failing for i in range(n)]
    return sweep({"lining.thickness": [round(0.2 + 0.005 * i, 4) for i in range(n)],
                  "solver.inner": ["uzawa" if b else "active-set" for b in bad],
                  "solver.max_iterations": [1 if b else 100_000 for b in bad]}, mode="zip")


def test_cheap_cases_go_several_to_a_task(tmp_path, client, monkeypatch):
    from distributed import get_task_stream

    monkeypatch.setattr(tasks, "BATCH_SECONDS", 60.0)  # batches by the sweep's size alone
    study = _batch_sweep(24, failing=5)  # the first four cases one a task (no timing yet), then several
    results = []
    with get_task_stream(client) as stream:
        ids = run_sweep(study, tmp_path, client=client, on_result=results.append)
    keys = [t["key"] for t in stream.data]
    assert len(keys) < len(ids) and any(k.startswith(tasks.BATCH_KEY_PREFIX) for k in keys)
    by_id = {r["case_id"]: r for r in results}
    assert sorted(by_id) == sorted(ids) and len(results) == 24  # each case reported once
    failed = ids[5]
    assert by_id[failed]["status"] == "failed" and "did not converge" in by_id[failed]["error"]
    assert as_store(tmp_path).error_path(failed).exists()
    assert all(by_id[c]["status"] == "done" and by_id[c]["computed"] for c in ids if c != failed)
    assert as_store(tmp_path).case_ids() == sorted(c for c in ids if c != failed)
    assert open_results(tmp_path).sizes["case"] == 23


def test_a_batch_whose_task_raises_is_tried_one_case_a_task(tmp_path, client, monkeypatch):
    import operator

    from distributed import get_task_stream

    monkeypatch.setattr(tasks, "BATCH_SECONDS", 60.0)
    submit = client.submit

    def dying(fn, *args, **kwargs):  # a batch's task raises, as when its worker dies
        if fn is tasks.solve_and_store_each:
            return submit(operator.truediv, 1, 0, key=kwargs["key"], pure=False)
        return submit(fn, *args, **kwargs)

    monkeypatch.setattr(client, "submit", dying)
    study = _batch_sweep(20)
    results = []
    with get_task_stream(client) as stream:
        ids = run_sweep(study, tmp_path, client=client, on_result=results.append)
    keys = {t["key"] for t in stream.data}
    assert any(k.startswith(tasks.BATCH_KEY_PREFIX) for k in keys)
    assert {tasks.task_key(c) for c in ids} <= keys  # in the end every case in a task of its own
    assert sorted(r["case_id"] for r in results) == sorted(ids)
    assert {r["status"] for r in results} == {"done"}
    assert as_store(tmp_path).case_ids() == sorted(ids)


def test_examples_are_valid():
    from workflows.commands import load_case, load_sweep

    root = __import__("pathlib").Path(__file__).parents[2] / "examples"
    assert load_case(root / "case.json") == CaseSpec()  # the example is the default case
    cases = expand_sweep(load_sweep(root / "sweep.json"))
    assert 4 <= len(cases) <= 8
    assert all(c.mesh == CaseSpec().mesh for c in cases)
    from workflows.studies import Search

    assert len(expand_sweep(load_sweep(root / "sobol-study.json"))) == 1024  # the README's study
    search = Search.model_validate_json((root / "thinnest-lining.json").read_text())  # and search
    assert search.parameter == "geometry.thickness" and len(expand_sweep(search.trial_sweep(search.low))) == 3
    assert load_case(root / "segmental.json").lining.joints.count == 6  # the README's segmental lining
    patterns = expand_sweep(load_sweep(root / "segment-patterns.json"))
    assert [(c.lining.joints.count, c.lining.joints.offset) for c in patterns] == [
        (4, 0.0), (4, 45.0), (6, 0.0), (6, 30.0), (8, 0.0), (8, 22.5)]


def test_dict_input_and_alias():
    data = {"name": "t", "base": COARSE, "vary": {"lining.thickness": [0.2, 0.4]}}
    assert [c.geometry.thickness for c in expand_sweep(data)] == [0.2, 0.4]
    with pytest.raises(SweepError) as info:
        expand_sweep({**data, "vary": {"lining.thickness": [0.2], "geometry.thickness": [0.3]}})
    assert info.value.errors[0][0] == "geometry.thickness"


def test_a_sweeps_definition_keeps_the_order_its_sample_depends_on():
    """A sampled sweep draws its dimensions in the order of ``vary``: the definition a record keeps
    gives back the same cases, where the canonical (sorted) form, the id's, gives others."""
    import json

    given = {"name": "order", "base": {"mesh": {"interface_size": 0.25, "far_size": 8.0}}, "mode": "sobol",
             "samples": 4, "seed": 3,
             "vary": {"loads.lateral_ratio": {"distribution": "uniform", "low": 0.5, "high": 1.0},
                      "design.load_factor": {"distribution": "uniform", "low": 1.2, "high": 1.5}}}
    sweep = Sweep.model_validate(given)
    ids = [s.case_id for s in expand_sweep(sweep)]
    again = Sweep.model_validate(json.loads(sweep.definition_json()))
    assert [s.case_id for s in expand_sweep(again)] == ids and again.sweep_id == sweep.sweep_id
    assert list(again.vary) == list(given["vary"])
    canonical = Sweep.model_validate(json.loads(sweep.canonical_json()))
    assert [s.case_id for s in expand_sweep(canonical)] != ids


def test_unknown_sweep_path_and_base_field_say_did_you_mean():
    """Issue 39: a misspelt path is named with the closest parameter."""
    from solver.errors import field_errors

    with pytest.raises(SweepError, match="did you mean 'ground.young'"):
        expand_sweep({"name": "typo", "base": {}, "vary": {"ground.yong": [1e7, 2e7]}})
    with pytest.raises(ValidationError) as info:
        Sweep.model_validate({"name": "typo", "base": {"ground": {"densty": 2000.0}}, "vary": {}})
    assert field_errors(info.value) == [("base.ground.densty", "unknown field; did you mean 'density'?")]


def test_a_sweep_over_a_profile_s_arc_radius(tmp_path):
    """``geometry.section.arcs.0.radius`` is a sweep parameter (SPEC §9.4): each case's first arc
    has the radius given and its last one is solved for closure; the combined results carry the
    radius as the case's parameter, and the crown's moment changes with the crown arc's radius."""
    from workflows.parameters import flat_parameters

    base = {"geometry": {"section": {"shape": "polycentric", "arcs": [
        {"radius": 4.0, "angle": 60.0}, {"radius": 2.5, "angle": 70.0}, {"angle": 50.0}]},
        "thickness": 0.3, "depth": 25.0, "width": 60.0, "height": 70.0},
        "mesh": {"interface_size": 0.4, "far_size": 10.0}}
    radii = [3.6, 4.0, 4.4]
    specs = expand_sweep({"name": "crown radius", "base": base, "vary": {"geometry.section.arcs.0.radius": radii}})
    assert [s.geometry.section.arcs[0].radius for s in specs] == radii
    closing = [s.geometry.profile().arcs[-1].radius for s in specs]
    assert len(set(closing)) == 3 and all(r > 0 for r in closing)
    names = [k for k, v in flat_parameters(specs[0]).items() if v == 3.6]
    assert len(names) == 1 and "radius" in names[0]
    store = as_store(tmp_path)
    ids = [store.run_and_store(s) for s in specs]
    ds = open_results(tmp_path, ids)
    assert list(ds[names[0]].values) == radii
    crown = [float(store.open_case(i)["moment"].values[0]) for i in ids]
    assert len(set(np.round(crown, 3))) == 3
