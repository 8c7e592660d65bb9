"""Segmental linings on sections beyond the circle (SPEC §9.4, §1.6): the joints are cuts normal to
the mid-surface through the excavation's point at each joint's polar angle, the lining graded
towards them along its length (in arc length) and through its thickness as on a circle.

Checked: a circle entered as two arcs with joints is the segmental circle; on a horseshoe the
joints lie on the lining's normals, the thrust acts inside every strip, the joint forces are the
section forces on the same normal cut, every segment is balanced and KKT holds; bonded
full-height joints that stay closed are the monolithic horseshoe."""
from __future__ import annotations

import numpy as np
import pytest

from solver import CaseSpec
from solver.lining.forces import lining_forces
from solver.model import TunnelModel

HORSESHOE = {"geometry": {"section": {"shape": "horseshoe", "crown_radius": 5.5, "crown_angle": 100.0,
                                      "side_radius": 3.5, "side_angle": 50.0},
                          "thickness": 0.3, "depth": 25.0, "width": 60.0, "height": 70.0},
             "ground": {"young": 2.0e8}, "mesh": {"interface_size": 0.25, "far_size": 8.0}}
TWO_ARCS = {"section": {"shape": "polycentric", "arcs": [{"radius": 2.5, "angle": 90.0}, {"angle": 90.0}]}}


def _forces(model, sol):
    return lining_forces(sol.spec, model.lining.body, model.mesh.interface, model.mesh.center, sol.u_lining,
                         sol.lam, sol.shear, profile=model.mesh.profile)


def _solve(case: dict):
    spec = CaseSpec.model_validate(case)
    model = TunnelModel(spec)
    return model, model.solve(spec)


@pytest.mark.parametrize("joints", [{"count": 6, "contact_height": 0.15},
                                    {"count": 6, "offset": 30.0, "contact_height": 0.3}])
def test_joints_on_a_circle_entered_as_two_arcs_are_the_circle_s(joints):
    """The same six-segment ring through the circle's path and the polycentric one (normal cuts
    found by the turning angle, hoop grading in arc length): joint thrust, moment and opening,
    and the ring's moment, agree to the meshes' difference (the ground is meshed from arcs on
    one, polylines on the other)."""
    base = {"mesh": {"interface_size": 0.2, "far_size": 8.0}, "lining": {"joints": joints}}
    circle_model, circle = _solve(base)
    arcs_model, arcs = _solve({**base, "geometry": TWO_ARCS})
    np.testing.assert_allclose(arcs.joints.theta, circle.joints.theta, atol=1e-9)
    assert arcs_model.mesh.joints.size == circle_model.mesh.joints.size
    assert list(arcs.joints.open) == list(circle.joints.open)
    scale_n, scale_m = circle.joints.thrust.max(), np.abs(circle.joints.moment).max()
    assert np.max(np.abs(arcs.joints.thrust - circle.joints.thrust)) < 2e-3 * scale_n
    assert np.max(np.abs(arcs.joints.moment - circle.joints.moment)) < 5e-3 * scale_m
    f0, f1 = _forces(circle_model, circle), _forces(arcs_model, arcs)
    theta = circle_model.mesh.interface.theta
    other = np.interp(theta, arcs_model.mesh.interface.theta, f1.moment)
    assert np.max(np.abs(other - f0.moment)) < 5e-3 * np.abs(f0.moment).max()


@pytest.fixture(scope="module")
def horseshoe():
    return _solve({**HORSESHOE, "lining": {"joints": {"count": 6, "offset": 30.0, "contact_height": 0.15}}})


def test_horseshoe_joints_cut_the_lining_along_its_normals(horseshoe):
    """Each joint's faces lie on one normal of the mid-surface (the line through the excavation's
    point at the joint's polar angle), their nodes evenly matched across the cut, the strip's
    edges on nodes, and the lining's segments numbered crown to invert."""
    model, _ = horseshoe
    mesh = model.mesh
    cut, p, c = mesh.joints, mesh.lining.p, np.asarray(mesh.center, float)[:, None]
    assert cut.size == 3 and cut.segments == 4  # joints at 30, 90 and 150 deg, none on the axis
    for j in range(cut.size):
        phi = np.radians(cut.normal[j])
        normal, tangent = np.array([np.sin(phi), np.cos(phi)]), np.array([np.cos(phi), -np.sin(phi)])
        for face in (cut.before[j], cut.after[j]):
            if face.size:
                assert np.ptp(tangent @ (p[:, face] - c)) < 1e-9  # on one line along the normal
                assert np.all(np.diff(normal @ p[:, face]) > 0)  # from the intrados out
        if cut.before[j].size and cut.after[j].size:
            np.testing.assert_allclose(p[:, cut.before[j]], p[:, cut.after[j]], atol=1e-12)
        across = cut.across[j]
        assert across[0] == pytest.approx(-0.15, abs=1e-9) and across[-1] == pytest.approx(0.15, abs=1e-9)
        assert np.min(np.abs(np.abs(across) - 0.075)) < 1e-9  # the strip's edges are nodes
        rel = mesh.interface.theta - cut.theta[j]
        assert np.min(np.abs(rel)) < 1e-9  # a station exactly at the joint
    mean = [np.mean(np.degrees(np.arctan2(*(p[:, cut.segment == s] - c)))) for s in range(cut.segments)]
    assert np.all(np.diff(mean) > 0)


def test_horseshoe_joints_carry_the_section_forces_inside_their_strips(horseshoe, imbalance):
    """|M| ≤ N a/2 at every joint; the joints' own forces (strip tractions) are the section forces
    on the same normal cut (nodal forces) to round-off; every segment's rigid modes balance; KKT."""
    model, sol = horseshoe
    j = sol.joints
    assert np.all(j.thrust > 0) and np.all(j.eccentricity_ratio <= 1 + 1e-9)
    f = _forces(model, sol)
    at = [int(np.argmin(np.abs(model.mesh.interface.theta - t))) for t in j.theta]
    np.testing.assert_allclose(j.thrust, f.thrust[at], rtol=1e-8)
    np.testing.assert_allclose(j.moment, f.moment[at], rtol=1e-8, atol=1e-8 * np.abs(f.moment).max())
    assert sol.kkt_residual < 1e-9
    assert imbalance(model, sol) < 1e-10


def test_bonded_closed_joints_on_a_horseshoe_are_the_monolithic_horseshoe():
    """Full-height bonded joints that stay closed transmit what the continuous section does:
    thrust, moment and contact pressure of the monolithic horseshoe to the meshes' difference
    (the joints add sector lines and the grading)."""
    loads = {"loads": {"lateral_ratio": 1.0}}
    mono_model, mono = _solve({**HORSESHOE, **loads})
    seg_model, seg = _solve({**HORSESHOE, **loads, "lining": {"joints": {"count": 5}}})
    assert not seg.joints.open.any()
    f0, f1 = _forces(mono_model, mono), _forces(seg_model, seg)
    th0, th1 = mono_model.mesh.interface.theta, seg_model.mesh.interface.theta
    for a, b, tol in ((f0.thrust, f1.thrust, 1e-3), (f0.moment, f1.moment, 1e-2), (mono.lam, seg.lam, 5e-3)):
        assert np.max(np.abs(np.interp(th0, th1, b) - a)) <= tol * np.max(np.abs(a))


def test_the_figures_find_a_horseshoe_s_joint_faces_on_their_normal_cuts(horseshoe):
    """The mesh figures find each joint's faces from the stored dataset alone (the lining's normal
    through the joint's station): the solver's faces, node for node, ordered from the intrados
    out, crown-side face first."""
    from solver.results.dataset import to_dataset
    from workflows.joint_plots import joint_faces

    model, sol = horseshoe
    ds = to_dataset(model, sol, software_version="test")
    xy = np.stack([ds["node_x"].values, ds["node_y"].values])
    cut = model.mesh.joints
    found = joint_faces(ds)
    assert len(found) == cut.size
    for j, (theta, _, faces) in enumerate(found):
        assert theta == pytest.approx(cut.theta[j])
        expected = [f for f in (cut.before[j], cut.after[j]) if f.size]
        assert len(faces) == len(expected)
        for face, nodes in zip(faces, expected):
            np.testing.assert_allclose(xy[:, face], model.mesh.lining.p[:, nodes], atol=1e-9)


SHAPES = [HORSESHOE["geometry"]["section"], {"shape": "ellipse", "width": 9.0, "height": 7.0},
          {"shape": "polycentric", "arcs": [{"radius": 4.0, "angle": 60.0}, {"radius": 2.5, "angle": 70.0},
                                            {"angle": 50.0}]}]


@pytest.mark.parametrize("seed", range(6))
def test_a_sample_of_segmental_sections_with_a_layer_line(seed, imbalance):
    """A seeded sample over the space a study samples: three shapes, 4–10 segments, both symmetric
    offsets, strips of a third to the whole thickness, K0 0.4–1.2, a layer line at a random depth
    (through the section or not): each meshes, solves with the contact's KKT conditions, every
    joint's thrust compressive and inside its strip, every segment balanced."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 11))
    case = {"geometry": {**HORSESHOE["geometry"], "section": SHAPES[seed % 3]},
            "ground": {"young": 1e8, "layers": [{"thickness": float(rng.uniform(18.0, 32.0)), "young": 5e7},
                                                {"thickness": 0.0, "young": 2e8}]},
            "loads": {"lateral_ratio": float(rng.uniform(0.4, 1.2))},
            "lining": {"joints": {"count": n, "offset": float(rng.choice([0.0, 180.0 / n])),
                                  "contact_height": float(rng.choice([0.1, 0.15, 0.3]))}},
            "mesh": {"interface_size": 0.25, "far_size": 8.0}}
    model, sol = _solve(case)
    j = sol.joints
    assert sol.kkt_residual < 1e-8
    assert np.all(j.thrust > 0) and j.eccentricity_ratio.max() <= 1 + 1e-9
    assert imbalance(model, sol) < 1e-9
