"""CaseSpec validation, case ids, and the mesh contract."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from pydantic import BaseModel, ValidationError

from solver import CaseSpec
from solver.errors import field_errors
from solver.geometry.mesh import build_mesh
from solver.geometry.sizing import MAX_ELEMENTS, estimated_elements


def test_default_case_and_stable_id():
    a = CaseSpec()
    b = CaseSpec.model_validate_json("{}")
    c = CaseSpec.model_validate({"geometry": {"thickness": 0.3}, "lining": {"young": 3e10}})
    assert a.case_id == b.case_id == c.case_id
    assert len(a.case_id) == 16 and int(a.case_id, 16) >= 0
    assert CaseSpec(geometry=dict(thickness=0.35)).case_id != a.case_id
    canon = json.loads(a.canonical_json())
    assert canon["solver"]["bolt"] == "auto" and list(canon) == sorted(canon)
    with pytest.raises(ValidationError):  # frozen
        a.geometry.thickness = 1.0  # type: ignore[misc]


@pytest.mark.parametrize("patch, field, reason", [
    ({"ground": {"poisson": 0.5}}, "ground.poisson", "less than or equal to 0.49"),
    ({"ground": {"young": float("inf")}}, "ground.young", "finite number"),
    ({"lining": {"young": float("nan")}}, "lining.young", "finite number"),
    ({"loads": {"surface_load": float("inf")}}, "loads.surface_load", "finite number"),
    ({"interface": {"model": "coulomb"}}, "interface", "friction: interface.model 'coulomb' needs"),
    ({"interface": {"friction": float("nan")}}, "interface.friction", "finite number"),
    ({"excavation": {"deconfinement": 1.5}}, "excavation.deconfinement", "less than or equal to 1"),
    ({"excavation": {"method": "cut-and-cover"}}, "excavation.method", "'deconfinement' or 'wished-in-place'"),
    ({"design": {"reinforcement_area": 0.001, "axis_distance": 0.2}}, "", "design.axis_distance"),
    ({"design": {"reinforcement_area": 0.01}}, "", "design.reinforcement_area"),
    ({"ground": {"young": 1e5}, "lining": {"young": 1e12}}, "", "lining.young: lining / ground stiffness ratio"),
    ({"lining": {"poisson": -0.1}}, "lining.poisson", "greater than or equal to 0"),
    ({"ground": {"young": 0}}, "ground.young", "greater than or equal to 100000"),
    ({"lining": {"density": 0}}, "lining.density", "greater than 0"),
    ({"loads": {"gravity": 0}}, "loads.gravity", "greater than or equal to 1"),
    ({"geometry": {"thickness": -0.1}}, "geometry.thickness", "greater than 0"),
    ({"geometry": {"depth": 3.0}}, "geometry", "depth: cover above"),
    ({"geometry": {"height": 17.0}}, "geometry", "height: room below"),
    ({"geometry": {"width": 3.0}}, "geometry", "width: room beside"),
    ({"geometry": {"gap": 0.5}}, "geometry", "gap:"),
    ({"mesh": {"interface_size": 1e-3, "far_size": 0.5}}, "", "mesh.interface_size: this mesh would have"),
    ({"mesh": {"far_size": 0.05}}, "", "mesh.far_size"),
    ({"solver": {"inner": "newton"}}, "solver.inner", "'active-set' or 'uzawa'"),
    ({"solver": {"bolt": 200.0}}, "solver.bolt", "outside [0, 180]"),
    ({"boundaries": {"side": "free"}}, "boundaries.side", "'fixed', 'roller' or 'pressure'"),
    ({"geometry": {"radius": 3.0}}, "geometry.radius", "Extra inputs are not permitted"),
    ({"colour": "red"}, "colour", "Extra inputs are not permitted"),
])
def test_invalid_cases_name_the_field(patch, field, reason):
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate(patch)
    errors = err.value.errors()
    locs = [".".join(str(p) for p in e["loc"] if not str(p).startswith("function-after")) for e in errors]
    assert any(loc == field or loc.startswith(field + ".") for loc in locs), locs
    assert reason in str(err.value)


def _numeric_fields(model=CaseSpec, prefix=""):
    """Dotted paths and annotations of every numeric leaf field of the case."""
    for name, info in model.model_fields.items():
        if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel):
            yield from _numeric_fields(info.annotation, f"{prefix}{name}.")
        elif info.annotation in (float, int) or "float" in str(info.annotation):
            yield f"{prefix}{name}"


NUMERIC_FIELDS = list(_numeric_fields())


def _patch(path, value):
    *parents, name = path.split(".")
    data = {name: value}
    if parents[-1] == "joints":  # a joint field is checked on a segmental ring
        data = {"count": 6, **data} if name != "count" else data
    for key in reversed(parents):
        data = {key: data}
    return data


#: Fields where null means something (a dry ground, a strip as high as the lining, the case's own ground
#: loss, no face distance, a field the section's shape does not use).
NULLABLE = {"water.table", "lining.joints.contact_height", "settlement.volume_loss", "excavation.face_distance",
            *(f"geometry.section.{k}" for k in ("width", "height", "crown_radius", "crown_angle", "side_radius",
                                                 "side_angle"))}


def test_every_numeric_field_is_found():
    assert len(NUMERIC_FIELDS) > 25 and "geometry.thickness" in NUMERIC_FIELDS and "solver.bolt" in NUMERIC_FIELDS


@pytest.mark.parametrize("path", NUMERIC_FIELDS)
@pytest.mark.parametrize("value", [True, False, "0.5", "1", None, [1.0]])
def test_a_number_must_be_a_number(path, value):
    """Lax validation took JSON ``true`` as 1.0 (a 1 m lining) and "0.5" as 0.5."""
    if value is None and path in NULLABLE:
        assert CaseSpec.model_validate(_patch(path, value))
        return
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate(_patch(path, value))
    assert [field for field, _ in field_errors(err.value)] == [path]


def test_integers_stay_integers_and_floats_take_integers():
    assert CaseSpec.model_validate({"solver": {"max_iterations": 500}}).solver.max_iterations == 500
    with pytest.raises(ValidationError, match="valid integer"):
        CaseSpec.model_validate({"solver": {"max_iterations": 500.0}})
    spec = CaseSpec.model_validate_json('{"geometry": {"depth": 20}, "solver": {"bolt": 30}}')
    assert spec.geometry.depth == 20.0 and isinstance(spec.geometry.depth, float) and spec.solver.bolt == 30.0
    assert spec.case_id == CaseSpec.model_validate({"geometry": {"depth": 20.0}, "solver": {"bolt": 30.0}}).case_id


def test_bonded_interface_refuses_a_clearance():
    """[u]ν = 0 with g0 > 0 glued a lining 20 mm away to the ground at full pressure."""
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate({"interface": {"model": "bonded"}, "geometry": {"gap": 0.02}})
    assert field_errors(err.value)[0][0] == "geometry.gap"
    assert "cannot be bonded" in str(err.value)
    CaseSpec.model_validate({"interface": {"model": "bonded"}})
    for model in ({"model": "frictionless"}, {"model": "coulomb", "friction": 0.3}):
        CaseSpec.model_validate({"interface": model, "geometry": {"gap": 0.02}})


def test_element_cap_is_stated_and_estimate_is_close():
    spec = CaseSpec()
    n = estimated_elements(spec)
    mesh = build_mesh(spec)
    actual = mesh.ground.t.shape[1] + mesh.lining.t.shape[1]
    assert 0.7 * actual < n < 1.3 * actual
    assert MAX_ELEMENTS >= 100_000


@pytest.mark.parametrize("gap", [0.0, 0.01])
def test_mesh_contract(gap):
    spec = CaseSpec(geometry=dict(gap=gap, thickness=0.2), mesh=dict(interface_size=0.1, far_size=4.0))
    mesh = build_mesh(spec)
    iface = mesh.interface
    c = np.array(mesh.center)
    # interface ordered crown to invert, duplicated per body, matched in angle
    assert iface.theta[0] == 0 and iface.theta[-1] == 180 and np.all(np.diff(iface.theta) > 0)
    pg = mesh.ground.p[:, iface.ground_node]
    pl = mesh.lining.p[:, iface.lining_node]
    np.testing.assert_allclose(np.hypot(*(pg - c[:, None])), spec.geometry.hole_radius, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(*(pl - c[:, None])), spec.geometry.outer_radius, rtol=1e-12)
    # normals: unit, towards the tunnel axis
    np.testing.assert_allclose(np.hypot(*iface.normal), 1.0)
    assert np.all(np.sum(iface.normal * (c[:, None] - pg), axis=0) > 0)
    # Simpson weights on the arc: they sum to the half circumference, 1:4:1 per edge
    assert iface.weight.sum() == pytest.approx(math.pi * spec.geometry.hole_radius, rel=1e-12)
    np.testing.assert_allclose(iface.weight[1:-1:2] / (iface.weight[0] * 4), 1.0, rtol=1e-6)
    # at least two quadratic elements through the lining thickness, vertices on layer circles
    assert mesh.layers >= 2
    r = np.hypot(*(mesh.lining.p[:, :mesh.lining.n_vertices] - c[:, None]))
    assert np.unique(np.round(r, 9)).size == mesh.layers + 1
    # edge nodes on the interface lie on the circle (curved, isoparametric edges)
    assert np.all(~iface.vertex[1::2]) and np.all(iface.vertex[0::2])
    # triangles counter-clockwise, all positive area
    for body in (mesh.ground, mesh.lining):
        x, y = body.p[:, body.t[:3]]
        area = 0.5 * ((x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]))
        assert area.min() > 0
    # interface element size near the requested one
    seg = np.diff(np.radians(iface.theta[iface.vertex])) * spec.geometry.hole_radius
    assert seg.max() <= spec.mesh.interface_size * 1.0001
    # every edge node: on a circle arc of the body (the hole; the lining's outer and inner
    # surfaces) at the arc's point halfway in angle between the edge's vertices, else the
    # edge's midpoint; the arcs' edges are exactly those with both vertices on the circle
    # along the boundary (half the interface nodes less one per arc)
    arcs = {"ground": [spec.geometry.hole_radius],
            "lining": [spec.geometry.outer_radius, spec.geometry.inner_radius]}
    for name, body in (("ground", mesh.ground), ("lining", mesh.lining)):
        pairs = np.array([[0, 1], [1, 2], [0, 2]])
        v1, v2 = (body.p[:, body.t[pairs[:, k]]] for k in range(2))  # (2, 3, E)
        e = body.p[:, body.t[3:]]
        straight = np.hypot(*(e - 0.5 * (v1 + v2)))
        r = [np.hypot(*(x - c[:, None, None])) for x in (v1, v2, e)]
        ang = [np.arctan2(*(x - c[:, None, None])[::-1]) for x in (v1, v2, e)]
        curved = np.zeros(e.shape[1:], bool)
        for radius in arcs[name]:
            on = np.isclose(r[0], radius, rtol=1e-12) & np.isclose(r[1], radius, rtol=1e-12)
            np.testing.assert_allclose(r[2][on], radius, rtol=1e-12)
            np.testing.assert_allclose(ang[2][on], 0.5 * (ang[0][on] + ang[1][on]), rtol=0, atol=1e-12)
            curved |= on
        assert np.all(straight[~curved] <= 1e-12 * max(spec.geometry.width, spec.geometry.height))
        edges_on_arcs = np.unique(body.t[3:][curved]).size
        assert edges_on_arcs == len(arcs[name]) * (iface.size - 1) // 2


def test_friction_is_ignored_outside_coulomb_so_one_physical_case_has_one_id():
    bonded = CaseSpec.model_validate({"interface": {"model": "bonded"}})
    assert CaseSpec.model_validate({"interface": {"model": "bonded", "friction": 0.3}}).case_id == bonded.case_id
    assert CaseSpec.model_validate({"interface": {"friction": 0.3}}) == CaseSpec()
    coulomb = CaseSpec.model_validate({"interface": {"model": "coulomb", "friction": 0.3}})
    assert coulomb.interface.friction == 0.3 and coulomb.case_id != bonded.case_id


def test_deconfinement_is_ignored_when_wished_in_place_so_one_physical_case_has_one_id():
    """Wished-in-place gave identical results for λd = 0 and 0.5 under two ids, and kept 0.5
    in the record as if it had acted."""
    wip = {"method": "wished-in-place"}
    ids = {CaseSpec.model_validate({"excavation": {**wip, **extra}}).case_id
           for extra in ({}, {"deconfinement": 0.0}, {"deconfinement": 0.5}, {"deconfinement": 1}, {"deconfinement": 0.3})}
    assert len(ids) == 1
    spec = CaseSpec.model_validate({"excavation": {**wip, "deconfinement": 0.5}})
    assert spec.excavation.deconfinement == 0.0
    assert CaseSpec.model_validate_json(spec.canonical_json()).case_id == spec.case_id
    staged = {CaseSpec.model_validate({"excavation": {"deconfinement": x}}).case_id for x in (0.0, 0.5)}
    assert len(staged) == 2  # where it acts, it counts
    for bad in (float("nan"), True, "0.5"):
        with pytest.raises(ValidationError):
            CaseSpec.model_validate({"excavation": {**wip, "deconfinement": bad}})
