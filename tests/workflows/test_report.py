"""The PDF report as a calculation record (issue 39 item 8): the title block, the stratigraphy
instead of interleaved layer rows, the design basis, numbered captions, and a first page whose
verdict never reads as its opposite. Pages are read back with pdfium (text) as a person reads them."""
from __future__ import annotations

import json

import pypdfium2 as pdfium
import pytest

from solver import CaseSpec, run_case
from workflows import ResultStore
from workflows.artifacts import render_report
from workflows.commands import report_command
from workflows.report import TITLE_FIELDS, case_report, stratigraphy, title_block

COARSE = {"mesh": {"interface_size": 0.2, "far_size": 8.0}}
LAYERED = {**COARSE, "ground": {"layers": [
    {"thickness": 6.0, "young": 2.0e7, "density": 1800.0},
    {"young": 8.0e7, "model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 32.0, "permeability": 1e-7}]},
    "lining": {"joints": {"count": 6, "contact_height": 0.15}}}
TITLE = {"project": "Metro Line 4, lot 2", "job": "J-2026-117", "author": "A. Engineer", "checker": "B. Checker",
         "revision": "C", "date": "2026-11-20"}


def _pages(pdf: bytes) -> list[str]:
    doc = pdfium.PdfDocument(pdf)
    try:
        return [doc[i].get_textpage().get_text_range() for i in range(len(doc))]
    finally:
        doc.close()


@pytest.fixture(scope="module")
def layered():
    return run_case(CaseSpec.model_validate(LAYERED))


@pytest.fixture(scope="module")
def pages(layered):
    """The layered segmental case's report with a title block, page by page as text (written once)."""
    return _pages(case_report(layered, title=TITLE))


def test_the_title_block_carries_every_field_given_and_today_by_default(pages):
    first = pages[0]
    for field in TITLE_FIELDS:
        assert TITLE[field] in first, field
    assert title_block(None)["date"] and title_block({"job": "7"})["project"] == ""
    with pytest.raises(ValueError, match="client"):
        title_block({"client": "x"})


def test_the_stratigraphy_is_a_table_of_resolved_layers_and_layer_inputs_are_not_listed_as_if_they_applied(
        layered, pages):
    rows = stratigraphy(json.loads(layered.attrs["case_spec"]))
    assert [r[1] for r in rows] == ["0–6", "6–50"]
    assert rows[0][2] == f"{1800 * 9.81 / 1e3:.3g}" and rows[1][3] == "80"  # γ in kN/m³, E in MPa
    assert rows[0][7] == "–" and rows[1][7] == "30" and rows[1][8] == "32"  # c, φ only where it yields
    inputs = pages[2]
    assert "Stratigraphy" in inputs
    assert "ground_young" not in inputs and "ground_layers_0_young" not in inputs  # the layers' own apply
    assert "lining_young" in inputs


def test_the_design_basis_states_the_clauses_and_partial_factors(pages):
    basis = pages[3]  # after the summary, the model and the inputs
    for text in ("EN 1992-1-1", "γC = 1.5", "γS = 1.15", "γF = 1.35", "(12.10)", "bolt-point"):
        assert text in basis, text


def test_a_failing_first_page_says_first_what_fails(pages):
    first = pages[0]
    assert "FAIL" in first
    assert "fails by the joints' contact strips" in first  # the section passes, the joints do not
    assert "axis depth" in first and "cover" not in first
    lines = [line for line in first.splitlines() if "FAIL" in line]
    assert lines and not any("passes" in line for line in lines)


def test_the_figures_are_numbered_and_captioned(pages):
    figures = [p for p in pages if "Figure " in p]
    numbers = [int(p.split("Figure ")[1].split(".")[0]) for p in figures]
    assert numbers == list(range(1, len(figures) + 1)) and len(figures) >= 8


def test_a_titled_report_is_cached_apart_and_the_cli_takes_the_title(tmp_path):
    case_id = ResultStore(tmp_path / "results").run_and_store(CaseSpec.model_validate(COARSE))
    plain = render_report(tmp_path / "results", case_id)
    out = tmp_path / "r.pdf"
    title = {"project": "Tunnel X", "checker": "C. D."}
    assert report_command(case_id, str(tmp_path / "results"), output=str(out), title=title) == 0
    titled = render_report(tmp_path / "results", case_id, title=title)  # the command's, from the cache
    assert plain != titled and plain.name == "report.pdf" and titled.read_bytes() == out.read_bytes()
    assert render_report(tmp_path / "results", case_id) == plain and plain.exists()  # not overwritten
    first, untitled = _pages(out.read_bytes())[0], _pages(plain.read_bytes())[0]
    assert "Tunnel X" in first and "C. D." in first and "Tunnel X" not in untitled
