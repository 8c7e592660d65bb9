"""Figures of a sweep (workflows.plots): what they draw, on small in-memory results."""
from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from workflows.plots import SWEEP_PLOTS, plot_interaction, plot_scalars

THETA = np.arange(0.0, 181.0, 1.0)


def combined_results() -> xr.Dataset:
    """Four cases of a 2 x 2 grid over lining_thickness and ground_young."""
    thickness = np.array([0.2, 0.2, 0.3, 0.3])
    young = np.array([2e7, 5e7, 2e7, 5e7])
    case = np.arange(4)
    pressure = 1e5 * (1 + thickness[:, None]) * (1 + np.cos(np.radians(THETA))[None, :])
    return xr.Dataset(
        {"contact_pressure": (("case", "theta"), pressure, {"units": "Pa"}),
         "thrust": (("case", "theta"), 4e5 + 0 * pressure, {"units": "N m-1"}),
         "moment": (("case", "theta"), 1e4 * np.cos(np.radians(2 * THETA))[None, :] * young[:, None] / 2e7,
                    {"units": "N m m-1"}),
         "max_abs_moment": ("case", 1e4 * young / 2e7, {"units": "N m m-1"}),
         "contact_extent": ("case", np.full(4, 180.0), {"units": "degree"}),
         "iterations": ("case", np.array([1.0, 2.0, 1.0, 3.0]), {"units": "1"})},
        coords={"theta": THETA, "case_id": ("case", [f"{i:016x}" for i in case]),
                "lining_thickness": ("case", thickness), "ground_young": ("case", young)})


def test_scalars_one_panel_per_changing_scalar_and_parameter_diagnostics_last():
    figure = plot_scalars(combined_results())
    panels = [ax for ax in figure.axes if ax.get_visible()]
    # contact_extent is the same everywhere: named in the title, not plotted
    assert [(ax.get_ylabel().split(" ")[0], ax.get_xlabel()) for ax in panels] == [
        ("max_abs_moment", "lining_thickness (m)"), ("max_abs_moment", "ground_young (MPa)"),
        ("iterations", "lining_thickness (m)"), ("iterations", "ground_young (MPa)")]
    assert "contact_extent = 180 °" in figure._suptitle.get_text()
    # against ground_young (MPa): one line per thickness, values in kN·m/m
    lines = panels[1].get_lines()
    assert len(lines) == 2
    np.testing.assert_allclose(lines[0].get_xdata(), [20.0, 50.0])
    np.testing.assert_allclose(lines[0].get_ydata(), [10.0, 25.0])


def test_a_sampled_sweeps_scalars_are_points_in_one_collection():
    """A sampled sweep (no two cases share the other parameters): each panel's points are one
    collection at the cases' values, not one line object a case."""
    rng = np.random.default_rng(3)
    n = 30
    thickness, young = rng.uniform(0.2, 0.4, n), rng.uniform(2e7, 8e7, n)
    ds = xr.Dataset({"max_abs_moment": ("case", 1e4 * young / 2e7, {"units": "N m m-1"})},
                    coords={"case_id": ("case", [f"{i:016x}" for i in range(n)]),
                            "lining_thickness": ("case", thickness), "ground_young": ("case", young)})
    figure = plot_scalars(ds)
    title = " ".join(figure._suptitle.get_text().split())
    assert "against lining_thickness: one point per case; against ground_young: one point per case" in title
    panels = [ax for ax in figure.axes if ax.get_visible() and ax.get_label() != "<colorbar>"]
    assert len(panels) == 2  # (each with a colour bar of the other parameter)
    for ax, x in zip(panels, (thickness, young / 1e6)):
        assert ax.get_lines() == [] and len(ax.collections) == 1
        points = ax.collections[0].get_offsets()
        np.testing.assert_allclose(np.sort(points[:, 0]), np.sort(x))
        np.testing.assert_allclose(np.sort(points[:, 1]), np.sort(10.0 * young / 2e7))


def legend_texts(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_scalars_have_a_legend_against_each_parameter_and_a_title_saying_what_is_drawn():
    figure = plot_scalars(combined_results())
    panels = [ax for ax in figure.axes if ax.get_visible()]
    # the first panel against each parameter: which line is which, in engineering units
    assert panels[0].get_legend() is not None and panels[1].get_legend() is not None
    assert legend_texts(panels[0]) == ["ground_young = 20 MPa", "ground_young = 50 MPa"]
    assert legend_texts(panels[1]) == ["lining_thickness = 0.2 m", "lining_thickness = 0.3 m"]
    assert all(ax.get_legend() is None for ax in panels[2:])  # once is enough
    title = " ".join(figure._suptitle.get_text().split())
    assert "against lining_thickness: one line per ground_young" in title
    assert "against ground_young: one line per lining_thickness" in title and "4 cases" in title


def with_utilization(combined: xr.Dataset) -> xr.Dataset:
    eta = 0.5 + combined["lining_thickness"].values + combined["ground_young"].values / 1e8
    return combined.assign(max_utilization=("case", eta, {"units": "1"}))


def sections(combined: xr.Dataset) -> list[xr.Dataset]:
    """Each case's forces with a design envelope that grows with its thickness."""
    cases = []
    angle = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    for i in range(combined.sizes["case"]):
        ds = combined[["thrust", "moment"]].isel(case=i, drop=True).drop_vars(list(combined.coords), errors="ignore")
        h = float(combined["lining_thickness"].values[i])
        ds["capacity_thrust"] = ("envelope", 1e7 * h * (1 + np.sin(angle)))
        ds["capacity_moment"] = ("envelope", 1e6 * h * np.cos(angle))
        ds["utilization"] = ("theta", np.full(THETA.size, 0.5))
        ds.attrs["case_spec"] = json.dumps({"design": {"load_factor": 1.35}})
        cases.append(ds)
    return cases


def test_the_nm_figure_has_a_legend_of_its_cases_and_of_eta_against_each_parameter():
    from workflows.plots import case_labels

    combined = with_utilization(combined_results())
    figure = plot_interaction(sections(combined), case_labels(combined), combined=combined)
    nm, *panels = figure.axes
    assert legend_texts(nm) == ["lining_thickness = 0.2 m, ground_young = 20 MPa",
                                "lining_thickness = 0.2 m, ground_young = 50 MPa",
                                "lining_thickness = 0.3 m, ground_young = 20 MPa",
                                "lining_thickness = 0.3 m, ground_young = 50 MPa",
                                "design envelope N_Rd–M_Rd of a section"]
    assert "N–M interaction of 4 cases" in nm.get_title() and "envelopes (lines)" in nm.get_title()
    assert [ax.get_title() for ax in panels] == [
        "max utilization η against lining_thickness\none line per ground_young",
        "max utilization η against ground_young\none line per lining_thickness"]
    assert legend_texts(panels[0]) == ["ground_young = 20 MPa", "ground_young = 50 MPa"]
    assert legend_texts(panels[1]) == ["lining_thickness = 0.2 m", "lining_thickness = 0.3 m"]


def test_the_nm_figure_of_many_cases_is_coloured_by_a_parameter_and_says_so():
    combined = design_sweep()
    combined["max_utilization"] = ("case", combined["lining_thickness"].values * 2, {"units": "1"})
    figure = plot_interaction(sections(combined), combined=combined)
    nm = figure.axes[0]
    assert legend_texts(nm) == ["design actions at the stations, colour: lining_thickness",
                                "design envelope N_Rd–M_Rd of a section"]
    bars = [ax for ax in figure.axes if ax.get_label() == "<colorbar>"]
    assert [bar.get_ylabel() for bar in bars] == ["lining_thickness (m)"]
    stations = [line for line in nm.get_lines() if line.get_marker() == "o"]
    colours = [tuple(line.get_color()) for line in stations]
    assert len(set(colours)) == 5 and colours[0] == colours[2] != colours[3]  # a colour per thickness
    titles = [ax.get_title() for ax in figure.axes[1:] if ax.get_label() != "<colorbar>"]
    assert titles == ["max utilization η against lining_thickness\none line per loads_lateral_ratio",
                      "max utilization η against loads_lateral_ratio\none line per lining_thickness"]


@pytest.mark.parametrize("envelope", [False, True])
def test_interaction_draws_every_station_and_the_envelopes_when_present(envelope):
    combined = combined_results()
    cases = []
    for i in range(4):
        ds = combined[["thrust", "moment"]].isel(case=i).drop_vars(["case_id", "lining_thickness", "ground_young"])
        ds.attrs["case_spec"] = json.dumps({"design": {"load_factor": 1.5}})
        if envelope:
            angle = np.linspace(0, 2 * np.pi, 50, endpoint=False)
            # one section per case (cases sharing a section share one drawn envelope)
            ds["capacity_thrust"] = ("envelope", 2e6 * (1 + 0.1 * i) * (1 + np.sin(angle)))
            ds["capacity_moment"] = ("envelope", 2e5 * (1 + 0.1 * i) * np.cos(angle))
            ds["utilization"] = ("theta", np.full(THETA.size, 0.4 + 0.1 * i))
        cases.append(ds)
    ax = plot_interaction(cases).axes[0]
    stations = [line for line in ax.get_lines() if line.get_marker() == "o"]
    curves = [line for line in ax.get_lines() if line.get_marker() != "o" and len(line.get_xdata()) > 2]
    assert len(stations) == 4 and all(len(line.get_xdata()) == THETA.size for line in stations)
    factor = 1.5 if envelope else 1.0
    np.testing.assert_allclose(stations[0].get_ydata(), factor * 400.0)  # kN/m
    assert len(curves) == (4 if envelope else 0)
    assert ("η = 0.7" in ax.get_title()) == envelope


@pytest.mark.parametrize("name", sorted(SWEEP_PLOTS))
def test_every_sweep_plot_draws_from_combined_results(name):
    assert SWEEP_PLOTS[name](combined_results()).axes


def design_sweep() -> xr.Dataset:
    """15 cases: 5 thicknesses x 3 lateral ratios (the README's design sweep shape)."""
    thickness = np.repeat([0.2, 0.25, 0.3, 0.35, 0.4], 3)
    ratio = np.tile([0.5, 0.7, 1.0], 5)
    moment = 1e4 * (1 - ratio[:, None]) * thickness[:, None] * np.cos(np.radians(2 * THETA))[None, :]
    return xr.Dataset(
        {"contact_pressure": (("case", "theta"), 1e5 * (1 + thickness[:, None] + 0 * THETA), {"units": "Pa"}),
         "thrust": (("case", "theta"), 4e5 + 0 * moment, {"units": "N m-1"}),
         "moment": (("case", "theta"), moment, {"units": "N m m-1"})},
        coords={"theta": THETA, "case_id": ("case", [f"{i:016x}" for i in range(15)]),
                "lining_thickness": ("case", thickness), "loads_lateral_ratio": ("case", ratio)})


@pytest.mark.parametrize("name", ["contact_pressure", "lining_forces"])
def test_sweep_curves_coloured_by_a_parameter_with_a_colour_bar_and_faceted_by_another(name):
    combined = design_sweep()
    figure = SWEEP_PLOTS[name](combined)
    bars = [ax for ax in figure.axes if ax.get_label() == "<colorbar>"]
    assert len(bars) == 1 and bars[0].get_ylabel() == "lining_thickness (m)"
    panels = [ax for ax in figure.axes if ax.get_label() != "<colorbar>"]
    assert len(panels) == (3 if name == "contact_pressure" else 6)  # one column per lateral ratio
    assert [ax.get_title() for ax in panels[:3]] == [f"loads_lateral_ratio = {k}" for k in (0.5, 0.7, 1)]
    lines = [line for line in panels[0].get_lines() if len(line.get_xdata()) == THETA.size]
    assert len(lines) == 5  # the five thicknesses at K0 = 0.5
    colours = [line.get_color() for line in lines]
    assert len({tuple(c) for c in colours}) == 5  # thinnest to thickest: five colours of the bar
    # a lining-thickness value maps to the same colour in every facet
    other = [line for line in panels[1].get_lines() if len(line.get_xdata()) == THETA.size]
    assert [tuple(line.get_color()) for line in other] == [tuple(c) for c in colours]


def test_scalars_over_many_values_of_the_other_parameter_get_a_colour_bar():
    n = 12
    thickness = np.repeat(np.linspace(0.2, 0.42, n), 2)
    young = np.tile([2e7, 5e7], n)
    combined = xr.Dataset({"max_abs_moment": ("case", 1e4 * thickness * young / 2e7, {"units": "N m m-1"})},
                          coords={"case_id": ("case", [f"{i:016x}" for i in range(2 * n)]),
                                  "lining_thickness": ("case", thickness), "ground_young": ("case", young)})
    figure = plot_scalars(combined)
    bars = [ax for ax in figure.axes if ax.get_label() == "<colorbar>"]
    # against ground_young: 12 lines, one per thickness, coloured by it
    assert [bar.get_ylabel() for bar in bars] == ["lining_thickness (m)"]


def three_parameter_grid() -> xr.Dataset:
    """η over a 3 × 2 × 2 grid of lining thickness, ground stiffness and K0 (K0 and E: two values)."""
    t, E, K = np.meshgrid([0.2, 0.3, 0.4], [2e7, 5e7], [0.5, 1.0], indexing="ij")
    t, E, K = t.ravel(), E.ravel(), K.ravel()
    eta = 0.3 / t + E / 1e8 + K
    return xr.Dataset({"max_utilization": ("case", eta, {"units": "1"})},
                      coords={"case_id": ("case", [f"{i:016x}" for i in range(t.size)]),
                              "lining_thickness": ("case", t), "ground_young": ("case", E),
                              "loads_lateral_ratio": ("case", K)})


def test_a_third_parameter_gets_a_panel_per_value():
    """"η against t, one line per E, one panel per K0": each panel holds the cases of one K0, its
    lines one per E, each line the η of those cases against t, and the title says so."""
    combined = three_parameter_grid()
    figure = plot_scalars(combined)
    panels = [ax for ax in figure.axes if ax.get_visible()]
    against_t = [ax for ax in panels if ax.get_xlabel() == "lining_thickness (m)"]
    assert [ax.get_title() for ax in against_t] == ["loads_lateral_ratio = 0.5", "loads_lateral_ratio = 1"]
    for ax, k0 in zip(against_t, (0.5, 1.0)):
        lines = ax.get_lines()
        assert len(lines) == 2  # one per E
        for line, young in zip(lines, (2e7, 5e7)):
            np.testing.assert_allclose(line.get_xdata(), [0.2, 0.3, 0.4])
            np.testing.assert_allclose(line.get_ydata(), 0.3 / np.array([0.2, 0.3, 0.4]) + young / 1e8 + k0)
    assert legend_texts(against_t[0]) == ["ground_young = 20 MPa", "ground_young = 50 MPa"]
    title = " ".join(figure._suptitle.get_text().split())
    assert "against lining_thickness: one line per ground_young, one panel per loads_lateral_ratio" in title
    # against K0 itself: the facets are E's (two values, the last of the fewest), the lines t's
    against_k0 = [ax for ax in panels if ax.get_xlabel() == "loads_lateral_ratio"]
    assert [ax.get_title() for ax in against_k0] == ["ground_young = 20 MPa", "ground_young = 50 MPa"]
    assert all(len(ax.get_lines()) == 3 for ax in against_k0)


def test_a_parameter_of_many_values_is_no_facet():
    """Every case its own K0 (12 values): K0 never gets a panel per value; against E the others are
    t (3 values) and K0 (12): t is the facet; against K0 itself E (2 values) is."""
    combined = three_parameter_grid()
    k0 = np.linspace(0.4, 1.4, combined.sizes["case"])
    combined = combined.assign_coords(loads_lateral_ratio=("case", k0))
    figure = plot_scalars(combined)
    panels = [ax for ax in figure.axes if ax.get_visible()]
    assert not any(ax.get_title().startswith("loads_lateral_ratio") for ax in panels)
    assert [ax.get_title() for ax in panels if ax.get_xlabel() == "ground_young (MPa)"] == [
        "lining_thickness = 0.2 m", "lining_thickness = 0.3 m", "lining_thickness = 0.4 m"]


def test_the_facets_of_a_row_share_their_scale():
    figure = plot_scalars(three_parameter_grid())
    row = [ax for ax in figure.axes if ax.get_visible() and ax.get_xlabel() == "lining_thickness (m)"]
    assert len(row) == 2 and row[0].get_ylim() == row[1].get_ylim()
    assert row[0].get_ylim()[0] <= 0.3 / 0.4 + 0.2 + 0.5 and row[0].get_ylim()[1] >= 0.3 / 0.2 + 0.5 + 1.0


def many_lines() -> xr.Dataset:
    """3 thicknesses × 8 ground stiffnesses: against thickness, eight lines coloured by E with a colour bar."""
    t, E = (a.ravel() for a in np.meshgrid([0.2, 0.3, 0.4], np.linspace(2e7, 9e7, 8), indexing="ij"))
    return xr.Dataset({"max_utilization": ("case", 0.3 / t + E / 1e8, {"units": "1"})},
                      coords={"case_id": ("case", [f"{i:016x}" for i in range(t.size)]),
                              "lining_thickness": ("case", t), "ground_young": ("case", E)})


@pytest.mark.parametrize("combined", [combined_results(), three_parameter_grid(), many_lines()],
                         ids=["grid", "faceted", "colour-bar"])
def test_the_scalars_panels_labels_stay_clear_of_the_other_panels_and_inside_the_figure(combined):
    """The scalars figure's fixed grid (no layout engine: :func:`workflows.plots._panel_grid`) leaves
    each panel room for its tick labels, axis labels and facet title: drawn, none reaches into
    another panel's axes or out of the figure, and the figure's title is above every panel."""
    combined = combined.assign(stage1_max_plastic_extent=("case", np.linspace(1.0, 2.0, combined.sizes["case"]),
                                                          {"units": "m"}))  # a long label
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    figure = plot_scalars(combined)
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    panels = [ax for ax in figure.axes if ax.get_visible()]  # colour bars too
    boxes = {ax: ax.get_tightbbox(renderer) for ax in panels}
    frame = figure.bbox
    title = figure._suptitle.get_window_extent(renderer)
    for ax, box in boxes.items():
        assert box.x0 >= frame.x0 - 0.5 and box.x1 <= frame.x1 + 0.5 and box.y0 >= frame.y0 - 0.5, ax.get_ylabel()
        assert box.y1 <= title.y0, ax.get_ylabel()
        for other in panels:
            if other is not ax and not _bar_of(other, ax) and not _bar_of(ax, other):
                assert not box.overlaps(other.get_window_extent(renderer)), (ax.get_ylabel(), other.get_ylabel())


def _bar_of(bar, ax) -> bool:
    """Whether ``bar`` is the colour bar drawn beside the panel ``ax`` (they touch by design)."""
    return bar.get_label() == "<colorbar>" and ax.get_label() != "<colorbar>" and \
        abs(bar.get_position().y0 - ax.get_position().y0) < 0.02 and 0 <= bar.get_position().x0 - ax.get_position().x1 < 0.05
