"""The body stiffness against scikit-fem's generic elasticity form, and its pattern."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from solver import CaseSpec
from solver.assembly import elasticity_form, vector_basis
from solver.mesh import build_mesh


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
    """Every element entry is kept, exact zeros too: the pattern is symmetric and every
    node's x and y rows reach the same columns (what the interface rotation's in-place
    path needs; scikit-fem's ``asm``, which drops zero entries, fails both at this mesh)."""
    from solver.linalg import _positions
    from solver.model import TunnelModel

    model = TunnelModel(CaseSpec(mesh=dict(interface_size=0.05, far_size=2.0)))
    for fb in (model.ground, model.lining):
        body = fb.body
        K = body.K
        pattern = sp.csr_matrix((np.ones(K.nnz), K.indices, K.indptr), shape=K.shape)
        assert abs(pattern - pattern.T).max() == 0
        both = (body.free_of >= 0).all(axis=0)
        x, y = body.free_of[0, both], body.free_of[1, both]
        np.testing.assert_array_equal(np.diff(K.indptr)[x], np.diff(K.indptr)[y])
        np.testing.assert_array_equal(K.indices[_positions(K.indptr, x)], K.indices[_positions(K.indptr, y)])
