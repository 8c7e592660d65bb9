"""The lining's mesh at the joints (issue 37, SPEC §9.2): right at the default mesh.

The lining is graded towards every joint (hoop and radial elements of ``JOINT_EDGE`` ×
``interface_size`` at the strip's edges), so that at the default mesh the joint forces, the
contact's position in the strip (eccentricity) and the lining's moments are within 1 % of the
values on a joint refinement four times finer (which itself agrees with a mesh of every size
divided by four to 0.03 %, measured: docs/segmental.md). A monolithic ring's mesh is untouched.
"""
from __future__ import annotations

import numpy as np
import pytest

import solver.geometry.joints as joint_mesh
from solver import CaseSpec
from solver.geometry.mesh import build_mesh
from solver.run import run_case

PATTERNS = [
    {"count": 6, "offset": 0.0, "contact_height": 0.15},
    {"count": 6, "offset": 30.0, "contact_height": 0.15},
    {"count": 6, "offset": 0.0, "contact_height": 0.3},
]


def _joint_answer(joints: dict) -> dict:
    ds = run_case(CaseSpec.model_validate({"lining": {"joints": joints}}))
    return {name: ds[name].values.copy() for name in
            ("joint_moment", "joint_thrust", "joint_eccentricity", "max_abs_moment", "max_thrust")}


@pytest.mark.parametrize("joints", PATTERNS, ids=["6-0-half", "6-30-half", "6-0-full"])
def test_joint_forces_at_the_default_mesh_are_within_one_percent_of_a_four_times_finer_one(joints, monkeypatch):
    default = _joint_answer(joints)
    monkeypatch.setattr(joint_mesh, "JOINT_EDGE", joint_mesh.JOINT_EDGE / 4.0)
    fine = _joint_answer(joints)
    scale = np.max(np.abs(fine["joint_moment"]))
    np.testing.assert_allclose(default["joint_moment"], fine["joint_moment"], rtol=0, atol=0.01 * scale)
    np.testing.assert_allclose(default["joint_thrust"], fine["joint_thrust"], rtol=0.01)
    np.testing.assert_allclose(default["joint_eccentricity"], fine["joint_eccentricity"], rtol=0, atol=0.01)
    for name in ("max_abs_moment", "max_thrust"):
        assert float(default[name]) == pytest.approx(float(fine[name]), rel=0.01), name


def test_the_lining_is_graded_towards_each_joint_and_the_strip_ends_on_nodes():
    spec = CaseSpec.model_validate({"lining": {"joints": PATTERNS[0]}})
    mesh = build_mesh(spec)
    iface = mesh.interface
    theta = iface.theta[iface.vertex]
    spacing = np.diff(theta)
    at_joint = np.radians(spacing[np.isclose(theta[:-1], 60.0)][0]) * spec.geometry.hole_radius
    assert at_joint == pytest.approx(joint_mesh.JOINT_SIZE * joint_mesh.joint_edge(spec), rel=0.05)
    assert spacing.max() == pytest.approx(90.0 / 44, rel=0.05)  # the uniform interface size elsewhere
    # the graded zone spans about one thickness each side, growing at most JOINT_GROWTH
    zones = joint_mesh.graded_zones(spec)
    lengths = [np.radians(abs(z.end - z.start)) * spec.geometry.hole_radius for z in zones]
    assert all(0.3 * spec.geometry.thickness < length < 1.5 * spec.geometry.thickness for length in lengths)
    assert spacing[1:][spacing[1:] > 0].max() / spacing.min() > 10
    ratios = spacing[1:] / spacing[:-1]
    # the growth inside a zone; where it meets the uniform sector, that sector's count is rounded
    bound = joint_mesh.JOINT_GROWTH * 1.05
    assert np.all(ratios < bound) and np.all(1 / ratios < bound)
    # the strip's edges are lines of nodes of the joint's face
    r = np.hypot(*(mesh.lining.p[:, mesh.joints.before[1]] - np.asarray(mesh.center)[:, None]))
    mid = spec.geometry.inner_radius + 0.15
    for edge in (mid - 0.075, mid + 0.075):
        assert np.min(np.abs(r - edge)) < 1e-9
    assert np.min(np.diff(np.sort(r))) <= 2 * joint_mesh.joint_edge(spec) / 2 + 1e-12


def test_a_monolithic_ring_has_no_grading():
    spec = CaseSpec.model_validate({})
    assert joint_mesh.graded_zones(spec) == []
    assert len(joint_mesh.radial_pieces(spec)) == 1
