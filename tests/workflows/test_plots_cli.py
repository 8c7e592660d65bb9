"""Plots of a case and of combined results; the tunnel-contact command line."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from solver import CaseSpec
from workflows import open_case, open_results, run_and_store
from workflows.plots import PLOTS, plot_comparison, plot_contact_pressure, plot_lining_forces

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
CLI = Path(sys.executable).with_name("tunnel-contact")


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    root = tmp_path_factory.mktemp("plots")
    ids = [run_and_store(CaseSpec.model_validate({**COARSE, "geometry": {"thickness": t}}), root)
           for t in (0.25, 0.35)]
    return root, ids


@pytest.mark.parametrize("name", sorted(PLOTS))
def test_case_plots_render(store, tmp_path, name):
    root, ids = store
    fig = PLOTS[name](open_case(root, ids[0]))
    assert isinstance(fig, Figure)
    fig.savefig(tmp_path / f"{name}.png")
    assert (tmp_path / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plotted_curves_are_the_data(store):
    root, ids = store
    ds = open_case(root, ids[0])
    [line] = plot_contact_pressure(ds).axes[0].get_lines()
    np.testing.assert_allclose(line.get_ydata(), ds["contact_pressure"].values / 1e3)
    # lining forces as offsets from the ring: tests/workflows/test_design_plots.py
    assert [ax.get_title().split(" (")[0] for ax in plot_lining_forces(ds).axes] == [
        "thrust N", "bending moment M", "shear force V"]


def test_comparison_plot_has_one_line_per_case(store):
    root, ids = store
    combined = open_results(root, ids)
    lines = plot_comparison(combined, "thrust").axes[0].get_lines()
    assert len(lines) == 2
    for i, line in enumerate(lines):
        np.testing.assert_allclose(line.get_ydata(), combined["thrust"].isel(case=i))
        assert "lining_thickness=" in line.get_label()
    with pytest.raises(ValueError):
        plot_comparison(combined, "max_thrust")


def cli(*args, cwd):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env.pop("DASK_SCHEDULER_ADDRESS", None)
    return subprocess.run([str(CLI), *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=120)


def cli_here(*args, cwd, capsys, monkeypatch):
    """:func:`cli` in this process (``service.cli.main``, the installed script's entry point): the
    same exit code and output without a Python start and the imports (about 2.5 s a call)."""
    from service.cli import main

    monkeypatch.chdir(cwd)
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    capsys.readouterr()
    code = main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out, err)


def test_cli_run_sweep_show(tmp_path, capsys, monkeypatch):
    (tmp_path / "case.json").write_text(json.dumps(COARSE))
    run = cli("run", "case.json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    case_id = CaseSpec.model_validate(COARSE).case_id
    assert (tmp_path / "results" / "cases" / f"{case_id}.nc").is_file()  # ./results by default
    assert "max_contact_pressure" in run.stdout

    (tmp_path / "sweep.json").write_text(json.dumps(
        {"name": "cli", "base": COARSE, "vary": {"lining.thickness": [0.25, 0.3]}}))
    sweep = cli("sweep", "sweep.json", "--results", "out", cwd=tmp_path)
    assert sweep.returncode == 0, sweep.stderr
    ids = [c.case_id for c in (CaseSpec.model_validate({**COARSE, "geometry": {"thickness": t}})
                               for t in (0.25, 0.3))]
    rows = [line for line in sweep.stdout.splitlines() if line.split()[:1] in ([ids[0]], [ids[1]])]
    assert len(rows) == 2 and "lining_thickness" in sweep.stdout
    combined = open_results(tmp_path / "out", ids)
    assert f"{float(combined['max_contact_pressure'][0]) / 1e3:.4g}" in rows[0]
    assert "Traceback" not in sweep.stderr

    show = cli("show", ids[1], "--results", "out", cwd=tmp_path)
    assert show.returncode == 0, show.stderr
    for name in PLOTS:
        png = tmp_path / "out" / "plots" / ids[1] / f"{name}.png"
        assert png.is_file() and png.stat().st_size > 1000
    assert "lining_thickness = 0.3" in show.stdout
    # an id prefix does, the whole store is listed, the version is printed
    again = cli_here("show", ids[1][:6], "--results", "out", cwd=tmp_path, capsys=capsys, monkeypatch=monkeypatch)
    assert again.returncode == 0 and "lining_thickness = 0.3" in again.stdout, again.stderr
    listed = cli_here("list", "--results", "out", cwd=tmp_path, capsys=capsys, monkeypatch=monkeypatch)
    assert listed.returncode == 0 and all(i in listed.stdout for i in ids) and "2 cases in out" in listed.stdout
    version = cli("--version", cwd=tmp_path)
    assert version.returncode == 0 and version.stdout.startswith("tunnel-contact ")


@pytest.mark.parametrize("args, content, message, real", [
    (["run", "bad.json"], "{not json", "not valid JSON", True),  # the installed script, as a process
    (["run", "bad.json"], '{"geometry": {"thickness": -1}}', "geometry.thickness", False),
    (["run", "bad.json"], '{"colour": "red"}', "colour", False),
    (["run", "missing.json"], None, "cannot read", False),
    (["sweep", "bad.json"], '{"name": "x", "vary": {"lining.colour": [1]}}', "lining.colour", False),
    (["sweep", "bad.json"], '{"vary": {}}', "name", False),
    (["show", "not-an-id"], None, "16 lowercase hex", True),
    (["show", "0123456789abcdef"], None, "not in", False),
    (["show", "01234"], None, "no case id", False),
])
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, args, content, message, real, capsys, monkeypatch):
    if content is not None:
        (tmp_path / "bad.json").write_text(content)
    result = (cli(*args, cwd=tmp_path) if real else
              cli_here(*args, cwd=tmp_path, capsys=capsys, monkeypatch=monkeypatch))
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    [line] = result.stderr.strip().splitlines()
    assert line.startswith("tunnel-contact: error:") and message in line


def test_cli_run_reports_a_solver_failure(tmp_path):
    case = {**COARSE, "solver": {"inner": "uzawa", "max_iterations": 1}}
    (tmp_path / "case.json").write_text(json.dumps(case))
    result = cli("run", "case.json", cwd=tmp_path)
    assert result.returncode == 1
    assert "did not converge" in result.stdout and "Traceback" not in result.stderr
    case_id = CaseSpec.model_validate(case).case_id
    assert (tmp_path / "results" / "cases" / f"{case_id}.error.json").is_file()
    show = cli("show", case_id, cwd=tmp_path)
    assert show.returncode == 1 and "did not converge" in show.stdout


def test_the_parser_and_the_version_need_no_finite_elements():
    """``tunnel-contact --help``, ``--version`` and a bad argument answer without importing the
    solver's finite elements, xarray or the workflows (a fresh process: 0.36 s against 1.6 s)."""
    probe = ("import sys; from service.cli import build_parser; build_parser(); import solver; "
             "print(sorted(m for m in ('solver.run', 'skfem', 'xarray', 'workflows') if m in sys.modules)); "
             "print(solver.run_case.__module__)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["[]", "solver.run"]
