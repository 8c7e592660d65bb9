"""The section's profile (SPEC §9.4) as pure geometry: points, normals, arc length, curvature,
the polycentric closure, offsets, and the spec's refusals naming the field."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from solver import CaseSpec
from solver.errors import field_errors
from solver.geometry.section import (SectionError, circle, close_polycentric, ellipse, equal_area_radius,
                                     polycentric)
from solver.spec.section import Section

PHI = np.linspace(0.0, math.pi, 721)
HORSESHOE = {"shape": "horseshoe", "crown_radius": 5.5, "crown_angle": 100.0, "side_radius": 3.5, "side_angle": 50.0}


@pytest.mark.parametrize("split", [[90.0, 90.0], [30.0, 150.0], [45.0, 60.0, 75.0]])
def test_circle_as_equal_arcs(split):
    """A circle entered as arcs of one radius is the circle: the closure gives the same radius."""
    arcs = polycentric([2.5] * (len(split) - 1) + [None], split)
    assert arcs.arcs[-1].radius == pytest.approx(2.5, rel=1e-12)
    assert np.allclose(arcs.points(PHI), circle(2.5).points(PHI), atol=1e-12)
    assert arcs.length == pytest.approx(math.pi * 2.5, rel=1e-12)
    assert arcs.area() == pytest.approx(math.pi * 2.5**2, rel=1e-6)


def _closure_by_walking(radii, angles):
    """The end of the half profile walked arc by arc from the crown (x, y), by a different route
    than the module's: a fine polyline of each arc's tangent directions."""
    x = y = 0.0
    start = 0.0
    for r, a in zip(radii, angles):
        phi = np.linspace(start, start + math.radians(a), 20001)
        mid = 0.5 * (phi[1:] + phi[:-1])
        x += np.sum(r * np.diff(phi) * np.cos(mid))
        y -= np.sum(r * np.diff(phi) * np.sin(mid))
        start += math.radians(a)
    return x, y


@pytest.mark.parametrize("radii, angles", [([5.5, 3.5, None], [100.0, 50.0, 30.0]),
                                           ([4.0, 2.0, None], [60.0, 60.0, 60.0]),
                                           ([3.0, None], [70.0, 110.0])])
def test_closure(radii, angles):
    last = close_polycentric(radii, angles)
    x, y = _closure_by_walking([*radii[:-1], last], angles)
    assert abs(x) < 1e-6  # the profile ends on the axis
    p = polycentric(radii, angles)
    ends = p.points(np.array([0.0, math.pi]))
    assert ends[0] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert ends[1, 0] == pytest.approx(-ends[1, 1], rel=1e-12)  # the centre midway
    assert p.height == pytest.approx(-y, rel=1e-6)
    # tangent-continuous: the points on each side of every tangent point agree
    for b in p.breaks():
        near = p.points(np.array([b - 1e-9, b]))
        assert np.allclose(near[:, 0], near[:, 1], atol=1e-8)


@pytest.mark.parametrize("profile", [polycentric([5.5, 3.5, None], [100.0, 50.0, 30.0]), ellipse(8.0, 5.0),
                                     circle(3.0)])
@pytest.mark.parametrize("d", [0.3, 0.6])
def test_offsets(profile, d):
    """The offset is d away along the normal, which is the unit normal of the curve (the finite-
    difference tangent is perpendicular to it), and its curvature radius grows by d."""
    inner, outer = profile.points(PHI), profile.offset_by(d).points(PHI)
    assert np.allclose(np.hypot(*(outer - inner)), d, atol=1e-12)
    n = profile.normals(PHI)
    tangent = np.gradient(inner, PHI, axis=1)
    cos = np.sum(tangent * n, axis=0) / np.hypot(*tangent)
    assert np.max(np.abs(cos[5:-5])) < 1e-3
    kin, kout = profile.curvature(PHI), profile.offset_by(d).curvature(PHI)
    assert np.allclose(1.0 / kout - 1.0 / kin, d)
    # arc length: ∫ρ dφ against the polyline's length
    poly = np.sum(np.hypot(*np.diff(outer, axis=1)))
    assert profile.offset_by(d).length == pytest.approx(poly, rel=1e-4)


def test_ellipse():
    e = ellipse(8.0, 5.0)
    x, y = e.points(PHI)
    assert np.allclose((x / 4.0) ** 2 + (y / 2.5) ** 2, 1.0)
    assert e.curvature(np.array([0.0]))[0] == pytest.approx(2.5 / 4.0**2)  # b / a² at the crown
    assert e.curvature(np.array([math.pi / 2]))[0] == pytest.approx(4.0 / 2.5**2)  # a / b² at the side
    a, b = 4.0, 2.5
    h = ((a - b) / (a + b)) ** 2
    ramanujan = math.pi * (a + b) * (1 + 3 * h / (10 + math.sqrt(4 - 3 * h)))
    assert 2 * e.length == pytest.approx(ramanujan, rel=1e-5)
    assert e.area() == pytest.approx(math.pi * a * b, rel=1e-6)
    assert equal_area_radius(e) == pytest.approx(math.sqrt(a * b), rel=1e-6)


def test_horseshoe_template_expands_to_polycentric():
    s = Section.model_validate(HORSESHOE)
    assert s.shape == "polycentric" and [a.angle for a in s.arcs] == [100.0, 50.0, 30.0]
    assert s.arcs[-1].radius is None  # the solved radius is not stored: one form per profile
    same = Section.model_validate({"shape": "polycentric", "arcs": [
        {"radius": 5.5, "angle": 100.0}, {"radius": 3.5, "angle": 50.0},
        {"radius": close_polycentric([5.5, 3.5, None], [100.0, 50.0, 30.0]), "angle": 30.0}]})
    assert same == s


@pytest.mark.parametrize("section, field", [
    ({"shape": "polycentric", "arcs": [{"radius": 5.0, "angle": 60.0}, {"radius": 1.0, "angle": 120.0}]},
     "geometry.section.arcs.1.radius"),  # a given last radius that does not close
    ({"shape": "polycentric", "arcs": [{"radius": 1.0, "angle": 150.0}, {"radius": 10.0, "angle": 20.0},
                                       {"angle": 10.0}]}, "geometry.section.arcs.2.radius"),  # no positive radius
    ({"shape": "polycentric", "arcs": [{"radius": 1.0, "angle": 30.0}, {"angle": 120.0}]},
     "geometry.section.arcs.1.angle"),  # angles not summing to 180
    ({"shape": "ellipse", "width": 6.0}, "geometry.section.height"),
    ({"shape": "circle", "arcs": [{"radius": 1.0, "angle": 180.0}]}, "geometry.section.arcs"),
    ({**HORSESHOE, "side_angle": 80.0}, "geometry.section.side_angle"),
    ({"shape": "horseshoe", "crown_radius": 5.0}, "geometry.section.crown_angle"),
])
def test_refused_naming_the_field(section, field):
    with pytest.raises(ValidationError) as err:
        CaseSpec.model_validate({"geometry": {"section": section}})
    assert field_errors(err.value)[0][0] == field


def test_circle_keeps_its_id():
    assert CaseSpec.model_validate({"geometry": {"section": {"shape": "circle"}}}).case_id == CaseSpec().case_id
    assert "section" not in CaseSpec().canonical_json()


def test_the_last_radius_is_checked():
    with pytest.raises(SectionError, match="arcs.1.radius"):
        polycentric([2.0, 3.0], [90.0, 90.0])


def test_joints_and_layer_lines_through_a_shaped_section_are_accepted():
    geometry = {"section": HORSESHOE, "thickness": 0.3, "depth": 25.0, "width": 60.0, "height": 70.0}
    CaseSpec.model_validate({"geometry": geometry, "lining": {"joints": {"count": 6}}})
    for top in (10.0, 25.0):  # a layer line above it and one through it
        CaseSpec.model_validate({"geometry": geometry, "ground": {"layers": [{"thickness": top}, {"thickness": 0.0}]}})


def test_a_bend_sharper_than_the_mesh_and_a_section_out_of_bounds_are_refused():
    plain = {"design": {"reinforcement_area": 0.0}}
    with pytest.raises(ValidationError) as err:  # the sidewall bends on 0.14 m: 0.1 m elements cannot follow
        CaseSpec.model_validate({"geometry": {"section": {"shape": "ellipse", "width": 12.0, "height": 1.5},
                                              "thickness": 0.05}, **plain})
    assert field_errors(err.value)[0][0] == "mesh.interface_size"
    with pytest.raises(ValidationError) as err:  # larger than inner_radius may be
        CaseSpec.model_validate({"geometry": {"section": {"shape": "polycentric", "arcs": [{"radius": 60.0, "angle": 90.0},
                                                                                          {"angle": 90.0}]}}})
    assert field_errors(err.value)[0][0] == "geometry.section"
    # the canonical JSON of a shaped section holds its equal-area radius and validates again
    spec = CaseSpec.model_validate({"geometry": {"section": {"shape": "ellipse", "width": 6.0, "height": 4.0}}})
    assert spec.geometry.inner_radius == pytest.approx(math.sqrt(3.0 * 2.0))
    assert CaseSpec.model_validate_json(spec.canonical_json()).case_id == spec.case_id
