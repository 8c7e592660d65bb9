"""``solver.mesh_check`` (SPEC §9.2): the reported changes are the ones a finer run gives."""
from __future__ import annotations

import json

import pytest

from solver import CaseSpec
from solver.results.mesh_check import CHECKED
from solver.run import run_case

COARSE = {"mesh": {"interface_size": 0.7, "far_size": 20.0}}


def test_the_reported_mesh_change_is_the_change_to_a_mesh_refined_once():
    checked = run_case(CaseSpec.model_validate({**COARSE, "solver": {"mesh_check": True}}))
    default = run_case(CaseSpec.model_validate(COARSE))
    fine = run_case(CaseSpec.model_validate({"mesh": {"interface_size": 0.35, "far_size": 10.0}}))
    warnings = json.loads(checked.attrs["warnings"])
    for name in CHECKED:
        expected = (float(fine[name]) - float(default[name])) / abs(float(fine[name]))
        assert float(checked[f"mesh_change_{name}"]) == pytest.approx(expected, rel=1e-9, abs=1e-15), name
        assert float(checked[name]) == float(default[name])  # the case's own answer is the default mesh's
        assert any(w.startswith(name + " ") for w in warnings) == (abs(expected) > 0.01), name
    assert any(abs(float(checked[f"mesh_change_{n}"])) > 0.01 for n in CHECKED)  # coarse enough to show


def test_the_mesh_check_is_part_of_the_case_id_only_when_asked():
    plain = CaseSpec.model_validate({})
    assert CaseSpec.model_validate({"solver": {"mesh_check": False}}).case_id == plain.case_id
    assert CaseSpec.model_validate({"solver": {"mesh_check": True}}).case_id != plain.case_id
