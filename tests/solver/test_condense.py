"""A stiffness condensed onto a region of its unknowns (solver.fe.condense) against dense linear algebra,
and stage 1 on the yielding zone (solver.stages.region) against the whole ground's iteration."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import solver.stages.region as region
from solver import CaseSpec, run_case
from solver.fe.condense import Reach, RegionSchur
from solver.fe.linalg import InterfaceFactor


def laplacian_2d(n: int) -> sp.csr_matrix:
    T = sp.diags([-1, 2.1, -1], [-1, 0, 1], shape=(n, n))
    return (sp.kron(sp.eye(n), T) + sp.kron(T, sp.eye(n))).tocsr()


@pytest.mark.parametrize("size, seed", [(14, 0), (20, 1), (9, 2)])
def test_the_region_solve_is_the_schur_complements(size, seed):
    """``S⁻¹ b`` is ``(K⁻¹ b)_p`` for a load on the region alone, and ``S x`` the Schur complement's
    product, for regions scattered through the ordering (so that supernodes straddle the region's first
    column) and a random ordering of the rest."""
    K = laplacian_2d(size)
    n = K.shape[0]
    rng = np.random.default_rng(seed)
    inside = np.zeros(n, bool)
    inside[rng.choice(n, n // 3, replace=False)] = True
    schur = RegionSchur(K, rng.permutation(n), inside)
    assert np.array_equal(schur.dofs, np.flatnonzero(inside))
    A = K.toarray()
    p, e = inside, ~inside
    S = A[np.ix_(p, p)] - A[np.ix_(p, e)] @ np.linalg.solve(A[np.ix_(e, e)], A[np.ix_(e, p)])
    b = rng.standard_normal(p.sum())
    full = np.zeros(n)
    full[p] = b
    np.testing.assert_allclose(schur.solve(b), np.linalg.solve(A, full)[p], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(schur.product(b), S @ b, rtol=1e-10, atol=1e-12)


def test_a_region_of_one_block_and_of_everything():
    """The region as the trailing block of the ordering, and the whole matrix."""
    K = laplacian_2d(8)
    n = K.shape[0]
    A = K.toarray()
    b = np.random.default_rng(3).standard_normal(n)
    whole = RegionSchur(K, np.arange(n), np.ones(n, bool))
    np.testing.assert_allclose(whole.solve(b), np.linalg.solve(A, b), rtol=1e-10)
    np.testing.assert_allclose(whole.product(b), A @ b, rtol=1e-12)
    tail = np.zeros(n, bool)
    tail[-10:] = True
    part = RegionSchur(sp.csr_matrix(A), np.arange(n), tail)
    full = np.zeros(n)
    full[tail] = b[:10]
    np.testing.assert_allclose(part.solve(b[:10]), np.linalg.solve(A, full)[tail], rtol=1e-10)


COARSE = {"interface_size": 0.15, "far_size": 6.0}
@pytest.mark.parametrize("size, seed", [(16, 4), (24, 5)])
def test_the_reached_columns_solve_a_load_on_some_unknowns_as_the_whole_factor(size, seed):
    """A load on a few unknowns scattered through a nested-dissection ordering (with an interface of unknowns
    last): :class:`Reach`'s forward solve is the whole factor's on the columns it reaches and the whole factor's
    is zero on the others; its backward solve gives ``K⁻¹ b`` at the loaded unknowns; its last ``k`` entries give
    the interface's; and it reaches less than the whole factor."""
    K = laplacian_2d(size)
    n = K.shape[0]
    rng = np.random.default_rng(seed)
    grid = np.arange(n).reshape(size, size)
    last = grid[0, :]  # one edge: the interface, factorized last
    factor = InterfaceFactor(K, last, rng.permutation(n) if seed % 2 else None)
    loaded = np.union1d(rng.choice(grid[size // 2:, size // 2:].ravel(), 12, replace=False), last)
    reach = Reach(factor, loaded)
    b = rng.standard_normal(loaded.size)
    full = np.zeros(n)
    full[loaded] = b
    y_whole = factor.forward(full)
    y = reach.forward(b)
    np.testing.assert_allclose(y, y_whole[reach.columns], rtol=1e-12, atol=1e-12)
    assert not np.delete(y_whole, reach.columns).any()
    x = np.linalg.solve(K.toarray(), full)
    np.testing.assert_allclose(reach.at(reach.backward(y)), x[loaded], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(factor.interface_of(y[-last.size:]), x[last], rtol=1e-10, atol=1e-12)
    assert reach.columns.size < n


#: issue 36's default Mohr–Coulomb ground; the weak sample's case 1 (split and arc-length steps)
CASES = {
    "mohr-coulomb": {"mesh": COARSE, "ground": {"model": "mohr-coulomb", "cohesion": 1.0e4, "friction_angle": 28.0,
                                                "dilatancy": 0.0}},
    "hoek-brown": {"mesh": COARSE, "ground": {"model": "hoek-brown", "young": 5.0e8, "ucs": 1.0e6, "gsi": 30.0,
                                              "mi": 8.0, "dilatancy": 5.0}},
    "stiffer": {"mesh": COARSE, "ground": {"model": "mohr-coulomb", "young": 3.0e8, "cohesion": 1.0e4,
                                           "friction_angle": 28.0, "dilatancy": 0.0}},
}


def _solved(case: dict, monkeypatch, **settings):
    for name, value in settings.items():
        monkeypatch.setattr(region, name, value)
    grown = []
    real = region.Zone._grow

    def spy(self, elements, layers=region.LAYERS):
        real(self, elements, layers)
        if self.condensed:  # stage 1's (stage 2 returns the stresses at its zone's points alone)
            grown.append((int(self.elements.sum()), self.given_up, self.waiting))

    monkeypatch.setattr(region.Zone, "_grow", spy)
    ds = run_case(CaseSpec.model_validate(case))
    monkeypatch.undo()
    return ds, grown


def _close(a, b, area_rtol: float):
    for name in ("crown_settlement", "max_thrust", "max_moment", "ground_loss", "wall_convergence"):
        if name in a:
            assert float(b[name]) == pytest.approx(float(a[name]), rel=2e-3, abs=1e-9), name
    for name in ("plastic_area", "stage1_plastic_area"):
        assert float(b[name]) == pytest.approx(float(a[name]), rel=area_rtol, abs=0.02), name


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_zones_answer_is_the_whole_grounds(name, monkeypatch):
    """Stage 1 on the zone (the rest of the ground condensed) and stage 2 with the stresses returned at the
    zone's points give the whole ground's answer within the stop test: the displacements and forces to
    0.2 %, the yielded areas (points within the stop test's reach of the surface) to 5 %, the zone a part of
    the ground throughout; and started from a zone of a few elements, both grow
    where the ground yields outside it (the check on the whole ground) to the same answer."""
    whole, grown = _solved(CASES[name], monkeypatch, ENABLED=False)
    assert not grown  # no zone
    zone, grown = _solved(CASES[name], monkeypatch)
    assert grown and not any(given_up or waiting for _, given_up, waiting in grown)
    _close(whole, zone, 0.05)

    real = region.Zone.__init__

    def tiny(self, model, gauss, u_r, elements, *args, **kwargs):
        few = np.zeros_like(elements)
        few[np.flatnonzero(elements)[:3]] = True
        real(self, model, gauss, u_r, few, *args, **kwargs)

    monkeypatch.setattr(region.Zone, "__init__", tiny)
    small, grown = _solved(CASES[name], monkeypatch, LAYERS=0, GROWTH=1)
    assert len(grown) >= 3  # it grew as the ground yielded outside it
    _close(whole, small, 0.05)
    monkeypatch.setattr(region.Zone, "__init__", tiny)
    outgrown, grown = _solved(CASES[name], monkeypatch, LAYERS=0, GROWTH=1, MOST=0.03)
    assert not grown[0][1] and grown[-1][1], grown  # it outgrew MOST: the whole ground took over from there
    _close(whole, outgrown, 0.05)
    # a zone over EARLY waits for the stage's iterations on the whole ground, then is built
    waited, grown = _solved(CASES[name], monkeypatch, EARLY=0.0, AMORTIZE=10)
    assert grown[0][2] and any(not waiting and not given_up for _, given_up, waiting in grown[1:]), grown
    _close(whole, waited, 0.05)


def test_the_points_returned_grow_within_the_zone_without_a_refactorization(monkeypatch):
    """A zone returns the stresses only at the points of its watched elements (where the elastic ground yields at
    λd, and two rings round what has yielded); the rings of the zone beyond them are the margin in which they grow
    with no new factorization. On issue 36's c 10 kPa case (coarse mesh) the watched elements stay within the zone,
    grow at least once without a refactorization, and the answer is the whole ground's (the test above)."""
    builds, watched = [], []
    real_watch, real_schur = region.Zone._watch, region.RegionSchur

    def watch(self, elements):
        real_watch(self, elements)
        if self.condensed:  # stage 1's zone (the contact stage's is not condensed: it never refactorizes)
            watched.append((int(self.watched.sum()), bool((self.watched & ~self.elements).any()), len(builds)))

    def schur(*args):
        builds.append(1)
        return real_schur(*args)

    monkeypatch.setattr(region.Zone, "_watch", watch)
    monkeypatch.setattr(region, "RegionSchur", schur)
    run_case(CaseSpec.model_validate(CASES["mohr-coulomb"]))
    assert watched and not any(outside for _, outside, _ in watched)
    assert any(after[0] > before[0] and after[2] == before[2] for before, after in zip(watched, watched[1:]))


@pytest.mark.slow
def test_the_zone_benchmark_compares_like_with_like():
    """``python -m bench.ground --zones 0``: issue 36's three default cases with and without zones, at the default
    mesh; the answers agree (no timing is asserted) and zones are switched back on after it."""
    from bench.ground import zone_study

    study = zone_study(0)
    assert set(study["cases"]) == {"mohr-coulomb", "hoek-brown", "c 10 kPa"}
    for row in study["cases"].values():
        assert row["largest_difference"] < 2e-3 and row["area_difference_m2"] < 0.05
        assert row["whole_s"] > 0 and row["zone_s"] > 0
    assert region.ENABLED
