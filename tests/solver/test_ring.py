"""Closed-form checks: a lining ring in a large elastic medium."""
from __future__ import annotations

import numpy as np
import pytest

from solver import CaseSpec, run_case
from solver.analytic import ring_in_medium_case as ring_case
from solver.analytic import ring_pressure, thin_ring_cos2

P = 1.0e5  # far-field vertical pressure (surface load), Pa
E, NU = 5.0e7, 0.3


def exact_pressure(young_l: float) -> float:
    return ring_pressure(P, E, NU, young_l, 0.2, 2.5, 2.8)


def mean_pressure(ds) -> float:
    w = ds.weight.values
    return float(np.sum(w * ds.contact_pressure.values) / np.sum(w))


def mean_thrust(ds) -> float:
    th = np.radians(ds.theta.values)
    return float(np.trapezoid(ds.thrust.values, th) / np.pi)


@pytest.mark.parametrize("young_l", [3e10, 5e8])
def test_hydrostatic_ring_matches_exact_pressure_and_thrust(young_l, kkt):
    ds = run_case(ring_case(radii=15, K=1.0, young_l=young_l))
    kkt(ds)
    q = exact_pressure(young_l)
    assert mean_pressure(ds) == pytest.approx(q, rel=0.01)
    assert mean_thrust(ds) == pytest.approx(q * 2.8, rel=0.02)
    assert float(ds.contact_extent) == pytest.approx(180.0)
    # nearly axisymmetric: pressure varies little around the ring
    assert np.ptp(ds.contact_pressure.values) < 0.02 * q


def test_error_against_exact_ring_falls_as_mesh_halves():
    errs_q, errs_n = [], []
    for h in (0.2, 0.1, 0.05):
        ds = run_case(ring_case(radii=40, K=1.0, h=h, young_l=5e8))
        q = exact_pressure(5e8)
        errs_q.append(abs(mean_pressure(ds) / q - 1))
        errs_n.append(abs(mean_thrust(ds) / (q * 2.8) - 1))
    assert errs_q[0] > errs_q[1] > errs_q[2]
    assert errs_n[0] > errs_n[1] > errs_n[2]
    assert errs_n[2] < 0.25 * errs_n[0]  # at least first order; measured ~O(h^2)


def test_anisotropic_far_field_matches_thin_ring_cos2theta_terms(kkt):
    """K = 0.5: cos 2θ parts of pressure and moment against the thin-ring solution.

    Tolerance. The thin-ring theory replaces the lining by its centreline, an
    error of order t/2R (here 0.3/5.3 = 5.7 %). The measured moment error falls
    from 7.2 % (h = t/6) to 6.3 % (t/8) to 5.7 % (t/12), i.e. onto the thin-ring
    error; p2 from 1.5 % to 0.6 % to 0.06 %. So, at h = t/8: p2 within t/2R and
    M2 within 1.25 t/2R (the theory's error plus a quarter of it for the mesh).
    """
    t, R = 0.3, 2.5 + 0.15
    ds = run_case(ring_case(radii=40, K=0.5, h=t / 8))
    kkt(ds)
    th = np.radians(ds.theta.values)  # from the crown: cos 2θ_springline = -cos 2θ

    def cos2(f):
        return -2 * np.trapezoid(f * np.cos(2 * th), th) / np.pi

    M2, p2 = thin_ring_cos2(P, 0.5, E, NU, 3e10, 0.2, R, t)
    tol = t / (2 * R)
    assert cos2(ds.contact_pressure.values) == pytest.approx(p2, rel=tol)
    assert cos2(ds.moment.values) == pytest.approx(M2, rel=1.25 * tol)
    # springline: inner fibre in compression; crown: in tension
    assert ds.moment.sel(interface=np.argmin(np.abs(ds.theta.values - 90))) > 0
    assert ds.moment[0] < 0 and ds.moment[-1] < 0
