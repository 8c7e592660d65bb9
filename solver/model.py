"""Build once, solve many: what a geometry, its mesh settings and materials fix.

A :class:`TunnelModel` holds the mesh, both bodies' stiffness and factorizations and
the dense interface flexibility. Its :meth:`~TunnelModel.solve` takes any case that
shares those (:func:`model_key`) and varies only loads, construction stages, the
interface model, solver options or design inputs (SPEC §1.1-§1.3)::

    model = TunnelModel(spec)            # mesh, assembly, factorization: once
    for case in cases:                   # same model_key(case)
        solution = model.solve(case)     # forward solves, the contact solve, backward solves

Stages (``excavation.method = "deconfinement"``, SPEC §1.1): the geostatic state σ0
needs no solve (zero displacement); the excavation load is the discrete one, the
nodal forces ``r = f_ext - ∫Bᵀσ0`` that σ0 leaves unbalanced on the ground with its
hole (zero at every free node off the excavation boundary: the unexcavated discrete
ground is in exact equilibrium). Stage 1 releases ``λd r`` on the ground alone; stage 2
releases ``(1 - λd) r`` with the lining in place and its weight, with contact on the
increment.

Loads. Every load is linear in ρg, q, K0·q and K0·ρg (:data:`LOAD_TERMS`), so a model
assembles those four ground load shapes and the lining's unit weight once; a case
combines them. Solves. Each body's factorization has the interface unknowns last, so a
case's solve splits around the contact problem: a forward solve of its load gives the
interface jumps ``B K⁺ f``, and one backward solve with the contact tractions the
displacements (:meth:`FactoredBody.forward`, :meth:`~FactoredBody.backward`): the
triangular solves of one elastic solve per body, the stage-1 displacement of a staged
excavation a second column of the ground's backward solve.
"""
from __future__ import annotations

import json
import os
import threading
import time
from collections import OrderedDict
import copy
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la

import scipy.sparse as sp

from . import floating, friction, joints, water
from .assembly import (
    Basis,
    assemble_body,
    gradient_operator,
    gravity_load,
    ground_constraints,
    lining_constraints,
    point_basis,
    vector_basis,
)
from .ground import LOAD_TERMS, load_shapes, moduli
from .ground import load_coefficients as _layer_coefficients
from .contact import BoltedSolution, BoltTrial, DualProblem, SolverError, pressure_scale, solve_contact
from .flexibility import (
    FactoredBody,
    ScaledBody,
    Rows,
    interface_operator,
    interface_rows,
    lining_pin,
    rows_of_model,
)
from .mesh import TunnelMesh, build_mesh
from .linalg import blas_threads
from .post import kkt_residual
from .spec import CaseSpec
from .strata import layer_at, strata

__all__ = ["TunnelModel", "Solution", "model_key", "shared_model", "load_coefficients", "LOAD_TERMS"]


def load_coefficients(spec: CaseSpec) -> np.ndarray:
    """The case's values of :data:`~solver.ground.LOAD_TERMS`, layer after layer."""
    return _layer_coefficients(spec, strata(spec))


#: Relative gap (to the largest displacement) below which a node counts as closed.
CONTACT_GAP_TOL = 1e-6
#: KKT residual every answer meets whatever its inner tolerance (exact active sets reach
#: 1e-10 or less; the field measured over the test suite's cases stays below 1e-7).
KKT_ACCEPT = 1e-6


def accepted_residual(tolerance: float) -> float:
    """The largest discrete KKT residual (:func:`solver.post.kkt_residual`) of an answer given
    as a result: the case's ``solver.tolerance`` or :data:`KKT_ACCEPT`, whichever is larger."""
    return max(tolerance, KKT_ACCEPT)


def model_key(spec: CaseSpec) -> str:
    """The canonical JSON of what a :class:`TunnelModel` fixes (cases with equal keys share one).

    The ground's Young's moduli (and their gradients) enter relative to the first layer's:
    the ground's stiffness matrix is linear in them, so a case whose ground is the model's
    with every modulus times α solves on the model's factorization with ``K⁺`` divided by α
    (:class:`~solver.flexibility.ScaledBody`)."""
    layers = strata(spec)
    e0 = layers[0].young  # the ground's stiffness enters as ratios to it: a model serves every scale
    shared = {
        "geometry": spec.geometry.model_dump(mode="json"),
        "mesh": spec.mesh.model_dump(mode="json"),
        "boundaries": spec.boundaries.model_dump(mode="json"),
        "strata": [[s.top, s.bottom, s.young / e0, s.poisson, s.young_gradient / e0] for s in layers],
        "lining": {"young": spec.lining.young, "poisson": spec.lining.poisson},
    }
    j = spec.lining.joints
    if j.count:  # the joints cut the mesh; their shear law is the contact problem's
        shared["joints"] = [j.count, j.offset, j.contact_height]
    return json.dumps(shared, sort_keys=True, separators=(",", ":"))


@dataclass(frozen=True)
class StageLoads:
    """Free-DOF loads (N/m) of one case: the contact stage's ground and lining loads, and
    the full excavation load ``release`` (None for ``wished-in-place``; stage 1 releases
    λd of it, the contact stage the rest)."""

    ground: np.ndarray
    lining: np.ndarray
    release: np.ndarray | None
    #: the seepage force of a drained lining's stage 2 (already in ``ground``), or None
    seepage: np.ndarray | None = None


@dataclass(frozen=True)
class Forward:
    """A case's loads solved forward (:meth:`FactoredBody.forward`): the contact stage's
    ground and lining loads and, for a staged excavation, the whole release r and λd."""

    ground: np.ndarray
    lining: np.ndarray
    release: np.ndarray | None = None
    deconfinement: float = 0.0


@dataclass
class Solution:
    """The solved contact stage of one case, in SI units.

    u_ground : (2, Ng) m, ground displacement since excavation (stages 1 + 2), or since the
        stress-free start for ``wished-in-place``; u_stage1 : (2, Ng) m, stage 1 alone.
    u_lining : (2, Nl) m, lining displacement since placement.
    lam, shear : (m,) Pa, contact pressure and shear traction on the lining.
    normal_jump, tangential_jump : (m,) m, [u]ν and [u]τ of the contact stage.
    in_contact, slipping : (m,) bool, closed nodes (all of them for ``bonded``) and those of
        them that slip (a tangential jump, which the bond forbids).
    """

    spec: CaseSpec
    u_ground: np.ndarray
    u_stage1: np.ndarray
    u_lining: np.ndarray
    lam: np.ndarray
    shear: np.ndarray
    normal_jump: np.ndarray
    tangential_jump: np.ndarray
    in_contact: np.ndarray
    slipping: np.ndarray
    a: float | np.ndarray
    bolt: int | None
    trials: list[BoltTrial]
    iterations: int
    admissible: bool
    F2: float
    kkt_residual: float
    timings: dict = field(default_factory=dict)
    #: N/m: the (half) lining's weight, and the upward resultant of the water on its extrados
    lining_weight: float = 0.0
    water_uplift: float = 0.0
    #: water: (N,) pore pressure at the ground's nodes after stage 2 (Pa; hydrostatic unless
    #: drained), (m,) water pressure on the lining's extrados (Pa), inflow (m³/s per metre)
    pore: np.ndarray | None = None
    water_pressure: np.ndarray | None = None
    water_inflow: float = 0.0
    #: yielding ground (:func:`solver.plastic.solve_staged`): effective stress, yield flags and
    #: equivalent plastic strain at the sub-triangle centroids, iterations, ground reaction curve
    plastic: dict | None = None
    #: a segmental lining's joints (:class:`solver.joints.JointResults`) and its bolt set
    joints: "joints.JointResults | None" = None

    @property
    def gap(self) -> np.ndarray:
        return self.spec.geometry.gap - self.normal_jump


class TunnelModel:
    """Mesh, stiffness, factorizations and interface flexibility of one geometry and material pair.

    Attributes
    ----------
    mesh : TunnelMesh
    ground, lining : FactoredBody (``B`` has the interface rows of :func:`interface_rows`).
    S : (R, R) m/N per m of interface, the dense interface flexibility ``B K⁺ Bᵀ`` of both bodies.
    r : (R,) jumps of a unit rigid upward lining translation, ``[ν2; τ2]``.
    timings : seconds spent meshing, assembling and factorizing.
    """

    def __init__(self, spec: CaseSpec):
        self.key = model_key(spec)
        t0 = time.perf_counter()
        self.mesh: TunnelMesh = build_mesh(spec)
        t1 = time.perf_counter()
        g = spec.geometry
        gb = vector_basis(self.mesh.ground)
        iface = self.mesh.interface
        self.layers = strata(spec)
        #: the first layer's Young's modulus the ground was assembled and factorized with (Pa)
        self.ground_young = self.layers[0].young
        self.band = self.mesh.ground_band
        young, poisson = moduli(self.layers, self.band, np.asarray(gb.global_coordinates())[1])
        # interface nodes carry normal and tangential unknowns (skew basis): each contact row
        # then acts on one unknown, and the normal ones alone can be ordered last
        ground = assemble_body(self.mesh.ground, young, poisson,
                               ground_constraints(gb, width=g.width, height=g.height,
                                                  side=spec.boundaries.side, bottom=spec.boundaries.bottom), gb,
                               skew=(iface.ground_node, iface.normal))
        lb = vector_basis(self.mesh.lining)
        cut = self.mesh.joints
        skew_nodes, skew_dirs = iface.lining_node, iface.normal
        if cut is not None:  # a joint's second corner on the extrados faces the same ground node
            stations, corners = self._joint_corners()
            skew_nodes, skew_dirs = np.r_[skew_nodes, corners], np.hstack([skew_dirs, iface.normal[:, stations]])
        loose = joints.axis_faces(cut) if cut is not None else None
        lining = assemble_body(self.mesh.lining, spec.lining.young, spec.lining.poisson,
                               lining_constraints(lb, scale=g.outer_radius, loose=loose), lb,
                               skew=(skew_nodes, skew_dirs))
        t2 = time.perf_counter()
        nodes, directions, self.tangential = interface_rows(iface)
        Bg = interface_operator(ground, iface.ground_node[nodes], directions, +1.0)
        Bl = interface_operator(lining, iface.lining_node[nodes], directions, -1.0)
        m = iface.size
        self._S: dict[str, np.ndarray] = {}
        self.w = np.r_[iface.weight, iface.weight[self.tangential]]
        #: the lining's upward translation as a whole (its weight's and the water's resultant)
        self.vertical = lining.rigid_vertical()
        #: row indices of the interface's tangential rows (after a segmental lining's joint rows)
        self.tangential_rows = m + np.arange(self.tangential.size)
        self.joint_rows: joints.JointRows | None = None
        if cut is None:
            self.ground = FactoredBody(ground, Bg, m)
            self.lining = FactoredBody(lining, Bl, m, lining_pin(lining, iface.lining_node))
            self.r = np.r_[iface.normal[1], iface.tangent[1, self.tangential]]
            #: the lining's rigid modes: its vertical translation (n,), or a segmental lining's (n, k)
            self.rigid = self.vertical
        else:
            self._segmental(spec, ground, lining, Bg, Bl, nodes, directions)
        self.timings = {"mesh": t1 - t0, "assembly": t2 - t1, "factorization": 0.0}
        self._factorize(rows_of_model(spec.interface.model))
        self._units: dict[str, np.ndarray] = {}
        self._point_bases: dict = {}
        self._gradients: dict = {}
        self._seepage: "OrderedDict[tuple, water.SeepageModel]" = OrderedDict()
        self._lock = threading.Lock()

    @property
    def m(self) -> int:
        return self.mesh.interface.size

    # -- a segmental lining (SPEC §1.6) ------------------------------------------------------
    def _joint_corners(self) -> tuple[np.ndarray, np.ndarray]:
        """The interface stations at the joints inside the half model, and each joint's second
        extrados corner (the invert-side face's outermost node; the station's lining node is the
        crown-side one)."""
        cut, iface = self.mesh.joints, self.mesh.interface
        inner = [j for j in range(cut.size) if not cut.on_axis(j)]
        stations = np.array([int(np.flatnonzero(iface.lining_node == cut.before[j][-1])[0]) for j in inner], np.int64)
        corners = np.array([cut.after[j][-1] for j in inner], np.int64)
        return stations, corners

    def _segmental(self, spec: CaseSpec, ground, lining, Bg, Bl, nodes, directions) -> None:
        """Rows, bodies and rigid modes of a segmental lining: the interface rows of a joint's
        station see the mean of its two corners; the joints' rows come after the interface's
        normal rows (so the ``"normal"`` factorization serves them too); each segment's rigid
        modes are pinned for ``K⁺`` and solved for (:mod:`solver.floating`)."""
        iface, m, g = self.mesh.interface, self.m, spec.geometry
        stations, corners = self._joint_corners()
        other = iface.lining_node.copy()
        other[stations] = corners
        # each corner takes its own edge's Simpson share of the station's weight (L/6 of each edge)
        theta = iface.theta
        before = theta[stations] - theta[stations - 2]
        share = np.ones(m)
        share[stations] = before / (before + theta[stations + 2] - theta[stations])
        Bl_other = interface_operator(lining, other[nodes], directions, -1.0)
        Bl = sp.diags(share[nodes]) @ Bl + sp.diags(1.0 - share[nodes]) @ Bl_other
        height = spec.lining.joints.contact_height or g.thickness
        self.r_mid = g.inner_radius + 0.5 * g.thickness
        rows = joints.joint_rows(lining, self.mesh.joints, self.mesh.center, r_mid=self.r_mid, height=height,
                                 shear=True)
        self.joint_rows, nj = rows, rows.size
        Bl = sp.vstack([Bl[:m], rows.B, Bl[m:]]).tocsr()
        Bg = sp.vstack([Bg[:m], sp.csr_matrix((nj, ground.n)), Bg[m:]]).tocsr()
        modes = joints.rigid_modes(lining, self.mesh, avoid=np.unique(Bl.indices))
        self.modes = modes
        self.ground = FactoredBody(ground, Bg, m + nj)
        self.lining = FactoredBody(lining, Bl, m + nj, modes.pins)
        self.rigid = modes.vectors
        #: jumps of each unit rigid mode (R, k), with the sign of ``r``: J = d - S W t - G a
        self.G = -(Bl @ modes.vectors)
        self.r = None
        self.w = np.r_[iface.weight, rows.weight, iface.weight[self.tangential]]
        self.tangential_rows = m + nj + np.arange(self.tangential.size)

    def _rigid_motion(self, a) -> np.ndarray:
        """The lining's rigid motion of amplitude(s) ``a`` on its free DOFs."""
        return a * self.rigid if self.rigid.ndim == 1 else self.rigid @ a

    def mode_loads(self, f_lining: np.ndarray):
        """The lining's loads on its rigid modes: F2 (N/m, float) or a segmental lining's (k,)."""
        F = f_lining @ self.rigid
        return float(F) if np.ndim(F) == 0 else F

    def _floating(self, spec: CaseSpec, d: np.ndarray, F: np.ndarray, rows: Rows):
        """The segmental lining's contact problem (:mod:`solver.floating`) at ``rows``: its
        solution and the tractions on every row (zero where ``rows`` has none)."""
        iface, m, jr = self.mesh.interface, self.m, self.joint_rows
        nj, R = jr.size, self.w.size
        size = m + nj if rows == "normal" else R
        model, shear = spec.interface.model, spec.lining.joints.shear
        kind = np.full(size, floating.UNILATERAL, np.int8)
        partner = np.full(size, -1)
        mu = np.zeros(size)
        if model == "bonded":
            kind[:m] = floating.EQUALITY
        jt = m + np.flatnonzero(~jr.normal)  # joint tangential rows: partner the normal row at the node
        kind[jt] = floating.EQUALITY if shear == "bonded" else floating.FRICTION
        partner[jt] = m + jr.partner[jt - m]
        mu[jt] = spec.lining.joints.friction
        if size == R:
            tr = self.tangential_rows
            kind[tr] = floating.EQUALITY if model == "bonded" else floating.FRICTION
            partner[tr] = self.tangential
            mu[tr] = spec.interface.friction
        g0 = np.zeros(size)
        g0[:m] = spec.geometry.gap
        where = ([f"interface {th:.1f} deg" for th in iface.theta]
                 + [f"joint {self.mesh.joints.theta[j]:.1f} deg r={r:.3f} m" for j, r in zip(jr.joint, jr.radius)]
                 + [f"interface shear {th:.1f} deg" for th in iface.theta[self.tangential]])[:size]
        fp = floating.FloatingProblem(
            S=self._flexibility(rows), d=d, g0=g0, w=self.w[:size], G=self.G[:size], F=np.atleast_1d(F),
            kind=kind, partner=partner, mu=mu, labels=self.modes.label,
            p_scale=pressure_scale(float(np.linalg.norm(F)), iface.normal[1], iface.weight), where=tuple(where),
            group=np.r_[-1 - np.arange(m), jr.joint, -1 - m - np.arange(R - m - nj)][:size])
        sv = spec.solver
        sol = floating.solve_floating(fp, tol=sv.tolerance, max_iterations=sv.max_iterations)
        t = np.zeros(R)
        t[:size] = sol.t
        return sol, t

    def drop_factorizations(self) -> None:
        """Forget both bodies' factorizations and the flexibilities computed with them:
        their memory is freed and they are rebuilt, and timed, on next use
        (``python -m bench.solver`` times them repeatedly this way)."""
        for fb in (self.ground, self.lining):
            fb.drop()
        self._S.clear()
        self.timings["factorization"] = 0.0
        self.timings.pop("flexibility", None)

    def point_basis(self, body: str) -> "Basis":
        """``'ground'`` or ``'lining'`` basis at the sub-triangle centroids (built on first use)."""
        if body not in self._point_bases:
            self._point_bases[body] = point_basis(getattr(self, body).body)
        return self._point_bases[body]

    def gradient_operator(self, where: str):
        """The ground's displacement gradient, as an operator on its unknowns, at its quadrature
        points (``'gauss'``) or at the sub-triangle centroids (``'points'``); built on first use."""
        if where not in self._gradients:
            body = self.ground.body
            basis = body.basis if where == "gauss" else self.point_basis("ground")
            self._gradients[where] = gradient_operator(body, basis)
        return self._gradients[where]

    def _factorize(self, rows: Rows) -> None:
        """Both bodies' factorizations serving ``rows`` (built once; timed)."""
        t0 = time.perf_counter()
        self.ground.factor(rows)
        self.lining.factor(rows)
        self.timings["factorization"] += time.perf_counter() - t0

    def _flexibility(self, rows: Rows) -> np.ndarray:
        """``S_ground / α + S_lining`` (each body's flexibility computed once per model)."""
        if rows not in self._S:
            self._factorize(rows)
            t0 = time.perf_counter()
            self._S[rows] = (self.ground.base.flexibility(rows), self.lining.flexibility(rows))  # each symmetric
            self.timings["flexibility"] = self.timings.get("flexibility", 0.0) + time.perf_counter() - t0
        ground, lining = self._S[rows]
        return ground / self.ground.scale + lining

    @property
    def S(self) -> np.ndarray:
        """(R, R) interface flexibility of the normal and tangential rows (built on first use)."""
        return self._flexibility("all")

    @property
    def S_normal(self) -> np.ndarray:
        """(m, m) normal block of the flexibility: all that frictionless contact needs (built
        on first use from its own factorization, so a result never depends on what the model
        solved before)."""
        return self._flexibility("normal")

    def accepts(self, spec: CaseSpec) -> bool:
        return model_key(spec) == self.key

    # -- loads -------------------------------------------------------------------------
    def _unit(self, name: str, compute) -> np.ndarray:
        """A unit load vector of this model, assembled on first use."""
        if name not in self._units:
            self._units[name] = compute()
        return self._units[name]

    def _shapes(self, spec: CaseSpec, method: str) -> np.ndarray:
        """(N, 4 L) full-DOF ground load per :data:`~solver.ground.LOAD_TERMS` term of each
        layer, assembled once per model (:func:`solver.ground.load_shapes`): the applied loads
        (``method = "wished-in-place"``) or the excavation load ``f_ext - ∫Bᵀσ0``
        (``"deconfinement"``). Every ground load of a case is ``shapes @ load_coefficients(case)``:
        a sweep over loads, densities and K0 assembles nothing."""
        g = spec.geometry
        return self._unit(f"shapes_{method}", lambda: load_shapes(
            self.ground.body.basis, self.band, self.layers, width=g.width, height=g.height,
            side=spec.boundaries.side, method=method))

    def ground_loads(self, spec: CaseSpec) -> np.ndarray:
        """Full-DOF external loads on the ground (N/m): gravity, surface load, a 'pressure' side."""
        return self._shapes(spec, "wished-in-place") @ load_coefficients(spec)

    def excavation_load(self, spec: CaseSpec) -> np.ndarray:
        """Full-DOF excavation load (N/m): what the in-situ state leaves unbalanced, ``f_ext -
        ∫Bᵀσ0``, and below a water table the water's share, so that the effective traction
        is released (:func:`solver.water.effective_release`)."""
        r = self._shapes(spec, "deconfinement") @ load_coefficients(spec)
        if spec.water.table is not None:
            r = r + self._effective_release(spec)
        return r

    def _effective_release(self, spec: CaseSpec) -> np.ndarray:
        layers, w = strata(spec), spec.water
        k0 = np.array([s.k0 for s in layers])
        body, iface = self.ground.body, self.mesh.interface
        return water.effective_release(body, iface.ground_node, self.mesh.center, w.table, w.unit_weight,
                                       lambda x: k0[layer_at(layers, -x[1])])

    def stage_loads(self, spec: CaseSpec) -> StageLoads:
        ground, lining = self.ground.body, self.lining.body
        f_l = lining.restrict(spec.lining.density * spec.loads.gravity * self._lining_shape())
        w = spec.water
        if w.table is not None and w.lining == "watertight":
            f_l = f_l + lining.restrict(self._water_on_lining(spec))
        if spec.excavation.method == "wished-in-place":
            return StageLoads(ground.restrict(self.ground_loads(spec)), f_l, None)
        loads = ground.restrict(self.excavation_load(spec))
        stage2 = (1.0 - spec.excavation.deconfinement) * loads
        seep = None
        if spec.drained:
            seep = ground.restrict(self._seepage_force(spec))
            stage2 = stage2 + seep
        return StageLoads(stage2, f_l, loads, seep)

    def _water_on_lining(self, spec: CaseSpec) -> np.ndarray:
        """Full-DOF load of the hydrostatic water on the lining's extrados (watertight)."""
        return water.pressure_load(self.lining.body, self.mesh.interface.lining_node, self.mesh.center,
                                   spec.water.table, spec.water.unit_weight)

    def _seepage_model(self, spec: CaseSpec) -> water.SeepageModel:
        """The head problem of a drained case, its factorization kept per table depth and
        permeabilities (the two most recent)."""
        k = np.array([s.permeability for s in strata(spec)])
        key = (spec.water.table, tuple(k))
        with self._lock:
            if key not in self._seepage:
                g = spec.geometry
                self._seepage[key] = water.SeepageModel(self.mesh.ground, self.mesh.interface.ground_node,
                                                        k[self.band], spec.water.table, g.width, g.height)
                while len(self._seepage) > 2:
                    self._seepage.popitem(last=False)
            return self._seepage[key]

    def seepage(self, spec: CaseSpec) -> water.Seepage:
        """Steady seepage of a drained case (:class:`solver.water.SeepageModel`)."""
        return self._seepage_model(spec).solve(spec.water.unit_weight)

    def _seepage_force(self, spec: CaseSpec) -> np.ndarray:
        model = self._seepage_model(spec)
        seep = model.solve(spec.water.unit_weight)
        u0 = water.hydrostatic(self.mesh.ground.p[1], spec.water.table, spec.water.unit_weight)
        return water.seepage_load(self.ground.body.basis, model.basis, seep.pore - u0)

    def _lining_shape(self) -> np.ndarray:
        return self._unit("lining_gravity", lambda: gravity_load(self.lining.body.basis, 1.0, 1.0))

    # -- solve -------------------------------------------------------------------------
    def solve(self, spec: CaseSpec) -> Solution:
        """Solve ``spec`` (which must share this model's :func:`model_key`)."""
        if not self.accepts(spec):
            raise ValueError("the case does not share this model's geometry, mesh, boundaries and materials")
        t0 = time.perf_counter()
        model = self.for_case(spec)
        with blas_threads():
            rows = rows_of_model(spec.interface.model)
            self._factorize(rows)
            if spec.plastic:
                from .plastic import solve_staged

                sol = solve_staged(model, spec, rows, t0)
            else:
                loads, stage, d, F2 = model._contact_stage(spec, rows)
                sol = model._finish(spec, rows, loads, stage, d, F2, t0)
        limit = accepted_residual(spec.solver.tolerance)
        if not sol.kkt_residual <= limit:  # NaN too: never a result above the tolerance
            raise SolverError(
                f"solver: the discrete KKT residual of the answer is {sol.kkt_residual:.3g}, above the accepted "
                f"{limit:.3g} (max of solver.tolerance and {KKT_ACCEPT:g}); the inputs are probably at the edge of "
                "what double precision resolves (e.g. loads or stiffnesses many orders of magnitude apart)")
        return sol

    def contact_tractions(self, spec: CaseSpec, d: np.ndarray, F2: float) -> tuple[BoltedSolution, np.ndarray]:
        """The contact problem of the interface jumps ``d`` (and the lining's vertical load
        ``F2``): its solution and the interface tractions ``t`` (normal, then tangential rows)."""
        iface, m, g0, sv = self.mesh.interface, self.m, spec.geometry.gap, spec.solver
        model = spec.interface.model
        if self.joint_rows is not None:
            return self._floating(spec, d, F2, rows_of_model(model))
        if model == "frictionless":
            sol = solve_contact(self._dual(d, F2, g0), iface.theta, inner=sv.inner, tol=sv.tolerance,
                                max_iterations=sv.max_iterations, bolt=sv.bolt)
            return sol, np.r_[sol.lam, np.zeros(m - 2)]
        if model == "bonded":
            t, a = self._tie(d, F2)
            return BoltedSolution(a=a, bolt=None), t
        fp = friction.FrictionProblem(S=self.S, d=d, g0=g0, w=self.w, r=self.r, F2=F2, m=m,
                                      mu=spec.interface.friction)
        sol = friction.solve_coulomb(fp, iface.theta, tol=sv.tolerance, max_iterations=sv.max_iterations,
                                     bolt=sv.bolt)
        return sol, sol.t

    def for_case(self, spec: CaseSpec) -> "TunnelModel":
        """This model as ``spec``'s: itself, or, when the case's ground is this model's with
        every modulus times α, a view whose ground is :class:`ScaledBody` (α) sharing every
        factorization and cache."""
        scale = strata(spec)[0].young / self.ground_young
        if scale == 1.0:
            return self
        view = copy.copy(self)
        view.ground = ScaledBody(self.ground, scale)
        return view

    def _finish(self, spec: CaseSpec, rows: Rows, loads: StageLoads, stage: Forward, d: np.ndarray, F2: float,
                t0: float, u1: np.ndarray | None = None) -> Solution:
        """The contact stage solved from its forward-solved loads: the contact problem, the
        backward solves, the checks. ``u1`` (free DOFs) is a stage-1 displacement computed
        elsewhere (the yielding ground's), else stage 1 is ``λd K⁻¹ r``."""
        ground, lining = self.ground, self.lining
        iface = self.mesh.interface
        m, g0 = self.m, spec.geometry.gap
        model = spec.interface.model
        sol, t = self.contact_tractions(spec, d, F2)
        t_solve = time.perf_counter()
        Wt = self.w * t
        if u1 is not None:
            u_g = ground.backward(stage.ground, rows, Wt)
        elif stage.release is not None and stage.deconfinement > 0.0:
            # the contact stage and stage 1 (λd r alone) in one backward sweep over the factor
            u = ground.backward(np.column_stack([stage.ground, stage.release]), rows,
                                np.column_stack([Wt, np.zeros_like(Wt)]))
            u_g, u1 = u[:, 0], stage.deconfinement * u[:, 1]
        else:
            u_g = ground.backward(stage.ground, rows, Wt)
            u1 = np.zeros_like(u_g)
        u_l = lining.backward(stage.lining, rows, Wt) + self._rigid_motion(sol.a)
        J = ground.B @ u_g + lining.B @ u_l
        lam = t[:m]
        shear = np.zeros(m)
        shear[self.tangential] = t[self.tangential_rows]
        jt = np.zeros(m)
        jt[self.tangential] = J[self.tangential_rows]
        u_lining = lining.body.expand(u_l)
        # scales of the contact stage (the increment contact acts on)
        u_ref = max(float(np.max(np.abs(u_g))), float(np.max(np.abs(u_l))), g0, 1e-300)
        F_vertical = F2 if self.joint_rows is None else float(self.vertical @ loads.lining)
        p_ref = max(float(np.max(np.abs(t))), pressure_scale(F_vertical, iface.normal[1], iface.weight))
        closed = (g0 - J[:m] <= CONTACT_GAP_TOL * u_ref) | (model == "bonded")
        slipping = closed & (np.abs(jt) > CONTACT_GAP_TOL * u_ref)
        residuals = [(fb.stiffness() @ u + fb.B.T @ Wt - f, np.abs(f) + np.abs(fb.B.T @ Wt))
                     for fb, u, f in ((ground, u_g, loads.ground), (lining, u_l, loads.lining))]
        if self.joint_rows is None:
            balance = F2 + float(np.sum(self.r * Wt))
            balance_scale = abs(F2) + float(np.sum(np.abs(self.r * Wt)))
        else:  # every segment's modes: the worst relative to its own scale
            wrench = F2 + self.G.T @ Wt
            balance = float(np.max(np.abs(wrench) / np.maximum(np.abs(F2) + np.abs(self.G).T @ np.abs(Wt), 1e-300)))
            balance_scale = 1.0
        kkt = kkt_residual(K_u_minus_f=residuals, balance=balance, balance_scale=balance_scale, lam=lam, normal_jump=J[:m], g0=g0,
                           p_ref=p_ref, u_ref=u_ref, model=model, shear=shear, tangential_jump=jt,
                           mu=spec.interface.friction)
        joint_state = None
        if self.joint_rows is not None:
            jr, nj = self.joint_rows, self.joint_rows.size
            tj, Jj = t[m:m + nj], J[m:m + nj]
            kkt = max(kkt, joints.joint_kkt(jr, tj, Jj, spec.lining.joints, p_ref=p_ref, u_ref=u_ref))
            joint_state = joints.joint_results(
                self.mesh, jr, tj, Jj, u_lining, r_mid=self.r_mid,
                height=spec.lining.joints.contact_height or spec.geometry.thickness, gap_tol=CONTACT_GAP_TOL * u_ref)
        a = float(sol.a) if np.ndim(sol.a) == 0 else np.asarray(sol.a, float)
        return Solution(spec=spec, u_ground=ground.body.expand(u_g + u1), u_stage1=ground.body.expand(u1),
                        u_lining=u_lining, lam=lam, shear=shear, normal_jump=J[:m], tangential_jump=jt,
                        in_contact=closed, slipping=slipping, a=a, bolt=sol.bolt, trials=sol.trials,
                        iterations=int(sol.iterations), admissible=bool(sol.admissible), F2=F_vertical,
                        kkt_residual=kkt,
                        timings={"contact": t_solve - t0, "recovery": time.perf_counter() - t_solve},
                        joints=joint_state, **self._water_state(spec, F_vertical))

    def _water_state(self, spec: CaseSpec, F2: float) -> dict:
        """The lining's weight and water uplift (N/m), the ground's pore pressure after stage 2
        at its nodes, the water pressure on the extrados and the inflow (:class:`Solution`)."""
        w = spec.water
        y = self.mesh.ground.p[1]
        out = {"lining_weight": -F2, "water_uplift": 0.0, "pore": water.hydrostatic(y, w.table, w.unit_weight),
               "water_pressure": np.zeros(self.m), "water_inflow": 0.0}
        if w.table is not None and w.lining == "watertight":
            weight = -spec.lining.density * spec.loads.gravity * float(
                self.vertical @ self.lining.body.restrict(self._lining_shape()))
            out.update(lining_weight=weight, water_uplift=F2 + weight,
                       water_pressure=water.hydrostatic(self.mesh.lining.p[1, self.mesh.interface.lining_node],
                                                        w.table, w.unit_weight))
        elif w.table is not None:
            seep = self.seepage(spec)
            out["pore"], out["water_inflow"] = seep.pore, seep.inflow
        return out

    def _contact_stage(self, spec: CaseSpec, rows: Rows | None = None):
        """Loads, both bodies' loads of the contact stage solved forward (:class:`Forward`),
        ``d = B K⁺ f`` at the rows the factorization serves and the lining's vertical load F2.

        Both stages release parts of one excavation load r: stage 1 ``λd r`` on the ground
        alone, the contact stage ``(1 - λd) r``; one forward solve of r serves both.
        """
        rows = rows or rows_of_model(spec.interface.model)
        loads = self.stage_loads(spec)
        ground, lining = self.ground, self.lining
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
        return loads, stage, d, self.mode_loads(loads.lining)

    def _dual(self, d: np.ndarray, F2: float, g0: float) -> DualProblem:
        m, iface = self.m, self.mesh.interface
        return DualProblem(S=self.S_normal, d=d[:m], g0=np.full(m, g0), w=iface.weight.copy(),
                           nu2=iface.normal[1].copy(), F2=F2)

    def dual_problem(self, spec: CaseSpec) -> DualProblem:
        """The frictionless contact stage of ``spec`` in interface form (:class:`DualProblem`; a
        monolithic lining's: a segmental one's is :mod:`solver.floating`'s)."""
        if self.joint_rows is not None:
            raise ValueError("dual_problem: a segmental lining's contact problem has the joints' rows and every "
                             "segment's modes (solver.floating.FloatingProblem), not the one-mode dual")
        model = self.for_case(spec)
        d, F2 = model._contact_stage(spec, "normal")[2:]
        return model._dual(d, F2, spec.geometry.gap)

    def _tie(self, d: np.ndarray, F2: float) -> tuple[np.ndarray, float]:
        """Bonded interface: J = 0 at every row and the lining balance; no bolt needed."""
        w, r, S = self.w, self.r, self.S
        R = r.size
        A = np.zeros((R + 1, R + 1))
        A[:R, :R] = (w[:, None] * S) * w[None, :]
        A[:R, R] = A[R, :R] = w * r
        rhs = np.r_[w * d, -F2]
        x = la.solve(A, rhs, assume_a="sym")
        if not np.all(np.isfinite(x)):
            raise SolverError("the bonded interface system is singular")
        return x[:R], float(x[R])



_SHARED: "OrderedDict[str, TunnelModel]" = OrderedDict()
_SHARED_LOCK = threading.Lock()
#: Models a process keeps for reuse (a worker running a sweep over one geometry needs one);
#: ``TUNNEL_CONTACT_SHARED_MODELS=0`` turns reuse off (every case built from nothing).
SHARED_MODELS = int(os.environ.get("TUNNEL_CONTACT_SHARED_MODELS", "2"))


def shared_model(spec: CaseSpec) -> TunnelModel:
    """The process's :class:`TunnelModel` for ``spec``'s :func:`model_key`, built on first use.

    Cases of a sweep that share geometry, mesh, boundaries and materials (loads, K0,
    deconfinement, interface, solver and design varying) then pay mesh, assembly and
    factorization once per worker process. Least recently used models are dropped
    beyond :data:`SHARED_MODELS`. Solving on a shared model gives the same result as on
    a fresh one: what a model builds on first use (unit load vectors, the factorization and
    flexibility an interface model needs, stress bases) depends on the model alone.
    """
    if SHARED_MODELS <= 0:
        return TunnelModel(spec)
    key = model_key(spec)
    with _SHARED_LOCK:
        if key in _SHARED:
            _SHARED.move_to_end(key)
            return _SHARED[key]
        model = TunnelModel(spec)
        _SHARED[key] = model
        while len(_SHARED) > SHARED_MODELS:
            _SHARED.popitem(last=False)
        return model
