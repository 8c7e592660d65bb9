"""Anderson mixing (:mod:`solver.stages.mixing`): the companion ``K x`` it carries, and the
residual its least-squares mix minimizes."""
from __future__ import annotations

import numpy as np

from solver.stages.mixing import Anderson


def test_anderson_carries_k_times_the_iterate_along_its_mix():
    """The stop test's ``K x`` without a product: Anderson's mix of the loads each ``G(x)`` was
    solved for is ``K`` times its mix of the ``G(x)`` (checked against the product on a
    contractive affine map with a plastic-like nonlinearity, over several mixes of full depth)."""
    rng = np.random.default_rng(7)
    n = 40
    A = rng.normal(size=(n, n))
    K = A @ A.T + n * np.eye(n)
    f = rng.normal(size=n)
    plastic_load = lambda x: 0.3 * np.tanh(x)  # noqa: E731
    acc = Anderson(4)
    x = np.zeros(n)
    for _ in range(12):
        b = f + plastic_load(x)
        gx = np.linalg.solve(K, b)
        x, Kx = acc.step(x, gx, b)
        assert np.allclose(Kx, K @ x, rtol=1e-10, atol=1e-10 * np.abs(b).max())
    assert np.linalg.norm(f + plastic_load(x) - K @ x) < 1e-8 * np.linalg.norm(f)  # and it converged


def _affine_weights(gxs: list[np.ndarray], target: np.ndarray) -> np.ndarray:
    """The weights (summing to 1) of ``target`` as an affine combination of ``gxs``."""
    A = np.vstack([np.column_stack(gxs), np.ones(len(gxs))])
    weights, *_ = np.linalg.lstsq(A, np.r_[target, 1.0], rcond=None)
    assert np.allclose(A @ weights, np.r_[target, 1.0], atol=1e-10 * np.abs(target).max())
    return weights


def test_the_mix_minimizes_the_residual_it_is_given():
    """On a linear map ``G(x) = K⁻¹(f + P x)`` every residual is affine in the iterate, so the next
    iterate ``Σ α G(x_j)`` has the residual ``Σ α r_j``: given the out-of-balance forces
    ``K (G(x) - x)``, the weights are the least-force affine combination (no other of the same
    iterates has a smaller one, the weights the displacement changes would choose included); given
    nothing, the least displacement change."""
    rng = np.random.default_rng(3)
    n = 30
    A = rng.normal(size=(n, n))
    K = A @ A.T + n * np.eye(n)
    K[0, 0] *= 50.0  # unlike scales of force and displacement: the two minimizations differ
    P = 0.4 * rng.normal(size=(n, n)) / np.sqrt(n)
    f = rng.normal(size=n)
    G = lambda x: np.linalg.solve(K, f + P @ x)  # noqa: E731
    mixer = Anderson(5)
    x = np.zeros(n)
    xs, gxs = [], []
    for _ in range(4):
        gx = G(x)
        xs.append(x)
        gxs.append(gx)
        x_next = mixer.step(x, gx, residual=K @ (gx - x))
        if len(xs) > 1:
            probe = Anderson(5)  # the same iterates, their displacement changes minimized
            for xj, gj in zip(xs, gxs):
                other = probe.step(xj, gj)
            forces = np.column_stack([K @ (g - xj) for xj, g in zip(xs, gxs)])
            changes = np.column_stack([g - xj for xj, g in zip(xs, gxs)])
            alpha, beta = _affine_weights(gxs, x_next), _affine_weights(gxs, other)
            least_force = np.linalg.norm(forces @ alpha)
            assert least_force <= min(np.linalg.norm(forces @ beta), np.linalg.norm(forces[:, -1])) * (1 + 1e-9)
            assert np.linalg.norm(changes @ beta) <= np.linalg.norm(changes @ alpha) * (1 + 1e-9)
            assert np.linalg.norm(forces @ beta) > least_force * (1 + 1e-6)  # the choice matters here
        x = x_next
