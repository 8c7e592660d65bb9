"""Closed-form checks: a lining ring in a large elastic medium, external loading (the
paper's wished-in-place model), against the exact annulus of :func:`solver.analytic.exact_ring`.

cos 2θ amplitudes are taken with the interface quadrature weights (the weights of the
nodal contact forces): vertex and edge-node pressures of quadratic elements alternate
slightly about the smooth field, which a trapezoid in θ would misread.
"""
from __future__ import annotations

import numpy as np
import pytest

from solver import run_case
from solver.analytic import (
    cos2_amplitude,
    exact_ring,
    interface_mean,
    ring_in_medium_case,
    ring_pressure,
)

P = 1.0e5  # far-field vertical pressure (surface load), Pa
E, NU, NU_L = 5.0e7, 0.3, 0.2
A = 2.5


@pytest.mark.parametrize("young_l", [3e10, 5e8])
def test_hydrostatic_ring_matches_exact_pressure_and_thrust(young_l, kkt):
    ds = run_case(ring_in_medium_case(radii=15, K=1.0, young_l=young_l))
    kkt(ds)
    q = ring_pressure(P, E, NU, young_l, NU_L, A, A + 0.3)
    assert interface_mean(ds, ds.contact_pressure.values) == pytest.approx(q, rel=0.01)
    assert interface_mean(ds, ds.thrust.values) == pytest.approx(q * 2.8, rel=0.01)
    assert float(ds.contact_extent) == pytest.approx(180.0)
    assert np.ptp(ds.contact_pressure.values) < 0.02 * q


@pytest.mark.parametrize("t_over_a", [0.025, 0.1, 0.25])
def test_cos2theta_moment_and_pressure_within_one_percent_at_the_default_mesh(t_over_a, kkt):
    """Thin to thick linings at the default interface_size (quadratic elements, two or more
    layers): the cos 2θ moment and pressure of the exact annulus within 1 %."""
    t = t_over_a * A
    ds = run_case(ring_in_medium_case(radii=30, K=0.5, thickness=t))
    kkt(ds)
    ex = exact_ring(P, 0.5, E, NU, 3e10, NU_L, A, A + t, loading="external", interface="slip")
    assert cos2_amplitude(ds, ds.moment.values) == pytest.approx(ex.M2, rel=0.01)
    assert cos2_amplitude(ds, ds.contact_pressure.values) == pytest.approx(ex.p2, rel=0.01)
    # springline: inner fibre in compression; crown and invert: in tension
    assert ds.moment.sel(interface=int(np.argmin(np.abs(ds.theta.values - 90)))) > 0
    assert ds.moment[0] < 0 and ds.moment[-1] < 0


@pytest.mark.slow
def test_domain_of_thirty_radii_is_large_enough():
    """Doubling the 30-radii domain changes the cos 2θ moment by less than 0.3 %."""
    m30 = run_case(ring_in_medium_case(radii=30, K=0.5, thickness=0.0625))
    m60 = run_case(ring_in_medium_case(radii=60, K=0.5, thickness=0.0625))
    assert cos2_amplitude(m60, m60.moment.values) == pytest.approx(cos2_amplitude(m30, m30.moment.values), rel=0.003)


@pytest.mark.slow
def test_moment_converges_at_least_at_second_order():
    """Thin ring (two element layers throughout), interface_size halved twice: the
    observed order of the cos 2θ moment, log2 of the ratio of successive differences
    (the modelling error of the finite domain cancels in the differences), is at least 2."""
    M = [cos2_amplitude(ds, ds.moment.values)
         for ds in (run_case(ring_in_medium_case(radii=30, K=0.5, thickness=0.0625, h=h)) for h in (0.2, 0.1, 0.05))]
    order = np.log2(abs(M[0] - M[1]) / abs(M[1] - M[2]))
    assert order >= 2.0
