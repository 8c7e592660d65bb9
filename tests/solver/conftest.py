"""Shared checks for solved cases: the lining balance and the discrete KKT conditions."""
from __future__ import annotations

import numpy as np
import pytest


def assert_kkt(ds, *, tol: float = 1e-7) -> None:
    """Check balance, λ >= 0, gap >= 0, λ·gap = 0 from the stored arrays (not from kkt_residual).

    For ``interface.model = "coulomb"`` also the friction law through its natural map
    (kkt.kkt_residual's) and the stored tangential jump; the balance includes the shear.
    """
    lam = ds.contact_pressure.values
    shear = ds.shear_traction.values  # zero when frictionless
    gap = ds.gap.values
    w = ds.weight.values
    nu2 = ds.normal_y.values
    weight = float(ds.lining_weight)
    # paper Def. 2.6: ∫F''_2 + I(λ ν2 + s τ2) = 0, F''_2 the (downward) lining weight, τ2 = ν1
    assert abs(-weight + np.sum(w * lam * nu2) + np.sum(w * shear * ds.normal_x.values)) <= 1e-8 * weight
    p_ref = max(lam.max(), weight / np.sum(np.abs(nu2) * w) * 2)
    u_ref = max(np.abs(ds.displacement_x).max(), np.abs(ds.displacement_y).max())
    assert lam.min() >= -tol * p_ref
    assert gap.min() >= -tol * u_ref
    assert np.max(np.abs(lam * gap)) <= tol * p_ref * u_ref
    # the stored gap is what the stored displacements say
    gn, ln = ds.ground_node.values, ds.lining_node.values
    # the contact acts on the stage-2 increment: take stage 1 off the ground's displacement
    ux = ds.displacement_x.values - ds.stage1_displacement_x.values
    uy = ds.displacement_y.values - ds.stage1_displacement_y.values
    nx, ny = ds.normal_x.values, ds.normal_y.values
    jump = (ux[gn] - ux[ln]) * nx + (uy[gn] - uy[ln]) * ny
    np.testing.assert_allclose(ds.normal_jump.values, jump, rtol=0, atol=1e-12 * u_ref)
    g0 = __import__("json").loads(ds.attrs["case_spec"])["geometry"]["gap"]
    np.testing.assert_allclose(gap, g0 - jump, rtol=0, atol=1e-12 * u_ref)
    spec = __import__("json").loads(ds.attrs["case_spec"])
    if spec["interface"]["model"] == "coulomb":
        tjump = -(ux[gn] - ux[ln]) * ny + (uy[gn] - uy[ln]) * nx  # τ = ν turned 90°
        np.testing.assert_allclose(ds.tangential_jump.values, tjump, rtol=0, atol=1e-12 * u_ref)
        p_s = max(p_ref, np.abs(shear).max())
        bound = spec["interface"]["friction"] * np.maximum(lam, 0.0)
        natural = shear - np.clip(shear + p_s / float(u_ref) * tjump, -bound, bound)
        assert np.max(np.abs(natural)) <= tol * p_s
    assert float(ds.kkt_residual) <= tol
    assert int(ds.converged) == 1


@pytest.fixture
def kkt():
    return assert_kkt


def segment_imbalance(model, sol) -> float:
    """The largest relative imbalance of a segmental lining's rigid modes, ``F + Gᵀ W t`` over the
    sum of the magnitudes of its terms (round-off when every segment is balanced)."""
    import solver.stages.contact as contact_stage

    _, _, d, F = contact_stage.forward_stage(model, sol.spec)
    _, t = contact_stage.contact_tractions(model, sol.spec, d, F)
    wrench = F + model.G.T @ (model.w * t)
    scale = np.abs(F) + np.abs(model.G).T @ np.abs(model.w * t)
    return float(np.max(np.abs(wrench) / scale))


@pytest.fixture
def imbalance():
    return segment_imbalance
