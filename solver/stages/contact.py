"""The contact stage: the case's loads solved forward to interface jumps, and the contact
problem of its interface model on the model's interface flexibility ``S = B K⁺ Bᵀ``.

Each body's factorization has the interface unknowns last, so the solve splits around the
contact problem: a forward solve of the loads gives the jumps ``d = B K⁺ f``; the contact
problem gives the tractions t; one backward solve with them the displacements
(:mod:`.recovery`). Frictionless contact is the paper's bolt-point problem
(:func:`solver.contact.bolt.solve_contact`), Coulomb friction :mod:`solver.contact.friction`,
a bonded interface a tie (:func:`tie`), a segmental lining :mod:`solver.contact.floating`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as la

from ..build import BuiltModel
from ..contact import floating, friction
from ..contact.bolt import BoltedSolution, DualProblem, pressure_scale, solve_contact
from ..errors import SolverError
from ..fe.flexibility import Rows, rows_of_model
from ..spec import CaseSpec
from .loads import stage_loads
from .state import Forward


def forward_stage(model: BuiltModel, spec: CaseSpec, rows: Rows | None = None):
    """Loads, both bodies' loads of the contact stage solved forward (:class:`Forward`),
    ``d = B K⁺ f`` at the rows the factorization serves and the lining's load on its modes F2.

    Both stages release parts of one excavation load r: stage 1 ``λd r`` on the ground
    alone, the contact stage ``(1 - λd) r``; one forward solve of r serves both.
    """
    rows = rows or rows_of_model(spec.interface.model)
    loads = stage_loads(model, spec)
    ground, lining = model.ground, model.lining
    y_l = lining.forward(loads.lining, rows)
    if loads.release is not None:
        ld = spec.excavation.deconfinement
        y_r = ground.forward(loads.release, rows)
        y_g = (1.0 - ld) * y_r
        if loads.seepage is not None:
            y_g = y_g + ground.forward(loads.seepage, rows)
        stage = Forward(ground=y_g, lining=y_l, release=y_r, deconfinement=ld)
    else:
        stage = Forward(ground=ground.forward(loads.ground, rows), lining=y_l)
    d = ground.jumps(stage.ground, rows) + lining.jumps(y_l, rows)
    return loads, stage, d, model.mode_loads(loads.lining)


def contact_tractions(model: BuiltModel, spec: CaseSpec, d: np.ndarray, F2) -> tuple[BoltedSolution, np.ndarray]:
    """The contact problem of the interface jumps ``d`` (and the lining's load on its modes
    ``F2``): its solution and the interface tractions ``t`` (normal, then tangential rows)."""
    iface, m, g0, sv = model.mesh.interface, model.m, spec.geometry.gap, spec.solver
    kind = spec.interface.model
    if model.joint_rows is not None:
        return floating_contact(model, spec, d, F2, rows_of_model(kind))
    if kind == "frictionless":
        sol = solve_contact(dual(model, d, F2, g0), iface.theta, inner=sv.inner, tol=sv.tolerance,
                            max_iterations=sv.max_iterations, bolt=sv.bolt)
        return sol, np.r_[sol.lam, np.zeros(m - 2)]
    if kind == "bonded":
        t, a = tie(model, d, F2)
        return BoltedSolution(a=a, bolt=None), t
    fp = friction.FrictionProblem(S=model.S, d=d, g0=g0, w=model.w, r=model.r, F2=F2, m=m,
                                  mu=spec.interface.friction)
    sol = friction.solve_coulomb(fp, iface.theta, tol=sv.tolerance, max_iterations=sv.max_iterations,
                                 bolt=sv.bolt)
    return sol, sol.t


def _row_kinds(model: BuiltModel, spec: CaseSpec, size: int):
    """Each row's kind (unilateral, equality, friction), friction partner and coefficient."""
    m, jr, R = model.m, model.joint_rows, model.w.size
    kind = np.full(size, floating.UNILATERAL, np.int8)
    partner = np.full(size, -1)
    mu = np.zeros(size)
    if spec.interface.model == "bonded":
        kind[:m] = floating.EQUALITY
    jt = m + np.flatnonzero(~jr.normal)  # joint tangential rows: partner the normal row at the node
    kind[jt] = floating.EQUALITY if spec.lining.joints.shear == "bonded" else floating.FRICTION
    partner[jt] = m + jr.partner[jt - m]
    mu[jt] = spec.lining.joints.friction
    if size == R:
        tr = model.tangential_rows
        kind[tr] = floating.EQUALITY if spec.interface.model == "bonded" else floating.FRICTION
        partner[tr] = model.tangential
        mu[tr] = spec.interface.friction
    return kind, partner, mu


def floating_contact(model: BuiltModel, spec: CaseSpec, d: np.ndarray, F, rows: Rows):
    """The segmental lining's contact problem (:mod:`solver.contact.floating`) at ``rows``: its
    solution and the tractions on every row (zero where ``rows`` has none)."""
    iface, m, jr = model.mesh.interface, model.m, model.joint_rows
    nj, R = jr.size, model.w.size
    size = m + nj if rows == "normal" else R
    kind, partner, mu = _row_kinds(model, spec, size)
    g0 = np.zeros(size)
    g0[:m] = spec.geometry.gap
    where = ([f"interface {th:.1f} deg" for th in iface.theta]
             + [f"joint {model.mesh.joints.theta[j]:.1f} deg, {r:+.3f} m from the mid-surface"
                for j, r in zip(jr.joint, jr.across)]
             + [f"interface shear {th:.1f} deg" for th in iface.theta[model.tangential]])[:size]
    fp = floating.FloatingProblem(
        S=model.flexibility(rows), d=d, g0=g0, w=model.w[:size], G=model.G[:size], F=np.atleast_1d(F),
        kind=kind, partner=partner, mu=mu, labels=model.modes.label,
        p_scale=pressure_scale(float(np.linalg.norm(F)), iface.normal[1], iface.weight), where=tuple(where),
        group=np.r_[-1 - np.arange(m), jr.joint, -1 - m - np.arange(R - m - nj)][:size])
    sv = spec.solver
    sol = floating.solve_floating(fp, tol=sv.tolerance, max_iterations=sv.max_iterations)
    t = np.zeros(R)
    t[:size] = sol.t
    return sol, t


def dual(model: BuiltModel, d: np.ndarray, F2: float, g0: float) -> DualProblem:
    """The frictionless problem in interface form (normal rows only)."""
    m, iface = model.m, model.mesh.interface
    return DualProblem(S=model.S_normal, d=d[:m], g0=np.full(m, g0), w=iface.weight.copy(),
                       nu2=iface.normal[1].copy(), F2=F2)


def dual_problem(model: BuiltModel, spec: CaseSpec) -> DualProblem:
    """The frictionless contact stage of ``spec`` in interface form (:class:`DualProblem`; a
    monolithic lining's: a segmental one's is :mod:`solver.contact.floating`'s)."""
    if model.joint_rows is not None:
        raise ValueError("dual_problem: a segmental lining's contact problem has the joints' rows and every "
                         "segment's modes (solver.contact.floating.FloatingProblem), not the one-mode dual")
    model = model.for_case(spec)
    d, F2 = forward_stage(model, spec, "normal")[2:]
    return dual(model, d, F2, spec.geometry.gap)


def tie(model: BuiltModel, d: np.ndarray, F2: float) -> tuple[np.ndarray, float]:
    """Bonded interface: J = 0 at every row and the lining balance; no bolt needed."""
    w, r, S = model.w, model.r, model.S
    R = r.size
    A = np.zeros((R + 1, R + 1))
    A[:R, :R] = (w[:, None] * S) * w[None, :]
    A[:R, R] = A[R, :R] = w * r
    rhs = np.r_[w * d, -F2]
    x = la.solve(A, rhs, assume_a="sym")
    if not np.all(np.isfinite(x)):
        raise SolverError("the bonded interface system is singular")
    return x[:R], float(x[R])


__all__ = ["forward_stage", "contact_tractions", "floating_contact", "dual", "dual_problem", "tie"]
