"""Construction stages (SPEC §1.1): in-situ stress, excavation with deconfinement, lining placed after."""
from __future__ import annotations

import json

import numpy as np
import pytest

from solver import CaseSpec, run_case
from solver.analytic import (
    cos2_amplitude,
    exact_ring,
    interface_mean,
    kirsch_wall_displacement,
    ring_in_medium_case,
)
from solver.model import TunnelModel
import solver.stages.loads as stage_fns

P, E, NU, E_L, NU_L = 1.0e5, 5.0e7, 0.3, 3.0e10, 0.2
A, T = 2.5, 0.3
B = A + T


def test_excavation_loading_matches_the_exact_ring_hydrostatic(kkt):
    ds = run_case(ring_in_medium_case(radii=20, K=1.0, loading="excavation"))
    kkt(ds)
    ex = exact_ring(P, 1.0, E, NU, E_L, NU_L, A, B, loading="excavation", interface="slip")
    lam_l = (1 + NU_L) * ((1 - 2 * NU_L) * B**2 + A**2) / (E_L * (B**2 - A**2))
    q = P / (1 + E * lam_l / (1 + NU))  # closed-forms.md, excavation loading
    assert ex.p0 == pytest.approx(q, rel=1e-9)
    assert interface_mean(ds, ds.contact_pressure.values) == pytest.approx(q, rel=0.01)
    assert interface_mean(ds, ds.thrust.values) == pytest.approx(q * B, rel=0.01)


def test_excavation_loading_matches_the_exact_ring_cos2theta(kkt):
    """K = 0.5, full slip: the cos 2θ pressure and moment of the exact annulus
    (Michell n = 0, 2; solver.analytic.exact_ring) within 1.5 % on 20 radii."""
    ds = run_case(ring_in_medium_case(radii=20, K=0.5, loading="excavation"))
    kkt(ds)
    ex = exact_ring(P, 0.5, E, NU, E_L, NU_L, A, B, loading="excavation", interface="slip")
    assert cos2_amplitude(ds, ds.contact_pressure.values) == pytest.approx(ex.p2, rel=0.015)
    assert cos2_amplitude(ds, ds.moment.values) == pytest.approx(ex.M2, rel=0.015)
    # springline: inner fibre in compression for K < 1
    assert float(ds.moment.sel(interface=int(np.argmin(np.abs(ds.theta.values - 90))))) > 0


def test_deconfinement_scales_the_lining_load_linearly():
    """A light lining in full contact carries (1 - λd) of the excavation load: λd = 0.4
    gives 0.6 times the pressure, thrust and moment of λd = 0 (one model, two solves)."""
    spec0 = ring_in_medium_case(radii=15, K=0.7, loading="excavation", h=0.2)
    model = TunnelModel(spec0)
    spec4 = spec0.model_copy(update={"excavation": spec0.excavation.model_copy(update={"deconfinement": 0.4})})
    ds0, ds4 = run_case(spec0, model=model), run_case(spec4, model=model)
    assert float(ds0.contact_extent) == pytest.approx(180.0)
    for name in ("contact_pressure", "thrust", "moment"):
        ref = ds0[name].values
        np.testing.assert_allclose(ds4[name].values, 0.6 * ref, rtol=0, atol=1e-3 * np.abs(ref).max())


def test_full_release_before_the_lining_is_kirsch_and_leaves_the_lining_its_weight(kkt):
    """λd = 1: the ground wall converges as an unlined hole (Kirsch); the lining then
    carries only its own weight (the same pressures as with no in-situ stress at all).

    The finite model (free surface above, roller bottom below) also translates the hole
    vertically as a whole, which the infinite plane cannot show: +9 % / -8 % at crown /
    invert on 15 radii, halving with each doubling of the domain; 60 radii (coarse far
    field) bring it under 3 %, and the mean of crown and invert, which the translation
    cancels, is within 0.5 %."""
    K = 0.6
    spec = ring_in_medium_case(radii=60, K=K, loading="excavation", deconfinement=1.0, h=0.2)
    spec = spec.model_copy(update={"mesh": spec.mesh.model_copy(update={"far_size": 24.0})})
    ds = run_case(spec)
    kkt(ds)
    iface = {th: int(np.argmin(np.abs(ds.theta.values - th))) for th in (0.0, 90.0, 180.0)}
    gn = ds.ground_node.values
    ux, uy = ds.displacement_x.values[gn], ds.displacement_y.values[gn]
    u_r = -(ux * ds.normal_x.values + uy * ds.normal_y.values)  # outward
    for th, i in iface.items():
        assert u_r[i] == pytest.approx(kirsch_wall_displacement(P, K, E, NU, B, th), rel=0.03), th
    crown_invert = 0.5 * (u_r[iface[0.0]] + u_r[iface[180.0]])
    assert crown_invert == pytest.approx(kirsch_wall_displacement(P, K, E, NU, B, 0.0), rel=0.005)
    unloaded = run_case(spec.model_copy(update={"loads": spec.loads.model_copy(update={"surface_load": 0.0})}))
    p = unloaded.contact_pressure.values
    np.testing.assert_allclose(ds.contact_pressure.values, p, rtol=0, atol=1e-8 * p.max())


def test_release_forces_are_the_discrete_excavation_load():
    """r = f_ext - ∫Bᵀσ0 vanishes at every free node off the excavation boundary (the
    unexcavated discrete ground is in exact equilibrium) and its vertical resultant is the
    weight of the excavated ground, ρ g times the area of the mesh's (curved) hole."""
    spec = CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0))
    model = TunnelModel(spec)
    r = stage_fns.excavation_load(model, spec)
    ground = model.ground.body
    hole = model.mesh.interface.ground_node
    off = np.ones(ground.mesh.p.shape[1], bool)
    off[hole] = False
    dofs = ground.dof_of_node[:, off].ravel()
    free_off = np.intersect1d(dofs, ground.free)
    scale = np.abs(r).max()
    assert np.abs(r[free_off]).max() <= 1e-10 * scale
    # area of the hole: vertex polygon closed along the axis + parabolic segments of the P2 edges
    p = ground.mesh.p[:, hole]
    v, mid = p[:, 0::2], p[:, 1::2]
    x, y = v
    polygon = 0.5 * abs(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]) + x[-1] * y[0] - x[0] * y[-1])
    chord = np.diff(v, axis=1)
    bulge = mid - 0.5 * (v[:, 1:] + v[:, :-1])
    segments = (2.0 / 3.0) * np.sum(np.abs(chord[0] * bulge[1] - chord[1] * bulge[0]))
    area = polygon + segments
    assert area == pytest.approx(0.5 * np.pi * spec.geometry.hole_radius**2, rel=1e-5)
    rho_g = spec.ground.density * spec.loads.gravity
    resultant = r[ground.dof_of_node[1, hole]].sum()
    assert resultant == pytest.approx(rho_g * area, rel=1e-10)


def test_default_case_does_not_depend_on_the_model_walls(kkt):
    base = run_case(CaseSpec())
    kkt(base)
    big = run_case(CaseSpec(geometry=dict(width=80.0, height=100.0)))
    kkt(big)
    for name in ("max_abs_moment", "max_thrust", "max_contact_pressure"):
        assert float(big[name]) == pytest.approx(float(base[name]), rel=0.03), name
    attrs = json.loads(base.attrs["stage1_convergence_m"])
    assert attrs["crown"] > 0 and attrs["invert"] > 0  # the hole closes before the lining is placed
    assert base.attrs["deconfinement"] == 0.3


def test_stages_reuse_the_factorization(monkeypatch):
    """Stage 1 is a triangular solve with the ground factor, not a second factorization."""
    import solver.fe.flexibility as flexibility

    spec = CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0))
    model = TunnelModel(spec)

    def refuse(*args, **kwargs):
        raise AssertionError("factorized again")

    monkeypatch.setattr(flexibility, "InterfaceFactor", refuse)
    case = spec.model_copy(update={"excavation": spec.excavation.model_copy(update={"deconfinement": 0.5})})
    sol = model.solve(case)
    # stage 1 (the second column of the ground's backward solve) is K u1 = λd r on the ground alone
    body = model.ground.body
    u1 = body.restrict(body.full(sol.u_stage1))  # in the body's (skew) basis, as K
    load = 0.5 * stage_fns.stage_loads(model, case).release
    np.testing.assert_allclose(body.K @ u1, load, rtol=0, atol=1e-9 * np.abs(load).max())
    assert np.abs(u1).max() > 0


def test_large_displacement_is_stored_with_a_warning():
    ds = run_case(CaseSpec(ground=dict(young=2.0e6), mesh=dict(interface_size=0.2, far_size=6.0)))
    warnings = json.loads(ds.attrs["warnings"])
    assert any("small-displacement" in w for w in warnings)


def test_a_shared_model_gives_the_result_of_a_fresh_one():
    """Cases that differ only in loads, stages, interface, solver and design reuse one model;
    every stored array is bit-for-bit what the case computes alone."""
    from solver.model import model_key, shared_model

    base = CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0))
    others = [base.model_copy(update={"loads": base.loads.model_copy(update={"lateral_ratio": 0.8})}),
              base.model_copy(update={"excavation": base.excavation.model_copy(update={"deconfinement": 0.6})}),
              base.model_copy(update={"interface": base.interface.model_copy(update={"model": "bonded"})})]
    model = shared_model(base)
    for spec in [base, *others, others[0]]:  # frictionless again after the bonded case
        assert model_key(spec) == model_key(base) and shared_model(spec) is model
        together, alone = run_case(spec, model=model), run_case(spec)
        for name, var in alone.data_vars.items():
            if name != "solve_seconds":
                np.testing.assert_array_equal(together[name].values, var.values, err_msg=name)


def test_split_solves_and_load_shapes():
    """A case's excavation load, combined from the model's four load shapes, is the one
    assembled directly for its ρg, q and K0; a solve split around the interface (forward,
    interface jumps, backward with tractions) answers ``B K⁺f`` and ``K u = f - BᵀWt`` for
    both bodies and both factorizations; a model that forgot its factorizations gives the
    same solution bit for bit after rebuilding them."""
    from solver.fe.assembly import gravity_load, initial_stress_forces, side_pressure_load, surface_load

    spec = CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0), boundaries=dict(side="pressure"),
                    loads=dict(lateral_ratio=0.6, surface_load=5.0e4))
    model = TunnelModel(spec)
    basis, g = model.ground.body.basis, spec.geometry
    rho_g, q, k0 = spec.ground.density * spec.loads.gravity, spec.loads.surface_load, spec.loads.lateral_ratio
    scale = max(g.width, g.height)
    direct = (gravity_load(basis, spec.ground.density, spec.loads.gravity) + surface_load(basis, q, scale=scale)
              + side_pressure_load(basis, q=q, rho_g=rho_g, k0=k0, width=g.width, scale=scale)
              - initial_stress_forces(basis, q=q, rho_g=rho_g, k0=k0))
    np.testing.assert_allclose(stage_fns.excavation_load(model, spec), direct, rtol=0, atol=1e-9 * np.abs(direct).max())
    rng = np.random.default_rng(3)
    m, R = model.m, model.ground.B.shape[0]
    for fb, f in ((model.ground, stage_fns.stage_loads(model, spec).release),
                  (model.lining, model.lining.body.restrict(model.lining_shape()))):
        for rows in ("normal", "all"):
            Wt = rng.standard_normal(R) * np.abs(f).max()
            if rows == "normal":
                Wt[m:] = 0.0  # a frictionless case has no shear
            y = fb.forward(f, rows)
            u0 = fb.backward(y, rows)
            served = slice(0, m) if rows == "normal" else slice(0, R)
            np.testing.assert_allclose(fb.jumps(y, rows), (fb.B @ u0)[served], rtol=1e-10,
                                       atol=1e-12 * np.abs(fb.B @ u0).max())
            u = fb.backward(y, rows, Wt)
            load = f - fb.B.T @ Wt
            residual = fb.body.K @ u - load
            scale = np.abs(load).max()
            # the lining's pinned DOF carries its unbalanced vertical load
            assert np.sum(np.abs(residual) > 1e-9 * scale) <= (1 if fb is model.lining else 0), (rows, fb)
    before = model.solve(spec)
    model.drop_factorizations()
    model.kept.forget()  # solved again, not taken from what the model kept
    assert not model._S and model.timings["factorization"] == 0.0
    after = model.solve(spec)
    np.testing.assert_array_equal(after.u_ground, before.u_ground)
    np.testing.assert_array_equal(after.lam, before.lam)
    assert model.timings["factorization"] > 0.0


def test_volume_loss_integrates_the_settling_part_of_the_trough():
    from solver.results.dataset import volume_loss

    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    s = np.array([2.0, 2.0, 0.0, -1.0, -1.0])  # settles over [0, 2], heaves beyond
    r = np.sqrt(2.0 / np.pi)  # half excavated area 1
    assert volume_loss(x, s, r) == pytest.approx(3.0)
    crossing = np.array([1.0, -1.0])  # zero at x = 0.5: a triangle of area 0.25
    assert volume_loss(np.array([0.0, 1.0]), crossing, r) == pytest.approx(0.25)
    assert volume_loss(x, -np.abs(s), r) == 0.0
