"""What shows and stores a segmental lining's joints (issue 26, SPEC §1.6 and §3): the dataset's
``joint`` variables against the solver's joints and the lining's section forces, the netCDF round
trip, the combined results of monolithic and segmental cases, the joints on the figures, and the
joints' check in the verdicts and the report."""
from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from solver import CaseSpec
from solver.results.dataset import joint_stations, to_dataset
from solver.results.variables import ECCENTRICITY_LIMIT, JOINT_VARIABLES, SCALARS
from solver.model import TunnelModel
from solver.lining.forces import lining_forces
from workflows import ResultStore
from workflows.combine import THETA, combine_files, on_theta_grid
from workflows.joint_check import joint_check, joint_report

MESH = {"mesh": {"interface_size": 0.2, "far_size": 8.0}}
SEGMENTAL = {**MESH, "lining": {"joints": {"count": 6, "contact_height": 0.15}}}
# five segments, joints at 36°, 108° and 180°: the first stays closed, the others open; a C45
# strip holds them (EN 1992 (12.10) on the strip: η 1.03 in C30)
MIXED = {**MESH, "loads": {"lateral_ratio": 0.8}, "design": {"concrete_strength": 4.5e7},
         "lining": {"joints": {"count": 5, "offset": 36.0, "contact_height": 0.2}}}
CHECKER = Path(sys.executable).with_name("ugrid-checker")


def _solve(data: dict):
    spec = CaseSpec.model_validate(data)
    model = TunnelModel(spec)
    sol = model.solve(spec)
    return model, sol, to_dataset(model, sol, software_version="test")


@pytest.fixture(scope="module")
def segmental():
    return _solve(SEGMENTAL)


@pytest.fixture(scope="module")
def monolithic() -> xr.Dataset:
    return _solve(MESH)[2]


@pytest.fixture(scope="module")
def mixed() -> xr.Dataset:
    return _solve(MIXED)[2]


@pytest.fixture(scope="module")
def store(tmp_path_factory, segmental, monolithic, mixed):
    store = ResultStore(tmp_path_factory.mktemp("joints"))
    for ds in (monolithic, segmental[2], mixed):
        store.write_case(ds)
    return store


# -- the dataset ----------------------------------------------------------------------------

def test_joint_variables_are_the_solvers_joints_and_the_section_forces_there(segmental):
    model, sol, ds = segmental
    joints = sol.joints
    assert ds.sizes["joint"] == joints.theta.size == 4  # 0, 60, 120, 180 deg in the half model
    np.testing.assert_array_equal(ds["joint_theta"], [0.0, 60.0, 120.0, 180.0])
    np.testing.assert_array_equal(ds["joint_thrust"], joints.thrust)
    np.testing.assert_array_equal(ds["joint_moment"], joints.moment)
    np.testing.assert_array_equal(ds["joint_opening"], joints.opening)
    np.testing.assert_array_equal(ds["joint_rotation"], joints.rotation)
    np.testing.assert_array_equal(ds["joint_open"], joints.open.astype(np.int8))
    assert ds["joint_open"].dtype == np.int8
    # the joints' forces are the lining's section forces at the joints' stations
    iface = model.mesh.interface
    forces = lining_forces(sol.spec, model.lining.body, iface, model.mesh.center, sol.u_lining, sol.lam, sol.shear)
    at = joint_stations(iface.theta, joints.theta)
    np.testing.assert_allclose(ds["theta"].values[at], joints.theta, atol=1e-9)
    np.testing.assert_allclose(ds["joint_thrust"], forces.thrust[at], rtol=1e-9)
    np.testing.assert_allclose(ds["joint_moment"], forces.moment[at], rtol=1e-9, atol=1e-9 * np.abs(forces.moment).max())
    # |M| / (N a/2) with a = 0.15 m; the thrust of nonnegative strip tractions acts within the strip
    a = 0.15
    np.testing.assert_allclose(ds["joint_eccentricity"], np.abs(joints.moment) / (joints.thrust * a / 2), rtol=1e-12)
    assert np.all(ds["joint_eccentricity"].values <= ECCENTRICITY_LIMIT)
    assert ds.attrs["joint_contact_height_m"] == ds["joint_eccentricity"].attrs["contact_height_m"] == a
    # the maxima
    assert float(ds["max_joint_opening"]) == joints.opening.max() > 0
    assert float(ds["max_joint_rotation"]) == np.abs(joints.rotation).max() > 0
    assert float(ds["max_joint_eccentricity"]) == ds["joint_eccentricity"].values.max()


def test_utilization_is_not_computed_at_the_joints_and_the_maximum_is_the_rest(segmental, monolithic):
    model, sol, ds = segmental
    eta = ds["utilization"].values
    at = joint_stations(ds["theta"].values, ds["joint_theta"].values)
    assert np.isnan(eta[at]).all() and np.isfinite(np.delete(eta, at)).all()
    assert float(ds["max_utilization"]) == np.delete(eta, at).max()
    assert "NaN at the joints" in ds["utilization"].attrs["long_name"]
    # a monolithic lining: the check everywhere, no joints, their maxima 0
    assert "joint" not in monolithic.dims and not [v for v in monolithic.variables if str(v).startswith("joint_")]
    assert np.isfinite(monolithic["utilization"].values).all()
    assert "NaN" not in monolithic["utilization"].attrs["long_name"]
    for name in ("max_joint_opening", "max_joint_rotation", "max_joint_eccentricity"):
        assert float(monolithic[name]) == 0.0 and name in SCALARS
    assert "joint_contact_height_m" not in monolithic.attrs
    assert isinstance(monolithic.attrs["lining_translation_m"], float)


def test_every_variable_has_units_and_the_attributes_are_json(segmental):
    model, sol, ds = segmental
    for name, var in ds.variables.items():
        if name != "mesh":
            assert var.attrs.get("units") and var.attrs.get("long_name"), name
    for name, (units, _) in JOINT_VARIABLES.items():
        assert ds[name].dims == ("joint",) and ds[name].attrs["units"] == units
    assert ds["joint_theta"].attrs["units"] == "degree" and ds["joint_rotation"].attrs["units"] == "rad"
    assert ds["max_joint_rotation"].attrs["units"] == "rad"
    # every segment's rigid modes, named; the bolt sets tried, the last one accepted
    amplitudes = json.loads(ds.attrs["lining_translation_m"])
    np.testing.assert_array_equal(amplitudes, sol.a)
    assert len(json.loads(ds.attrs["lining_modes"])) == len(amplitudes)
    trials = json.loads(ds.attrs["bolt_search"])
    assert len(trials) == int(ds["bolt_trials"]) == len(sol.trials) and trials[-1]["accepted"]
    assert trials[-1]["rows"] == [int(r) for r in sol.trials[-1].rows]
    assert np.isnan(float(ds["bolt_theta"]))  # no single bolt point: a bolt set


def test_netcdf_round_trip_and_ugrid_conventions(store, segmental):
    ds = segmental[2]
    back = store.open_case(ds.attrs["case_id"])
    xr.testing.assert_identical(back, ds)
    assert back["joint_open"].dtype == np.int8
    assert "CF-1.10" in back.attrs["Conventions"] and "UGRID-1.0" in back.attrs["Conventions"]
    checked = subprocess.run([str(CHECKER), str(store.case_path(ds.attrs["case_id"]))], capture_output=True,
                             text=True)
    assert checked.returncode == 0 and "No problems found" in checked.stdout, checked.stdout


# -- combined results -----------------------------------------------------------------------

def test_a_nan_station_is_nan_on_the_grid_only_where_it_is_nearest():
    theta = np.array([0.0, 2.5, 5.0, 7.5, 10.0, 180.0])
    values = 2.0 * theta + 1.0  # linear: interpolation is exact
    values[2] = np.nan  # not applicable at 5 deg
    grid = on_theta_grid(theta, values)
    nearest = np.abs(THETA[:, None] - theta[None, :]).argmin(axis=1)
    missing = nearest == 2
    assert THETA[missing].tolist() == [4.0, 5.0, 6.0]
    assert np.isnan(grid[missing]).all()
    np.testing.assert_allclose(grid[~missing], 2.0 * THETA[~missing] + 1.0)
    # without a NaN, exactly numpy's interpolation (results of old cases unchanged)
    np.testing.assert_array_equal(on_theta_grid(theta, 2.0 * theta), np.interp(THETA, theta, 2.0 * theta))


def test_monolithic_and_segmental_cases_combine(store, monolithic, segmental, mixed):
    cases = (monolithic, segmental[2], mixed)
    ids = [ds.attrs["case_id"] for ds in cases]
    combined = store.open_results(ids)
    xr.testing.assert_identical(combined, combine_files(store.root, ids))  # the index agrees with the files
    assert combined.sizes["case"] == 3 and "joint" not in combined.dims
    np.testing.assert_array_equal(combined["lining_joints_count"], [0, 6, 5])
    for name in ("max_joint_opening", "max_joint_rotation", "max_joint_eccentricity", "max_utilization"):
        assert combined[name].dims == ("case",)
        np.testing.assert_array_equal(combined[name], [float(ds[name]) for ds in cases])
    assert combined["max_joint_opening"].values[0] == 0.0 < combined["max_joint_opening"].values[1]
    eta = combined["utilization"].values
    assert np.isfinite(eta[0]).all()
    for k, ds in enumerate(cases[1:], start=1):
        near = np.isin(np.abs(THETA[:, None] - ds["theta"].values[None, :]).argmin(axis=1),
                       joint_stations(ds["theta"].values, ds["joint_theta"].values))
        assert np.isnan(eta[k, near]).all() and np.isfinite(eta[k, ~near]).all()
        assert near[np.round(ds["joint_theta"].values).astype(int)].all()  # the joints' own degrees
        assert float(np.nanmax(eta[k])) <= float(ds["max_utilization"]) + 1e-12


# -- figures --------------------------------------------------------------------------------

def _gids(fig, kind: str) -> list:
    return [a for ax in fig.axes for a in ax.get_children() if a.get_gid() == kind]


def test_joints_on_the_theta_and_ring_plots(mixed, monolithic):
    from workflows.case_plots import plot_contact_pressure, plot_lining_forces

    theta, is_open = mixed["joint_theta"].values, mixed["joint_open"].values.astype(bool)
    assert is_open.tolist() == [False, True, True]  # the case shows both kinds
    fig = plot_contact_pressure(mixed)
    for kind, which in (("joint-open", is_open), ("joint-closed", ~is_open)):
        lines = _gids(fig, kind)
        assert len(lines) == 2 * which.sum()  # both panels
        assert sorted({line.get_xdata()[0] for line in lines}) == sorted(theta[which])
    fig = plot_lining_forces(mixed)
    radius = 2.5 + 0.15
    ticks = [a for a in _gids(fig, "joint-open") + _gids(fig, "joint-closed") if len(a.get_xdata()) == 2]
    assert len(ticks) == 3 * theta.size  # one per joint in each of the three diagrams
    for tick in ticks:  # radial, through the ring, at a joint's angle
        x, y = np.asarray(tick.get_xdata()), np.asarray(tick.get_ydata())
        angle = np.degrees(np.arctan2(x, y))
        assert np.allclose(angle, angle[0]) and np.min(np.abs(theta - angle[0] % 360)) < 1e-9
        r = np.hypot(x, y)
        assert r.min() < radius < r.max()
    assert fig.legends and "3 joints, 2 open" in fig.legends[0].get_title().get_text()
    for plot in (plot_contact_pressure, plot_lining_forces):
        quiet = plot(monolithic)
        assert not _gids(quiet, "joint-open") and not _gids(quiet, "joint-closed")


def test_joints_on_the_interaction_diagram_lie_between_the_strips_rays(mixed):
    from workflows.case_plots import load_factor, plot_interaction

    fig = plot_interaction(mixed)
    gamma = load_factor(mixed)
    diamonds = [a for a in _gids(fig, "joint-open") + _gids(fig, "joint-closed")]
    assert len(diamonds) == mixed.sizes["joint"]
    points = sorted((float(d.get_xdata()[0]), float(d.get_ydata()[0])) for d in diamonds)
    expected = sorted(zip(gamma * mixed["joint_moment"].values / 1e3, gamma * mixed["joint_thrust"].values / 1e3))
    np.testing.assert_allclose(points, expected)
    (limit,) = _gids(fig, "joint-limit")
    m, n = np.asarray(limit.get_xdata()), np.asarray(limit.get_ydata())
    np.testing.assert_allclose(np.abs(m), 0.5 * 0.2 * n)  # |M| = N a/2, a = 0.2 m
    for mj, nj in points:
        assert abs(mj) <= 0.5 * 0.2 * nj
    # the stations of the section check leave out the joints (their utilization is not computed)
    stations = next(c for c in fig.axes[0].collections if c.get_label().startswith("stations"))
    assert len(stations.get_offsets()) == int(np.isfinite(mixed["utilization"].values).sum())
    assert "joints" in fig.axes[0].get_title()


def test_joints_cross_the_lining_on_the_mesh_plots(mixed, segmental, monolithic):
    from workflows.field_plots import plot_contours, plot_deformed_mesh

    geometry = json.loads(mixed.attrs["case_spec"])["geometry"]
    inner, outer = geometry["inner_radius"], geometry["inner_radius"] + geometry["thickness"]
    cy = float(np.mean(mixed["interface_y"].values[[0, -1]]))
    theta = mixed["joint_theta"].values
    faces = 2 * theta.size - 1  # the joint on the invert has one face in the half model
    fig = plot_contours(mixed)
    lines = _gids(fig, "joint-open") + _gids(fig, "joint-closed")
    assert len(lines) == faces * len(fig.axes[0::2][:4])  # every panel (colour bars aside)
    for line in lines:  # undeformed: from the intrados to the extrados at a joint's angle
        x, y = np.asarray(line.get_xdata()), np.asarray(line.get_ydata()) - cy
        np.testing.assert_allclose(np.hypot(x, y)[[0, -1]], [inner, outer], rtol=1e-6)
        angle = np.degrees(np.arctan2(x, y))
        assert np.min(np.abs(theta - angle.mean())) < 1e-3 and np.ptp(angle) < 1e-3
    fig = plot_deformed_mesh(mixed, scale=50.0)
    assert len(_gids(fig, "joint-open") + _gids(fig, "joint-closed")) == faces
    assert len(_gids(fig, "joint-closed")) == 2  # the joint at 36 deg, both faces
    assert "3 joints, 2 open" in fig.axes[0].get_title()
    # magnified, the faces of an open joint gape at the extrados by about the magnified opening
    ds = segmental[2]
    scale = 50.0
    fig = plot_deformed_mesh(ds, scale=scale, stage="2")  # since placement: the faces near their angles
    lines = _gids(fig, "joint-open")
    for j in (1, 2):  # the joints at 60 and 120 deg, opening at the extrados (rotation > 0)
        assert ds["joint_rotation"].values[j] > 0
        at = [line for line in lines
              if abs(np.degrees(np.arctan2(line.get_xdata()[0], line.get_ydata()[0] - cy)) - ds["joint_theta"].values[j])
              < 10]
        assert len(at) == 2
        outer_gap = np.hypot(*np.diff([[line.get_xdata()[-1], line.get_ydata()[-1]] for line in at], axis=0)[0])
        inner_gap = np.hypot(*np.diff([[line.get_xdata()[0], line.get_ydata()[0]] for line in at], axis=0)[0])
        assert outer_gap > inner_gap and outer_gap > 0.9 * scale * ds["joint_opening"].values[j]
    quiet = plot_deformed_mesh(monolithic)
    assert not _gids(quiet, "joint-open") and not _gids(quiet, "joint-closed")


# -- the verdicts and the report -----------------------------------------------------------

def test_joint_check_passes_and_fails_on_the_strip(mixed, monolithic):
    check = joint_check(mixed)
    assert check.count == 3 and check.open == 2 and check.passes and check.height == 0.2
    assert check.worst == float(mixed["max_joint_eccentricity"]) and check.theta == 180.0
    assert joint_check(monolithic) is None and joint_report(monolithic) == ""
    outside = mixed.copy(deep=True)
    outside["joint_eccentricity"].values[1] = 1.2
    failed = joint_check(outside)
    assert not failed.passes and failed.theta == 108.0 and "fails" in joint_report(outside)
    assert check.utilization == pytest.approx(float(mixed["max_joint_utilization"])) and check.utilization <= 1


def test_a_hinging_joint_whose_strip_cannot_hold_the_stress_block_fails(segmental):
    """Six segments, 0.15 m strips, C30 (the default case): every joint bears on its strip's edge
    (|M|/(N·a/2) = 1, inside the strip), but the stress block the thrust needs there does not fit:
    EN 1992 (12.10) on the strip gives η = a / (a - x) > 1, and the joints' check fails."""
    ds = segmental[2]
    check = joint_check(ds)
    assert check.worst <= ECCENTRICITY_LIMIT and check.utilization > 1 and not check.passes
    design = CaseSpec.model_validate_json(ds.attrs["case_spec"]).design
    x = design.load_factor * ds["joint_thrust"].values / (0.8 * design.concrete_strength / 1.5)
    edge = ds["joint_eccentricity"].values > 1 - 1e-6
    np.testing.assert_allclose(ds["joint_utilization"].values[edge], (0.15 / (0.15 - x))[edge], rtol=1e-6)
    assert "overloaded" in joint_report(ds)


def test_show_and_the_table_state_the_joints(store, mixed, monolithic):
    from workflows.commands import JOINT_TABLE_COLUMNS, case_row, comparison_table, show_command

    out = io.StringIO()
    show_command(mixed.attrs["case_id"], str(store.root), out=out)
    text = out.getvalue()
    assert "max utilization η" in text and "away from the joints" in text
    assert "joints (passes; contact strip a = 0.2 m)" in text and "2 of 3 joints open" in text
    assert "max_joint_opening" in text and "mrad" in text
    rows = [case_row(store.root, ds.attrs["case_id"]) for ds in (monolithic, mixed)]
    table = comparison_table(rows).splitlines()
    assert all(heading in table[0] for _, heading in JOINT_TABLE_COLUMNS)
    assert "joint gap" not in comparison_table(rows[:1]).splitlines()[0]  # monolithic alone: no joint columns
    cells = table[3 + 1].split()
    assert cells[-4] == f"{float(mixed['max_joint_opening']) * 1e3:.4g}"
    assert cells[-2] == f"{float(mixed['max_joint_eccentricity']):.4g}"
    assert cells[-1] == f"{float(mixed['max_joint_utilization']):.4g}"


def test_report_has_the_joints_page_and_the_joint_verdict(mixed, monolithic):
    import pypdfium2 as pdfium

    from workflows.plots import PLOTS
    from workflows.report import _summary_page, _verdict, case_report, joint_rows, title_block

    pdf = pdfium.PdfDocument(case_report(mixed))
    assert len(pdf) == 5 + len(PLOTS)  # summary, inputs, basis, lining forces, joints, figures
    first = pdf[0].get_textpage().get_text_range()
    assert "PASS" in first and "away from the joints" in first and "all 3 joints" in first
    joints = pdf[5].get_textpage().get_text_range()  # after summary, model, inputs, basis, lining forces
    assert "Joints of the segmental lining" in joints and "PASS" in joints
    for heading in ("θ (°)", "N (kN/m)", "M (kN·m/m)", "|M|/(N·a/2)", "opening (mm)", "rotation (mrad)", "state"):
        assert heading in joints
    for j in range(mixed.sizes["joint"]):  # each joint's row, in the table's units
        assert f"{mixed['joint_theta'].values[j]:.1f}" in joints
        assert f"{mixed['joint_thrust'].values[j] / 1e3:.1f}" in joints
        assert f"{mixed['joint_moment'].values[j] / 1e3:.2f}" in joints
        assert f"{mixed['joint_eccentricity'].values[j]:.3f}" in joints
    assert [r[-1] for r in joint_rows(mixed)] == ["closed", "open", "open"]
    assert "section forces" in pdf[7].get_textpage().get_text_range()  # the figures follow
    pdf.close()
    # a joint whose thrust leaves its strip fails the case, whatever the section's utilization
    outside = mixed.copy(deep=True)
    outside["joint_eccentricity"].values[2] = 1.5
    word, _, lines = _verdict(outside)
    assert word == "FAIL" and float(outside["max_utilization"]) < 1 and any("fails" in line for line in lines)
    # a monolithic lining: no joints page and no joint rows on the summary
    assert _verdict(monolithic)[0] == "PASS"
    summary = _summary_page(monolithic, json.loads(monolithic.attrs["case_spec"]), 1, 9, title_block(None))
    assert not [t for t in summary.texts if "max_joint" in t.get_text()]


def test_case_page_verdict_states_the_joints():
    from service.pages import design_verdict

    segmental = {"lining": {"joints": {"count": 6}}}
    ok = design_verdict({"max_utilization": 0.5, "max_joint_eccentricity": 1.0}, segmental)
    assert ok["passes"] and ok["joints"]["passes"] and "within the contact strip" in ok["joints"]["text"]
    out = design_verdict({"max_utilization": 0.5, "max_joint_eccentricity": 1.3}, segmental)
    assert not out["passes"] and out["section_passes"] and "1.3 > 1" in out["joints"]["text"]
    crushed = design_verdict({"max_utilization": 0.5, "max_joint_eccentricity": 1.0, "max_joint_utilization": 1.4},
                             segmental)
    assert not crushed["passes"] and not crushed["joints"]["passes"] and "1.4 > 1" in crushed["joints"]["text"]
    plain = design_verdict({"max_utilization": 1.2, "max_joint_eccentricity": 0.0}, {})
    assert not plain["passes"] and plain["joints"] is None
    assert design_verdict({}, segmental) is None
