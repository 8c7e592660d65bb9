"""The body stiffness against scikit-fem's generic elasticity form, and its pattern."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from solver import CaseSpec
from solver.fe.assembly import PairRotation, assemble_body, elasticity_form, lining_constraints, vector_basis
from solver.geometry.mesh import build_mesh


def test_stiffness_form_is_scikit_fems_linear_elasticity():
    """``elasticity_form`` (σ(u):∇v with the stress recovery's Hooke's law) assembles the
    plane-strain stiffness scikit-fem's ``C(sym_grad u) : sym_grad v`` does."""
    spec = CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0))
    basis = vector_basis(build_mesh(spec).lining)
    young, poisson = 31e9, 0.2
    ours = asm(elasticity_form(young, poisson), basis)
    reference = asm(linear_elasticity(*lame_parameters(young, poisson)), basis)
    assert abs(ours - reference).max() <= 1e-13 * abs(reference).max()


def test_stiffness_pattern_is_structural():
    """Every element entry is kept, exact zeros too: the pattern is the mesh's alone,
    symmetric, and every node's x and y rows reach the same columns (scikit-fem's ``asm``,
    which drops zero entries, fails both at this mesh)."""
    from solver.model import TunnelModel

    model = TunnelModel(CaseSpec(mesh=dict(interface_size=0.05, far_size=2.0)))
    for fb in (model.ground, model.lining):
        body = fb.body
        K = body.K
        pattern = sp.csr_matrix((np.ones(K.nnz), K.indices, K.indptr), shape=K.shape)
        assert abs(pattern - pattern.T).max() == 0
        both = (body.free_of >= 0).all(axis=0)
        x, y = body.free_of[0, both], body.free_of[1, both]
        assert (pattern[x] != pattern[y]).nnz == 0


def _turned(n: int, seed: int):
    """Random unit directions at ``n`` random nodes of the default lining, and its body."""
    spec = CaseSpec(mesh=dict(interface_size=0.2, far_size=6.0))
    mesh = build_mesh(spec).lining
    basis = vector_basis(mesh)
    rng = np.random.default_rng(seed)
    fixed = lining_constraints(basis, scale=spec.geometry.outer_radius)
    held = np.flatnonzero(np.isin(basis.nodal_dofs[0], fixed[0]))[:2]  # on the symmetry line: x held
    nodes = np.r_[held, rng.choice(np.setdiff1d(np.arange(basis.doflocs.shape[1] // 2), held), n, replace=False)]
    angle = rng.uniform(0, 2 * np.pi, nodes.size)
    plain = assemble_body(mesh, 31e9, 0.2, fixed, basis)
    skew = assemble_body(mesh, 31e9, 0.2, fixed, basis, skew=(nodes, np.stack([np.cos(angle), np.sin(angle)])))
    return plain, skew, nodes


def test_skew_basis_is_the_turned_stiffness():
    """Turning the element stiffnesses at the skew nodes before they are summed gives TᵀKT
    of the x, y stiffness; loads and displacements turn with Tᵀ and back with T, so the
    lining's rigid translation stays a zero mode of the turned K, and a node with a held
    DOF (the symmetry line) is not turned."""
    plain, skew, nodes = _turned(40, 0)
    T = skew.skew.matrix()
    np.testing.assert_allclose((T.T @ T - sp.identity(T.shape[0])).toarray(), 0.0, atol=1e-15)
    reference = T.T @ plain.K @ T
    assert abs(skew.K - reference).max() <= 1e-13 * abs(reference).max()
    assert skew.K.nnz == plain.K.nnz  # the same structural pattern
    held = (plain.free_of[:, nodes] < 0).any(axis=0)
    assert held[:2].all() and skew.skew.a.size == np.count_nonzero(~held)
    rng = np.random.default_rng(1)
    u_nodes = rng.standard_normal(plain.free_of.shape) * (plain.free_of >= 0)
    u = skew.restrict(skew.full(u_nodes))
    np.testing.assert_allclose(u, T.T @ plain.restrict(plain.full(u_nodes)), atol=1e-15)
    np.testing.assert_allclose(skew.expand(u), u_nodes, atol=1e-14)
    r = skew.rigid_vertical()
    np.testing.assert_allclose(T @ r, plain.rigid_vertical(), atol=1e-15)
    assert np.abs(skew.K @ r).max() <= 1e-9 * abs(skew.K).max()
    with pytest.raises(ValueError, match="unit vectors"):
        assemble_body(plain.mesh, 31e9, 0.2, [], plain.basis, skew=(nodes[:1], np.array([[0.6], [0.6]])))
    # energy is basis-free
    assert np.isclose(u @ (skew.K @ u), plain.restrict(plain.full(u_nodes)) @ (plain.K @ plain.restrict(
        plain.full(u_nodes))), rtol=1e-12)


def test_pair_rotation_applies_t_and_its_transpose():
    n = 30
    rng = np.random.default_rng(2)
    a, b = np.array([0, 7, 20]), np.array([1, 9, 25])
    angle = rng.uniform(0, 2 * np.pi, a.size)
    rotation = PairRotation(n, a, b, np.cos(angle), np.sin(angle))
    T = rotation.matrix().toarray()
    X = rng.standard_normal((n, 2))
    np.testing.assert_allclose(rotation.apply(X), T @ X, atol=1e-15)
    np.testing.assert_allclose(rotation.apply_transpose(X), T.T @ X, atol=1e-15)


def test_the_gradient_operators_are_scikit_fems_interpolation():
    """The model's operators give the displacement gradient scikit-fem's ``interpolate`` does, on
    both bodies at the stored points (``nodal_gradient_operator``, on the full DOF vector) and on
    the ground's unknowns (``gradient_operator``: the skew interface basis turned back); a random
    displacement, so every basis function is seen."""
    from solver.model import TunnelModel

    model = TunnelModel(CaseSpec(mesh=dict(interface_size=0.3, far_size=10.0)))
    rng = np.random.default_rng(7)
    for name in ("ground", "lining"):
        body, basis = getattr(model, name).body, model.point_basis(name)
        u = rng.standard_normal((2, body.basis.mesh.p.shape[1]))
        expected = basis.interpolate(body.full(u)).grad
        got = (model.point_gradient(name) @ body.full(u)).reshape(expected.shape)
        assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()
    body = model.ground.body
    x = rng.standard_normal(body.n)
    expected = model.point_basis("ground").interpolate(body.full(body.expand(x))).grad
    got = (model.gradient_operator("points") @ x).reshape(expected.shape)
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()
