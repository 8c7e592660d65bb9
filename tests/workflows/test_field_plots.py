"""Field figures of one case (workflows.field_plots) on real results: what each panel shows."""
from __future__ import annotations

import numpy as np
import pytest

from solver.run import run_case
from solver.spec import CaseSpec
from workflows.field_plots import plot_contours, plot_deformed_mesh

COARSE = {"interface_size": 0.15, "far_size": 6.0}


def _panels(figure):
    return [ax for ax in figure.axes if ax.get_visible() and ax.get_label() != "<colorbar>"]


@pytest.fixture(scope="module")
def yielding_wet():
    """Mohr-Coulomb ground that yields, under a water table (watertight lining)."""
    return run_case(CaseSpec.model_validate({"mesh": COARSE, "water": {"table": 5.0}, "ground": {
        "model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 28.0, "tensile_strength": 1.0e4}}))


def test_dry_elastic_case_has_displacement_and_three_stress_panels_each_with_a_colour_bar():
    ds = run_case(CaseSpec.model_validate({"mesh": COARSE}))
    figure = plot_contours(ds)
    titles = [ax.get_title() for ax in _panels(figure)]
    assert [t.split(" ")[0] for t in titles] == ["|u|", "σ'xx", "σ'yy", "τxy"]
    assert sum(ax.get_label() == "<colorbar>" for ax in figure.axes) == 4
    assert "stays elastic" in figure._suptitle.get_text()
    # the displacement panel's colour range is the displacements near the tunnel, in mm
    levels = getattr(_panels(figure)[0].collections[0], "levels", None)
    near = np.hypot(ds["node_x"].values, ds["node_y"].values + 15.0) < 3.0
    umax = 1e3 * np.hypot(ds["displacement_x"].values, ds["displacement_y"].values)[near].max()
    assert levels is not None and levels[-1] >= umax * 0.999


def test_yielding_wet_case_adds_pore_pressure_and_plastic_strain_and_outlines_the_yielded_zone(yielding_wet):
    ds = yielding_wet
    assert float(ds["plastic_area"]) > 0
    figure = plot_contours(ds)
    panels = _panels(figure)
    assert [ax.get_title().split(" ")[0] for ax in panels] == ["|u|", "σ'xx", "σ'yy", "τxy", "p", "ε̄p"]
    for ax in panels:  # the yielded zone's boundary on every panel
        outlines = [c for c in ax.collections if c.get_label() == "yielded zone"]
        assert len(outlines) == 1 and len(outlines[0].get_segments()) > 10
    pore = next(ax for ax in panels if ax.get_title().startswith("p "))
    faces = pore.collections[0].get_array()
    assert faces.max() == pytest.approx(ds["pore_pressure"].values[ds["body"].values == 0].max() / 1e3)


def test_deformed_mesh_magnifies_the_rings_own_deformation_and_colours_by_displacement(yielding_wet):
    ds = yielding_wet
    figure = plot_deformed_mesh(ds)
    ax = figure.axes[0]
    ring = ds["lining_node"].values.astype(int)
    uy = ds["displacement_y"].values[ring]
    own = np.hypot(ds["displacement_x"].values[ring], uy - uy.mean()).max()
    cy = float(np.mean(ds["interface_y"].values[[0, -1]]))
    radius = float(np.max(np.hypot(ds["interface_x"].values, ds["interface_y"].values - cy)))
    scale = float(ax.get_title().split("×")[1].split(",")[0])
    assert scale * own == pytest.approx(0.12 * radius, rel=1e-2)
    assert any(c.get_label() == "yielded zone" for c in ax.collections)
    assert figure.axes[1].get_label() == "<colorbar>"
