"""Segmental linings (issue 26, SPEC §1.6): joints that open, as contact, and segments that float.

The physics checked: bonded full-height joints that stay closed are the monolithic lining; the
thrust at every joint acts inside its contact strip; a full-height joint opens where the
eccentricity passes the kern a/6 (the linear stress distribution's limit) and not below; open
joints rotate more than closed ones; six segments lower the default case's moments. The method
checked: every segment's rigid modes are balanced and solved for (not pinned), the generalized
bolt method is the paper's on a one-mode lining, and a segment nothing can hold is named.
"""
from __future__ import annotations

import numpy as np
import pytest

from solver import CaseSpec, run_case
from solver.contact.bolt import solve_contact
from solver.lining.design import interaction_envelope, joint_utilization
from solver.contact.floating import EQUALITY, UNILATERAL, DriftError, FloatingProblem, kkt, solve_floating
from solver.model import TunnelModel
from solver.lining.forces import lining_forces
import solver.stages.contact as contact_stage

MESH = {"interface_size": 0.2, "far_size": 8.0}


def _solve(**sections):
    spec = CaseSpec.model_validate({"mesh": MESH, **sections})
    model = TunnelModel(spec)
    return model, model.solve(spec)


def _forces(model, sol):
    return lining_forces(sol.spec, model.lining.body, model.mesh.interface, model.mesh.center, sol.u_lining,
                         sol.lam, sol.shear)


@pytest.mark.parametrize("count", [5, 6])
def test_bonded_full_height_closed_joints_are_the_monolithic_lining(count):
    """Under nearly isotropic stress (K0 = 0.95) every joint stays closed; a bonded full-height
    joint then transmits what the continuous section does. The meshes differ only where the
    joints add sector lines, so the lining's forces and the contact pressure agree to the
    discretization (measured: thrust 0.002 %, moment 0.17 % of the largest, pressure 0.04 %)."""
    loads = {"lateral_ratio": 0.95}
    mono_model, mono = _solve(loads=loads)
    seg_model, seg = _solve(loads=loads, lining={"joints": {"count": count}})
    assert not seg.joints.open.any()
    f0, f1 = _forces(mono_model, mono), _forces(seg_model, seg)
    th0, th1 = mono_model.mesh.interface.theta, seg_model.mesh.interface.theta
    for a, b, tol in ((f0.thrust, f1.thrust, 2e-4), (f0.moment, f1.moment, 5e-3), (mono.lam, seg.lam, 2e-3)):
        b_on_a = np.interp(th0, th1, b)
        assert np.max(np.abs(b_on_a - a)) <= tol * np.max(np.abs(a))
    # and the joints' own forces are the section forces at their stations, exactly
    at = [int(np.argmin(np.abs(th1 - t))) for t in seg.joints.theta]
    np.testing.assert_allclose(seg.joints.thrust, f1.thrust[at], rtol=1e-9)
    np.testing.assert_allclose(seg.joints.moment, f1.moment[at], rtol=1e-9, atol=1e-9 * np.abs(f1.moment).max())


@pytest.mark.parametrize("case", [
    {"lining": {"joints": {"count": 6, "contact_height": 0.15}}},
    {"lining": {"joints": {"count": 6, "offset": 30.0, "contact_height": 0.1}}},
    {"lining": {"joints": {"count": 5, "contact_height": 0.2, "shear": "coulomb", "friction": 0.3}},
     "interface": {"model": "coulomb", "friction": 0.4}},
    {"lining": {"joints": {"count": 8, "contact_height": 0.15}}, "interface": {"model": "bonded"},
     "loads": {"lateral_ratio": 0.6}},
])
def test_the_thrust_acts_inside_the_strip_at_every_joint(case):
    """|M| ≤ N a/2 at every joint (the contact tractions are compressive over the strip), the
    joint forces are the section forces at the joint, every segment is balanced, KKT holds."""
    model, sol = _solve(**case)
    j = sol.joints
    assert np.all(j.thrust > 0)
    assert np.all(j.eccentricity_ratio <= 1 + 1e-9)
    assert j.eccentricity_ratio.max() > 0.5  # the cases are chosen so that some joint is well loaded
    f = _forces(model, sol)
    at = [int(np.argmin(np.abs(model.mesh.interface.theta - t))) for t in j.theta]
    np.testing.assert_allclose(j.thrust, f.thrust[at], rtol=1e-8)
    np.testing.assert_allclose(j.moment, f.moment[at], rtol=1e-8, atol=1e-8 * np.abs(f.moment).max())
    assert sol.kkt_residual < 1e-9


def test_a_full_height_joint_opens_where_the_eccentricity_passes_the_kern():
    """With a = t the strip is the whole section: its stress stays linear and compressive while
    e = |M|/N ≤ a/6. Over K0 from 0.6 to 1 the joints with e/a below 0.15 are closed and those
    above 0.185 open (measured: closed up to 0.166, open from 0.174)."""
    closed, opened = [], []
    for k0 in (0.6, 0.75, 0.8, 0.85, 0.9, 1.0):
        _, sol = _solve(loads={"lateral_ratio": k0}, lining={"joints": {"count": 6}})
        j = sol.joints
        ratio = np.abs(j.moment) / j.thrust / 0.3
        closed += list(j.open[ratio < 0.15])
        opened += list(j.open[ratio > 0.185])
    assert len(closed) >= 8 and len(opened) >= 6
    assert not any(closed) and all(opened)


def test_open_joints_rotate_more_than_closed_ones():
    """A closed joint is a linear rotational spring: its faces' relative rotation per unit moment
    is the same at every closed joint and load (measured 7.9-8.1e-9 rad per N·m/m for a = 0.15 m,
    t = 0.3 m on the mesh graded towards the joints; 5.1-5.6e-9 before it, too stiff); a joint
    that has opened wide is softer (K0 = 0.8: the crown and invert joints, 1.5e-8 and 1.6e-8; the
    120° joint has just opened, 0.8 µm, and is still as stiff as a closed one), its faces gape over
    the strip (opening > 0) where a closed joint's stay in contact, and its rotation has the
    moment's sign (M > 0, intrados compressed, opens the extrados)."""
    closed, opened = [], []
    for k0 in (0.8, 0.9):
        _, sol = _solve(loads={"lateral_ratio": k0}, lining={"joints": {"count": 6, "contact_height": 0.15}})
        j = sol.joints
        flexibility = j.rotation / j.moment
        assert np.all(flexibility > 0)
        closed += list(flexibility[~j.open])
        opened += list(flexibility[j.opening > 1e-5])
        assert np.all(flexibility[j.open] > 0.99 * flexibility[~j.open].min(initial=np.inf))
        assert np.all(j.opening[j.open] > 1e-7) and np.all(j.opening[~j.open] < 1e-12)
    assert len(closed) >= 4 and len(opened) >= 2
    assert max(closed) < 1.15 * min(closed)
    assert min(opened) > 1.5 * max(closed)


def test_six_segments_with_a_realistic_strip_lower_the_default_moments():
    """The default case (K0 = 0.5): six segments with a 0.15 m strip carry 0.71 of the monolithic
    ring's largest moment (coarse mesh), the thrust nearly unchanged."""
    mono_model, mono = _solve()
    seg_model, seg = _solve(lining={"joints": {"count": 6, "contact_height": 0.15}})
    m0, m1 = np.abs(_forces(mono_model, mono).moment).max(), np.abs(_forces(seg_model, seg).moment).max()
    n0, n1 = _forces(mono_model, mono).thrust.max(), _forces(seg_model, seg).thrust.max()
    assert m1 < 0.8 * m0
    assert abs(n1 - n0) < 0.03 * n0


def test_every_segment_floats_and_is_balanced(imbalance):
    """Each segment's rigid modes are unknowns solved with the contact (not pinned at zero): every
    mode's balance F + Gᵀ W t holds to round-off, and the segments moved rigidly."""
    model, sol = _solve(lining={"joints": {"count": 6, "offset": 30.0, "contact_height": 0.15}})
    assert imbalance(model, sol) < 1e-10
    # 4 segments in the half model: the crown's and invert's are cut by the axis (1 mode each), the
    # other two translate both ways and rotate
    assert model.G.shape[1] == 1 + 3 + 3 + 1
    assert np.all(np.abs(sol.a) > 1e-9)


def test_the_generalized_bolt_method_is_the_paper_s_on_a_monolithic_lining():
    """With one mode (a monolithic lining's vertical translation) the bolt-set search and its
    active sets give the paper's bolt-point answer (solver.contact.bolt.solve_contact)."""
    spec = CaseSpec.model_validate({"mesh": MESH, "geometry": {"gap": 0.02}})
    model = TunnelModel(spec)
    dual = contact_stage.dual_problem(model, spec)
    paper = solve_contact(dual, model.mesh.interface.theta, inner="active-set", tol=1e-10, max_iterations=1000)
    m = dual.m
    fp = FloatingProblem(S=dual.S, d=dual.d, g0=dual.g0, w=dual.w, G=dual.nu2[:, None], F=np.array([dual.F2]),
                         kind=np.full(m, UNILATERAL, np.int8), partner=np.full(m, -1), mu=np.zeros(m),
                         labels=("lining: vertical translation",), p_scale=dual.pressure_scale)
    ours = solve_floating(fp, tol=1e-10, max_iterations=1000)
    assert paper.lam.max() > 0 and (paper.lam == 0).any()  # a partial contact: the clearance matters
    np.testing.assert_allclose(ours.t, paper.lam, rtol=0, atol=1e-9 * paper.lam.max())
    np.testing.assert_allclose(ours.a, [paper.a], rtol=1e-8)


def _toy(F, G, kind=None):
    """Two unit-flexibility rows and the modes ``G`` (R, k) with loads ``F``."""
    G = np.asarray(G, float)
    R = G.shape[0]
    return FloatingProblem(S=np.eye(R), d=np.zeros(R), g0=np.zeros(R), w=np.ones(R), G=G, F=np.asarray(F, float),
                           kind=np.full(R, UNILATERAL, np.int8) if kind is None else np.asarray(kind, np.int8),
                           partner=np.full(R, -1), mu=np.zeros(R), p_scale=1.0,
                           labels=tuple(f"segment {i}: mode" for i in range(G.shape[1])))


def test_a_segment_no_row_holds_is_named_not_pinned():
    fp = _toy([-1.0, 0.0], [[1.0, 0.0], [1.0, 0.0]])  # the second mode moves no row
    with pytest.raises(DriftError, match=r"^lining\.joints: a segment would drift: segment 1: mode \(no contact row"):
        solve_floating(fp, tol=1e-10, max_iterations=100)


def test_a_segment_held_only_by_pulling_rows_is_named():
    """Load +1 on a mode both rows hold by pressing the same way: balance needs tension."""
    fp = _toy([1.0], [[1.0], [1.0]])
    with pytest.raises(DriftError, match="would pull"):
        solve_floating(fp, tol=1e-10, max_iterations=100)
    # the same mode pushed the other way is held, by compressive tractions that balance it
    held = solve_floating(_toy([-1.0], [[1.0], [1.0]]), tol=1e-10, max_iterations=100)
    assert np.all(held.t >= 0) and held.t.sum() == pytest.approx(1.0)


def test_a_rejected_bolt_set_is_replaced_from_the_pressures():
    """Two modes, rows pressing on each with opposite signs: the all-closed guess picks a bolt
    that pulls; the search drops it and the answer meets every condition."""
    G = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.5, 1.0]])
    fp = FloatingProblem(S=np.eye(4) + 0.2, d=np.array([0.3, -0.2, 0.1, 0.0]), g0=np.zeros(4), w=np.ones(4), G=G,
                         F=np.array([0.7, -1.0]), kind=np.r_[UNILATERAL, UNILATERAL, UNILATERAL, EQUALITY].astype(np.int8),
                         partner=np.full(4, -1), mu=np.zeros(4), labels=("a", "b"), p_scale=1.0)
    sol = solve_floating(fp, tol=1e-12, max_iterations=100)
    assert kkt(fp, sol.t, sol.a) < 1e-10
    assert np.all(sol.t[:3] >= -1e-12)


def test_the_joint_check_is_en_1992_12_10_on_the_strip():
    """At the strip's plain (12.10) envelope the joint's utilization is 1: M_Rd(N) = N (a - x)/2,
    x = γF N / fcd,pl; it scales with the moment at a given thrust; a thrust the strip cannot
    take at all, or a moment without thrust, is inf."""
    spec = CaseSpec.model_validate({})
    a, design = 0.15, spec.design
    env_n, env_m = interaction_envelope(a, concrete_strength=design.concrete_strength, steel_strength=0.0,
                                        reinforcement_area=0.0, axis_distance=0.0)
    up = (env_m > 0) & (env_n > 0.05 * env_n.max()) & (env_n < 0.95 * env_n.max())
    n_ed, m_ed = env_n[up], env_m[up]
    g = design.load_factor
    np.testing.assert_allclose(joint_utilization(n_ed / g, m_ed / g, a, design), 1.0, rtol=1e-9)
    np.testing.assert_allclose(joint_utilization(n_ed / g, -0.5 * m_ed / g, a, design), 0.5, rtol=1e-9)
    assert joint_utilization(1.01 * env_n.max() / g, 0.0, a, design) == np.inf
    assert joint_utilization(0.0, 1e3, a, design) == np.inf and joint_utilization(0.0, 0.0, a, design) == 0.0


@pytest.mark.parametrize("case", [
    {"ground": {"model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 28.0}},
    {"water": {"table": 5.0}},
    {"water": {"table": 5.0, "lining": "drained"}, "interface": {"model": "coulomb", "friction": 0.4}},
])
def test_segments_work_with_yielding_ground_and_water(case):
    """The joints' path under the other physics: a yielding ground's stage 2 solves the segmental
    contact problem at every iterate, water loads the segments; the answer meets the KKT conditions,
    the thrust stays in the strips, and the lining's weight and the water's uplift are the
    monolithic lining's (same concrete, same extrados)."""
    _, mono = _solve(**case)
    _, seg = _solve(**case, lining={"joints": {"count": 6, "contact_height": 0.15}})
    assert seg.kkt_residual < 1e-8
    assert np.all(seg.joints.eccentricity_ratio <= 1 + 1e-9) and np.all(seg.joints.thrust > 0)
    # the meshes' quadratic arcs differ (the segmental one is graded towards its joints): O(h⁴) in area
    assert seg.lining_weight == pytest.approx(mono.lining_weight, rel=1e-7)
    assert seg.water_uplift == pytest.approx(mono.water_uplift, rel=1e-7, abs=1e-9)
    if "ground" in case:
        assert seg.plastic["iterations"] > 0 and seg.plastic["at_yield"].any()


@pytest.mark.slow
def test_the_readme_segmental_example_reproduces():
    """README "Segmental linings": `examples/segmental.json`'s joint table (N, M, e/(a/2), opening,
    rotation, EN 1992 at the joint) to its printed digits, the ring's largest moment, the crown's
    settlement, η away from the joints, and the stress block x = γF N / fcd,pl of 4.5–5.1 cm."""
    import json
    from pathlib import Path

    from solver.lining.design import fcd

    example = json.loads((Path(__file__).parents[2] / "examples" / "segmental.json").read_text())
    ds = run_case(CaseSpec.model_validate(example))
    table = [(539, -39.7, 0.98, 0.70, -5.2, 1.41), (579, 40.2, 0.93, 0.20, 1.7, 1.37),
             (599, 42.4, 0.94, 0.29, 2.4, 1.42), (577, -42.5, 0.98, 0.78, -5.8, 1.45)]
    for k, row in enumerate(table):
        got = (round(float(ds["joint_thrust"][k]) / 1e3), round(float(ds["joint_moment"][k]) / 1e3, 1),
               round(float(ds["joint_eccentricity"][k]), 2), round(1e3 * float(ds["joint_opening"][k]), 2),
               round(1e3 * float(ds["joint_rotation"][k]), 1), round(float(ds["joint_utilization"][k]), 2))
        assert got == row, (k, got)
    assert round(float(ds["max_abs_moment"]) / 1e3, 1) == 97.8 and round(1e3 * float(ds["crown_settlement"]), 1) == 5.0
    assert round(float(ds["max_utilization"]), 2) == 0.48
    x = 1.35 * ds["joint_thrust"].values / fcd(30e6, plain=True)
    assert (round(100 * x.min(), 1), round(100 * x.max(), 1)) == (4.5, 5.1)
