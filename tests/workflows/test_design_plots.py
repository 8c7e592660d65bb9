"""Design check in the figures, the ``show`` report and the comparison table (issue 12 parts 3-4).

Also a small design sweep (lining thickness x ground stiffness) checked for the physics a
reader of its ``max_utilization`` table relies on.
"""
from __future__ import annotations

import io
import json

import numpy as np
import pytest
from matplotlib.image import imread
from matplotlib.path import Path as PolygonPath

from solver import CaseSpec
from workflows import ResultStore, open_results
from workflows.artifacts import render_plot, render_sweep_plot
from workflows.case_plots import (
    plot_contact_pressure,
    plot_interaction,
    plot_lining_forces,
)
from workflows.commands import TABLE_COLUMNS, case_row, column_unit, comparison_table, show_command
from workflows.plots import PLOTS, SWEEP_PLOTS, plot_scalars

COARSE = {"mesh": {"interface_size": 0.2, "far_size": 8.0}}
THICKNESS = (0.25, 0.4)
YOUNG = (2.0e7, 2.0e8)  # soft and stiff ground
SWEEP_ID = "00000000000d5e16"


def _spec(**sections) -> CaseSpec:
    return CaseSpec.model_validate({**COARSE, **sections})


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """A 2 x 2 design grid, a plain-concrete case (fails at any load) and a Coulomb case."""
    store = ResultStore(tmp_path_factory.mktemp("design"))
    grid = [store.run_and_store(_spec(geometry={"thickness": t}, ground={"young": e}))
            for t in THICKNESS for e in YOUNG]
    plain = store.run_and_store(_spec(design={"reinforcement_area": 0.0}))
    coulomb = store.run_and_store(_spec(interface={"model": "coulomb", "friction": 0.3}))
    return store, grid, plain, coulomb


def _png_size(path) -> tuple[int, int]:
    height, width = imread(path).shape[:2]
    return width, height


@pytest.mark.parametrize("name", ["contact_pressure", "lining_forces", "interaction", "surface_settlement",
                                  "deformed_mesh"])
def test_every_case_plot_is_registered_and_renders(store, name):
    root, grid, plain, _ = store
    assert name in PLOTS
    for case_id in (grid[0], plain):
        width, height = _png_size(render_plot(root, case_id, name))
        assert width > 300 and height > 200


def test_contact_pressure_has_shear_beside_pressure_and_the_coulomb_cone(store):
    root, _, _, coulomb = store
    ds = root.open_case(coulomb)
    ax_p, ax_s = plot_contact_pressure(ds).axes[:2]
    [pressure] = ax_p.get_lines()
    np.testing.assert_allclose(pressure.get_ydata(), ds["contact_pressure"].values / 1e3)
    shear, upper, lower = [line for line in ax_s.get_lines() if len(line.get_xdata()) == ds.sizes["interface"]]
    np.testing.assert_allclose(shear.get_ydata(), ds["shear_traction"].values / 1e3)
    np.testing.assert_allclose(upper.get_ydata(), 0.3 * ds["contact_pressure"].values / 1e3)
    np.testing.assert_allclose(lower.get_ydata(), -upper.get_ydata())
    # the shear stays within the cone it is drawn against
    assert np.all(np.abs(shear.get_ydata()) <= upper.get_ydata() * (1 + 1e-6) + 1e-6)
    assert "slipping" in ax_s.get_legend_handles_labels()[1]


def test_lining_forces_are_offsets_from_the_ring_with_station_values(store):
    root, grid, _, _ = store
    ds = root.open_case(grid[0])
    spec = json.loads(ds.attrs["case_spec"])["geometry"]
    radius = spec["inner_radius"] + spec["thickness"] / 2
    fig = plot_lining_forces(ds)
    assert len(fig.axes) == 3
    for ax, name in zip(fig.axes, ("thrust", "moment", "shear")):
        values = ds[name].values / 1e3
        [curve] = [line for line in ax.get_lines() if line.get_gid() == "forces"]
        offset = np.hypot(curve.get_xdata(), curve.get_ydata()) - radius
        peak = np.max(np.abs(values))
        # |offset| is the value scaled to 35 % of the radius at the largest one
        np.testing.assert_allclose(np.abs(offset), 0.35 * radius * np.abs(values) / peak, atol=1e-9)
        texts = {t.get_text().split("\n")[0]: t.get_text() for t in ax.texts}
        for station, theta in (("crown", 0.0), ("springline", 90.0), ("invert", 180.0)):
            i = int(np.argmin(np.abs(ds["theta"].values - theta)))
            shown = 0.0 if abs(values[i]) < 1e-6 * peak else values[i]
            assert f"{shown:.1f}" in texts[station]


def _on_polygon(m, n, polygon_m, polygon_n, tol) -> bool:
    path = PolygonPath(np.column_stack([polygon_m, polygon_n]))
    return path.contains_point((m, n), radius=tol) != path.contains_point((m, n), radius=-tol)


@pytest.mark.parametrize("which", ["reinforced", "plain"])
def test_interaction_draws_the_envelope_and_design_stations_coloured_by_theta(store, which):
    root, grid, plain, _ = store
    ds = root.open_case(grid[0] if which == "reinforced" else plain)
    gamma = json.loads(ds.attrs["case_spec"])["design"]["load_factor"]
    fig = plot_interaction(ds)
    ax = fig.axes[0]
    envelope = next(line for line in ax.get_lines() if line.get_label().startswith("design envelope"))
    env_m, env_n = ds["capacity_moment"].values / 1e3, ds["capacity_thrust"].values / 1e3
    np.testing.assert_allclose(envelope.get_xdata()[:-1], env_m)
    np.testing.assert_allclose(envelope.get_ydata()[:-1], env_n)
    stations = next(c for c in ax.collections if c.get_label().startswith("stations"))
    np.testing.assert_allclose(stations.get_offsets(), np.column_stack([gamma * ds["moment"], ds["design_thrust"]]) / 1e3)
    np.testing.assert_allclose(stations.get_array(), ds["theta"].values)
    assert len(fig.axes) == 2 and "θ" in fig.axes[1].get_ylabel()  # the colorbar
    worst = float(ds["max_utilization"])
    if which == "reinforced":
        assert f"η = {worst:.3g}" in ax.get_title()
        # the ray through the worst station ends on the envelope: the utilization's definition
        ray = next(line for line in ax.get_lines() if line.get_label().startswith("ray"))
        end_m, end_n = ray.get_xdata()[-1], ray.get_ydata()[-1]
        assert _on_polygon(end_m, end_n, env_m, env_n, tol=1e-3 * np.ptp(env_n))
    else:
        assert worst == np.inf and "η = inf" in ax.get_title()
    failing = next(c for c in ax.collections if c.get_label().startswith("η > 1"))  # both fail somewhere
    assert len(failing.get_offsets()) == int(np.sum(ds["utilization"].values > 1))


def test_show_prints_max_utilization_and_where(store):
    root, grid, plain, _ = store
    out = io.StringIO()
    assert show_command(grid[0], str(root.root), out=out) == 0
    text = out.getvalue()
    ds = root.open_case(grid[0])
    k = int(np.argmax(ds["utilization"].values))
    theta = float(ds["theta"][k])
    side = min(("crown", 0), ("springline", 90), ("invert", 180), key=lambda s: abs(s[1] - theta))[0]
    assert f"max utilization η = {float(ds['max_utilization']):.3g}" in text
    assert f"θ = {theta:.1f}° ({side} side)" in text
    gamma = json.loads(ds.attrs["case_spec"])["design"]["load_factor"]
    # N_Ed of the governing combination: γF N, or 1.0 N where the lower thrust governs (SPEC §9.3)
    assert float(ds["design_thrust"][k]) in (gamma * float(ds["thrust"][k]), float(ds["thrust"][k]))
    assert f"N_Ed = {float(ds['design_thrust'][k]) / 1e3:.1f} kN/m" in text
    assert f"M_Ed = {gamma * float(ds['moment'][k]) / 1e3:.1f} kN·m/m" in text
    for name in PLOTS:
        assert root.plot_path(grid[0], name).is_file()
    out = io.StringIO()
    show_command(plain, str(root.root), out=out)
    assert "max utilization η = inf (fails at any load level" in out.getvalue()


def test_table_has_the_design_and_settlement_columns(store):
    root, grid, plain, _ = store
    rows = [case_row(root, c) for c in (*grid, plain)]
    table = comparison_table(rows).splitlines()
    header, units = table[0], table[1]
    for key, name in TABLE_COLUMNS:
        assert name in header and column_unit(key) in units
    assert [column_unit(k) for k, _ in TABLE_COLUMNS] == [
        "kPa", "°", "kN/m", "kN·m/m", "≤ 1", "mm", "mm", "%", "mm", "mm"]
    # settlements lead with the ground loss and the Gaussian trough, the FE surface last
    assert [c[0] for c in TABLE_COLUMNS][-6:] == ["max_utilization", "crown_settlement", "ground_crown_settlement",
                                                  "ground_loss", "gaussian_max_settlement", "axis_settlement"]
    by_id = {line.split()[0]: line.split() for line in table[3:]}
    first = rows[0]["summary"]
    cells = by_id[grid[0]][-6:]
    assert cells == [f"{first['max_utilization']:.4g}", f"{first['crown_settlement'] * 1e3:.4g}",
                     f"{first['ground_crown_settlement'] * 1e3:.4g}", f"{first['ground_loss'] * 100:.4g}",
                     f"{first['gaussian_max_settlement'] * 1e3:.4g}", f"{first['axis_settlement'] * 1e3:.4g}"]
    assert by_id[plain][-6] == "inf"
    # the service's rows carry None (JSON has no inf) or text: shown as '-' and 'inf'
    rest = {**rows[0], "summary": {**first, "max_utilization": None, "axis_settlement": "inf"}}
    cells = comparison_table([rest]).splitlines()[3].split()
    assert cells[-6] == "-" and cells[-1] == "inf"


def test_design_sweep_utilization_against_thickness_and_ground(store):
    """Utilization is not monotonic in thickness; what a reader of the table must know.

    A thicker lining has more capacity (≈ h for the steel lever arm and the concrete
    block) but attracts more moment (bending stiffness ∝ h³). In stiff ground the lining
    is flexible relative to the ground, its moment grows nearly as h³ and the utilization
    rises with thickness; in soft ground the lining is the stiffer partner, the moment is
    near the rigid-ring value and grows more slowly than the capacity, so the
    utilization falls. Thrust and moment grow with thickness in both.
    """
    root, grid, _, _ = store
    combined = open_results(root, grid)
    eta = {(float(t), float(e)): float(u) for t, e, u in zip(combined["lining_thickness"].values,
                                                            combined["ground_young"].values,
                                                            combined["max_utilization"].values)}
    moment = dict(zip(eta, combined["max_abs_moment"].values))
    soft, stiff = YOUNG
    thin, thick = THICKNESS
    assert eta[thick, soft] < 0.9 * eta[thin, soft]      # soft ground: thicker helps
    assert eta[thick, stiff] > eta[thin, stiff]          # stiff ground: thicker attracts more than it gains
    assert all(moment[thick, e] > 1.2 * moment[thin, e] for e in YOUNG)
    assert all(eta[t, stiff] < eta[t, soft] for t in THICKNESS)  # stiffer ground carries more itself

    # the sweep's interaction figure: envelopes, stations, max_utilization against each parameter
    path = render_sweep_plot(root, SWEEP_ID, grid, "interaction")
    width, height = _png_size(path)
    assert width > 800 and height > 400
    from workflows.artifacts import _section_forces
    from workflows.plots import case_labels
    from workflows.plots import plot_interaction as plot_sweep_interaction

    fig = plot_sweep_interaction([_section_forces(root, c) for c in grid], case_labels(combined), combined=combined)
    envelopes = [line for line in fig.axes[0].get_lines() if len(line.get_xdata()) > 100]
    assert len(envelopes) == len(THICKNESS)  # one per section, not per case
    panels = [ax for ax in fig.axes if ax.get_ylabel().startswith("max utilization")]
    assert [ax.get_xlabel() for ax in panels] == ["lining_thickness (m)", "ground_young (MPa)"]
    against_thickness = sorted(panels[0].get_lines()[:2], key=lambda line: line.get_label())
    assert [line.get_label() for line in against_thickness] == ["ground_young = 20 MPa", "ground_young = 200 MPa"]
    np.testing.assert_allclose(against_thickness[0].get_ydata(), [eta[thin, soft], eta[thick, soft]])
    assert any(np.allclose(line.get_ydata(), 1.0) for line in panels[0].get_lines())  # the limit η = 1
    # and the scalars figure has max_utilization against both parameters
    scalars = [ax.get_xlabel() for ax in plot_scalars(combined).axes
               if ax.get_visible() and ax.get_ylabel().startswith("max_utilization")]
    assert scalars == ["lining_thickness (m)", "ground_young (MPa)"]
    for name in SWEEP_PLOTS:
        assert _png_size(render_sweep_plot(root, SWEEP_ID, grid, name))[0] > 0
