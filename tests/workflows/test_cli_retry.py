"""``tunnel-contact run``: a failed case is recomputed only with ``--retry-failed``
(as ``POST /cases?retry=failed``), a broken stored result is recomputed, never shown."""
from __future__ import annotations

import io
import json

from service.cli import main
from solver import CaseSpec
from workflows.commands import format_summary, run_command
from workflows.result_store import ResultStore, as_store

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


def test_failed_case_is_recomputed_only_when_asked(tmp_path):
    case = {**COARSE, "solver": {"inner": "uzawa", "max_iterations": 1}}
    (tmp_path / "case.json").write_text(json.dumps(case))
    results = str(tmp_path / "results")
    out = io.StringIO()
    assert run_command(str(tmp_path / "case.json"), results, out=out) == 1
    record = as_store(results).error_path(CaseSpec.model_validate(case).case_id)
    first = json.loads(record.read_text())["time"], record.stat().st_mtime_ns

    out = io.StringIO()
    assert run_command(str(tmp_path / "case.json"), results, out=out) == 1
    assert "failed before" in out.getvalue() and "--retry-failed" in out.getvalue()
    assert record.stat().st_mtime_ns == first[1]

    assert main(["run", str(tmp_path / "case.json"), "--results", results, "--retry-failed"]) == 1
    assert record.stat().st_mtime_ns != first[1]  # solved (and failed) again


def test_truncated_result_is_recomputed(tmp_path):
    (tmp_path / "case.json").write_text(json.dumps(COARSE))
    results = str(tmp_path / "results")
    assert run_command(str(tmp_path / "case.json"), results, out=io.StringIO()) == 0
    case_id = CaseSpec.model_validate(COARSE).case_id
    path = as_store(results).case_path(case_id)
    first = ResultStore(results).read_summary(case_id)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 4])
    out = io.StringIO()
    assert run_command(str(tmp_path / "case.json"), results, out=out) == 0
    again = ResultStore(results).read_summary(case_id)  # a whole file again, the same physics
    assert again["max_contact_pressure"] == first["max_contact_pressure"]
    assert format_summary(again) in out.getvalue()


def test_failed_sweep_cases_are_recomputed_only_when_asked(tmp_path):
    sweep = {"name": "retry", "base": {**COARSE, "solver": {"inner": "uzawa"}},
             "vary": {"solver.max_iterations": [1, 100000]}}
    (tmp_path / "sweep.json").write_text(json.dumps(sweep))
    results = str(tmp_path / "results")
    args = ["sweep", str(tmp_path / "sweep.json"), "--results", results, "--no-progress"]
    assert main(args) == 1  # the one-iteration case fails, the other is stored
    failing = CaseSpec.model_validate({**sweep["base"], "solver": {"inner": "uzawa", "max_iterations": 1}})
    record = as_store(results).error_path(failing.case_id)
    first = record.stat().st_mtime_ns
    assert main(args) == 1
    assert record.stat().st_mtime_ns == first  # shown as failed, not solved again
    assert main([*args, "--retry-failed"]) == 1
    assert record.stat().st_mtime_ns != first  # solved (and failed) again


def test_sweep_recomputes_a_truncated_result_and_show_says_it_is_unreadable(tmp_path, capsys):
    """A stored file cut short after the fact (a full disk, a bad copy) made every later
    ``tunnel-contact sweep`` of its study stop on an HDF error, and was never recomputed."""
    sweep = {"name": "truncated", "base": COARSE, "vary": {"loads.lateral_ratio": [0.5, 0.8]}}
    (tmp_path / "sweep.json").write_text(json.dumps(sweep))
    results = str(tmp_path / "results")
    args = ["sweep", str(tmp_path / "sweep.json"), "--results", results, "--no-progress"]
    assert main(args) == 0
    broken = CaseSpec.model_validate({**COARSE, "loads": {"lateral_ratio": 0.5}}).case_id
    kept = CaseSpec.model_validate({**COARSE, "loads": {"lateral_ratio": 0.8}}).case_id
    store = ResultStore(results)
    first = store.read_summary(broken)
    untouched = as_store(results).case_path(kept).stat().st_mtime_ns
    path = as_store(results).case_path(broken)
    path.write_bytes(path.read_bytes()[:1000])
    assert store.unreadable([broken, kept]) == [broken]

    capsys.readouterr()
    assert main(["show", broken, "--results", results]) == 2
    assert "cannot be read" in capsys.readouterr().err

    assert main(args) == 0
    assert store.read_summary(broken)["max_abs_moment"] == first["max_abs_moment"]
    assert as_store(results).case_path(kept).stat().st_mtime_ns == untouched  # a readable result is not recomputed
    assert store.unreadable([broken, kept]) == []


def test_operator_errors_are_one_line_not_a_traceback(tmp_path, capsys):
    (tmp_path / "case.json").write_text(json.dumps(COARSE))
    (tmp_path / "afile").write_text("not a folder")
    assert main(["run", str(tmp_path / "case.json"), "--results", str(tmp_path / "afile")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("tunnel-contact: error:") and "Traceback" not in err


def test_report_command_writes_the_pdf_of_a_case_by_id_prefix(tmp_path):
    results = str(tmp_path / "results")
    (tmp_path / "case.json").write_text(json.dumps({"mesh": {"interface_size": 0.2, "far_size": 6.0}}))
    assert main(["run", str(tmp_path / "case.json"), "--results", results]) == 0
    case_id = ResultStore(results).case_ids()[0]
    target = tmp_path / "out.pdf"
    assert main(["report", case_id[:6], "--results", results, "-o", str(target)]) == 0
    assert target.read_bytes().startswith(b"%PDF") and target.stat().st_size > 50_000
    assert main(["report", "ffff", "--results", results]) == 2  # no such case: an input error
