"""Sampled sweeps (SPEC §8): Sobol', Latin hypercube and Monte Carlo samples through each
parameter's distribution; same seed, same cases; bad input named."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from scipy import stats

from workflows.sampling import Distribution, unit_points
from workflows.sweep import Sweep, SweepError, expand_sweep

K0 = {"distribution": "uniform", "low": 0.4, "high": 1.2}
E = {"distribution": "lognormal", "mean": 5.0e7, "std": 1.5e7}


def _sweep(**kw):
    return {"name": "sampled", "mode": "sobol", "samples": 16, "seed": 7,
            "vary": {"loads.lateral_ratio": K0, "ground.young": E}, **kw}


@pytest.mark.parametrize("mode", ["sobol", "lhs", "random"])
def test_same_seed_same_cases_other_seed_other_cases(mode):
    a = [c.case_id for c in expand_sweep(_sweep(mode=mode))]
    assert len(a) == 16 and a == [c.case_id for c in expand_sweep(_sweep(mode=mode))]
    assert set(a).isdisjoint(c.case_id for c in expand_sweep(_sweep(mode=mode, seed=8)))
    values = [c.loads.lateral_ratio for c in expand_sweep(_sweep(mode=mode))]
    assert min(values) >= 0.4 and max(values) <= 1.2


def test_lhs_puts_one_sample_in_each_stratum_and_sobol_is_balanced():
    q = unit_points("lhs", 16, 2, seed=1)
    for j in range(2):
        assert sorted(np.floor(q[:, j] * 16).astype(int)) == list(range(16))
    s = unit_points("sobol", 64, 2, seed=1)
    for j in range(2):  # a power-of-two Sobol' sample has 2^k points in each of 2^k bins... here 8 bins of 8
        assert np.bincount(np.floor(s[:, j] * 8).astype(int), minlength=8).tolist() == [8] * 8


def test_distributions_have_their_stated_moments():
    q = (np.arange(200000) + 0.5) / 200000  # an exact quadrature of the inverse CDF
    lognormal = Distribution.model_validate(E).ppf(q)
    assert lognormal.mean() == pytest.approx(5.0e7, rel=1e-3) and lognormal.std() == pytest.approx(1.5e7, rel=1e-2)
    normal = Distribution.model_validate({"distribution": "normal", "mean": 2.0, "std": 0.5}).ppf(q)
    assert normal.mean() == pytest.approx(2.0, abs=1e-6) and normal.std() == pytest.approx(0.5, rel=1e-3)
    t = Distribution.model_validate({"distribution": "truncated-normal", "mean": 1.0, "std": 0.3, "low": 0.8, "high": 1.5})
    v = t.ppf(q)
    assert v.min() >= 0.8 and v.max() <= 1.5
    a, b = (0.8 - 1.0) / 0.3, (1.5 - 1.0) / 0.3
    assert v.mean() == pytest.approx(stats.truncnorm.mean(a, b, loc=1.0, scale=0.3), rel=1e-4)
    u = Distribution.model_validate(K0).ppf(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(u, [0.4, 0.8, 1.2])


@pytest.mark.parametrize("change, field", [
    ({"samples": 12}, "samples"),
    ({"samples": None}, "samples"),
    ({"vary": {"interface.model": K0}}, "interface.model"),
    ({"vary": {"loads.lateral_ratio": [0.5, 1.0]}}, "vary.loads.lateral_ratio"),
    ({"mode": "grid"}, "vary.loads.lateral_ratio"),
])
def test_bad_sampled_sweeps_name_the_field(change, field):
    with pytest.raises(SweepError, match=field.replace(".", r"\.")):
        expand_sweep(_sweep(**change))


@pytest.mark.parametrize("entry, field", [
    ({"distribution": "weibull", "low": 0, "high": 1}, "distribution"),
    ({"distribution": "normal", "mean": 1.0}, "std"),
    ({"distribution": "normal", "mean": 1.0, "std": -1.0}, "std"),
    ({"distribution": "uniform", "low": 2.0, "high": 1.0}, "high"),
    ({"distribution": "lognormal", "mean": -1.0, "std": 1.0}, "mean"),
])
def test_bad_distributions_name_the_parameter_and_field(entry, field):
    with pytest.raises(ValidationError, match=rf"loads\.lateral_ratio.*{field}"):
        Sweep.model_validate(_sweep(vary={"loads.lateral_ratio": entry}))


def test_grid_sweeps_keep_their_ids():
    assert Sweep.model_validate({"name": "x", "vary": {"loads.lateral_ratio": [0.5, 1.0]}}).sweep_id == "137ee315a4cb1fec"
    assert math.isclose(len(expand_sweep({"name": "x", "vary": {"loads.lateral_ratio": [0.5, 1.0]}})), 2)


def test_sobol_points_beat_random_points_on_discrepancy():
    from scipy.stats import qmc

    for d in (2, 4):
        sobol = qmc.discrepancy(unit_points("sobol", 256, d, seed=1))
        rand = qmc.discrepancy(unit_points("random", 256, d, seed=1))
        assert sobol < 0.2 * rand, (d, sobol, rand)
