"""The Mohr–Coulomb return mapping (SPEC §1.5): plastic consistency and the flow rule at every
point, apex and tension cut-off."""
from __future__ import annotations

import numpy as np
import pytest

from solver.ground.mohr_coulomb import from_principal, principal, return_map, yield_values

E, NU = 5.0e7, 0.3
LAM, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))


def _sorted_principal(stress):
    major, minor, _, zz = principal(stress)
    return np.sort(np.stack([major, minor, zz]), axis=0)[::-1]


@pytest.mark.parametrize("c, phi, psi, t", [(2e4, 30, 0, 0), (2e4, 30, 30, 0), (1e4, 25, 10, 5e3), (5e4, 0, 0, 2e4),
                                             (1e4, 35, 35, 1e4 / np.tan(np.radians(35)))])
def test_consistency_and_flow_rule_at_random_states(c, phi, psi, t):
    rng = np.random.default_rng(7)
    trial = rng.normal(0, 2e5, (4, 5000)) - np.array([1e5, 1e5, 0, 1e5])[:, None]
    stress, dep, at_yield = return_map(trial, LAM, MU, c, phi, psi, t)
    s = _sorted_principal(stress)
    f = yield_values(s, c, np.sin(np.radians(phi)), np.cos(np.radians(phi)), t)
    assert f.max() <= 1e-9 * 2e5  # every returned state on or inside every surface
    inside = _sorted_principal(trial)
    f_trial = yield_values(inside, c, np.sin(np.radians(phi)), np.cos(np.radians(phi)), t).max(axis=0)
    elastic = f_trial <= 0
    np.testing.assert_array_equal(stress[:, elastic], trial[:, elastic])  # elastic states untouched
    assert np.all(np.abs(f.max(axis=0)[~elastic]) <= 1e-9 * 2e5)  # plastic ones on the surface
    assert at_yield[~elastic].all() and 0.3 < (~elastic).mean() < 1
    # the flow rule: trial - stress = D Δεp in the trial's principal axes, Δεp = Σ Δγ b, Δγ ≥ 0
    ta, ti, _, tz = principal(trial)
    sa, si, _, sz = principal(stress)
    drop = np.stack([ta - sa, ti - si, tz - sz])
    np.testing.assert_allclose(drop, LAM * dep.sum(axis=0) + 2 * MU * dep, rtol=0, atol=1e-9 * 2e5)
    # with ψ = 0 no volume change, with ψ = φ dilation
    vol = dep.sum(axis=0)[~elastic]
    if psi == 0 and t == 0 and phi > 0:
        shear_only = np.abs(s[0, ~elastic]) > 1.0  # off the tension cut-off
        assert np.abs(vol[shear_only]).max() <= 1e-12
    if psi == phi and phi > 0:
        assert vol.min() >= -1e-15


def test_hydrostatic_tension_returns_to_the_apex_or_the_cut_off():
    c, phi = 1e4, 30
    apex = c / np.tan(np.radians(phi))
    trial = from_principal(np.full(3, 5e5), np.full(3, 5e5), (np.ones(3), np.zeros(3)), np.full(3, 5e5))
    for t, expected in ((apex, apex), (2e3, 2e3), (0.0, 0.0)):
        stress, _, _ = return_map(trial, LAM, MU, c, phi, 0, t)
        np.testing.assert_allclose(stress[[0, 1, 3]], expected, rtol=1e-12, atol=1e-6)
        np.testing.assert_allclose(stress[2], 0.0, atol=1e-6)


@pytest.mark.parametrize("c, phi, psi, t", [(2e4, 30, 0, 0), (1e4, 25, 10, 5e3), (5e4, 0, 0, 2e4),
                                             (1e4, 35, 35, 1e4 / np.tan(np.radians(35)))])
def test_the_consistent_tangent_is_the_derivative_of_the_return(c, phi, psi, t):
    """The algorithmic tangent (main plane, edges, cut-offs, apex; the spin of the in-plane
    directions) against central differences of the return, strain by strain; and a frozen set
    returns inside points onto the main plane with the same tangent (a smooth continuation)."""
    from solver.ground.mohr_coulomb import Material, consistent_tangent, return_stress
    from solver.ground.tangent import elastic_matrix

    rng = np.random.default_rng(11)
    trial = rng.normal(0, 2e5, (4, 3000)) - np.array([1e5, 1e5, 0, 1e5])[:, None]
    mat = Material.of(trial.shape[1], LAM, MU, c, phi, psi, t)
    stress, _, _, returned, C = consistent_tangent(trial, mat)
    np.testing.assert_array_equal(stress, return_stress(trial, mat)[0])
    assert 0.3 < returned.size / trial.shape[1] < 1
    D, h = elastic_matrix(LAM, MU)[0], 1e-9
    worst = 0.0
    for q in range(4):
        dt = D[:, q:q + 1] * h
        fd = (return_stress(trial + dt, mat)[0] - return_stress(trial - dt, mat)[0]) / (2 * h)
        err = np.abs(fd[:, returned] - C[:, :, q].T).max(axis=0) / np.abs(D).max()
        worst = max(worst, float(np.percentile(err, 99.5)))  # a few points sit on a kink within h
    assert worst < 1e-6
    frozen = np.ones(trial.shape[1], bool)
    sf, _, _, rf, Cf = consistent_tangent(trial, mat, frozen=frozen)
    assert rf.size == trial.shape[1]
    np.testing.assert_allclose(sf[:, returned], stress[:, returned], rtol=0, atol=1e-9 * 2e5)


@pytest.mark.parametrize("c, phi, psi, t", [(2e4, 30, 0, 0), (1e4, 25, 10, 5e3), (5e4, 0, 0, 2e4),
                                             (1e4, 35, 35, 1e4 / np.tan(np.radians(35)))])
def test_koiter_multipliers_are_non_negative_on_the_active_surfaces(c, phi, psi, t):
    """The compiled return picks, of the candidate active sets, one whose multipliers are all non-negative:
    the plastic strain is a non-negative combination of the flow directions of the surfaces (main plane, both
    edges, the cut-offs) the returned stress lies on (non-negative least squares leaves no residual). A return
    onto the wrong set (a negative multiplier) leaves one."""
    from scipy.optimize import nnls

    rng = np.random.default_rng(5)
    trial = rng.normal(0, 2e5, (4, 2000)) - np.array([1e5, 1e5, 0, 1e5])[:, None]
    stress, dep, _ = return_map(trial, LAM, MU, c, phi, psi, t)
    major, minor, (c2, s2), zz = principal(trial)
    order = np.argsort(-np.stack([major, minor, zz]), axis=0, kind="stable")
    ds = np.take_along_axis(dep, order, axis=0)  # in the trial's sorted axes
    cc, ss, sc = 0.5 * (1 + c2), 0.5 * (1 - c2), 0.5 * s2  # the returned stress along the trial's axes
    ret = np.stack([stress[0] * cc + stress[1] * ss + 2 * stress[2] * sc,
                    stress[0] * ss + stress[1] * cc - 2 * stress[2] * sc, stress[3]])
    ret = np.take_along_axis(ret, order, axis=0)
    sp, cp = np.sin(np.radians(phi)), np.cos(np.radians(phi))
    fv = np.vstack([(ret[0] - ret[2]) + (ret[0] + ret[2]) * sp - 2 * c * cp,
                    (ret[1] - ret[2]) + (ret[1] + ret[2]) * sp - 2 * c * cp,
                    (ret[0] - ret[1]) + (ret[0] + ret[1]) * sp - 2 * c * cp, ret - t])
    sq = np.sin(np.radians(psi))
    flows = np.array([[1 + sq, 0, -(1 - sq)], [0, 1 + sq, -(1 - sq)], [1 + sq, -(1 - sq), 0], *np.eye(3)])
    plastic = np.flatnonzero(np.any(dep != 0, axis=0))
    assert plastic.size > 500
    for i in plastic:
        active = fv[:, i] >= -1e-7 * 2e5
        assert active.any()
        _, resid = nnls(flows[active].T, ds[:, i])
        assert resid <= 1e-9 * np.abs(ds[:, i]).max()
