"""What a geometry, its mesh settings and materials fix, built once (:class:`BuiltModel`): the mesh, both
bodies' stiffness and factorizations, the dense interface flexibility and the unit loads a case combines.
Cases with equal :func:`model_key` share one; :class:`solver.model.TunnelModel` adds the staged solve."""
from __future__ import annotations

import copy
import json
import threading
import time
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

from .fe.assembly import (
    Basis,
    assemble_body,
    gradient_operator,
    gravity_load,
    ground_constraints,
    lining_constraints,
    nodal_gradient_operator,
    point_basis,
    vector_basis,
)
from .fe.flexibility import (
    FactoredBody,
    Rows,
    ScaledBody,
    interface_operator,
    interface_rows,
    lining_pin,
    rows_of_model,
)
from .geometry.bodies import TunnelMesh
from .geometry.mesh import build_mesh
from .ground import water
from .ground.loads import load_shapes, moduli
from .ground.strata import strata, table_line
from .limits import CaseCancelled, TimeLimitExceeded
from .lining import joints
from .spec import CaseSpec

__all__ = ["BuiltModel", "model_key"]


def model_key(spec: CaseSpec) -> str:
    """The canonical JSON of what a :class:`TunnelModel` fixes (cases with equal keys share one).

    The ground's Young's moduli (and their gradients) enter relative to the first layer's:
    the ground's stiffness matrix is linear in them, so a case whose ground is the model's
    with every modulus times α solves on the model's factorization with ``K⁺`` divided by α
    (:class:`~solver.fe.flexibility.ScaledBody`)."""
    layers = strata(spec)
    e0 = layers[0].young  # the ground's stiffness enters as ratios to it: a model serves every scale
    shared = {
        "geometry": spec.geometry.model_dump(mode="json"),
        "mesh": spec.mesh.model_dump(mode="json"),
        "boundaries": spec.boundaries.model_dump(mode="json"),
        "strata": [[s.top, s.bottom, s.young / e0, s.poisson, s.young_gradient / e0] for s in layers],
        "lining": {"young": spec.lining.young, "poisson": spec.lining.poisson},
    }
    table = table_line(spec)
    if table is not None:  # a drained case's table is a line of the mesh
        shared["table_line"] = table
    j = spec.lining.joints
    if j.count:  # the joints cut the mesh; their shear law is the contact problem's
        shared["joints"] = [j.count, j.offset, j.contact_height]
    return json.dumps(shared, sort_keys=True, separators=(",", ":"))


#: What a built model keeps of the solves it made, per kind (:class:`Kept`, the most recent):
#: full releases of the unsupported ground (a curve and a radius each: :mod:`solver.stages.face`) and
#: stage-1 states of yielding ground (their points' histories: 5.3 MB each at the default mesh,
#: :mod:`solver.stages.plastic`) and the solutions of cases (1.2 MB: :func:`solver.model.mechanics_key`).
KEPT = {"release": 16, "stage one": 2, "bound": 2, "solution": 4}


_MISSING = object()


class Kept:
    """What a built model keeps of the solves it made, per kind (:data:`KEPT`), the most recent."""

    def __init__(self):
        self._kinds: "dict[str, OrderedDict[str, object]]" = {kind: OrderedDict() for kind in KEPT}
        self._lock = threading.Lock()

    def get(self, kind: str, key: str, compute, failures: tuple = ()):
        """``compute()`` for ``key`` (the physics it depends on beyond the model), computed once and kept
        (the last ``KEPT[kind]``): a sweep over what that solve does not depend on (the face distance for a
        full release, the design for a case's mechanics, the lining's weight for yielding ground's stage 1)
        makes it once. A failure of one of the ``failures`` types is kept too and raised again (a copy,
        with its message); a time limit or a cancellation never is (the clock's or the user's, not the
        solve's: another try may finish)."""
        kept = self._kinds[kind]
        with self._lock:
            found = kept.get(key, _MISSING)
            if found is not _MISSING:
                kept.move_to_end(key)
        if found is _MISSING:
            try:
                found = compute()
            except (TimeLimitExceeded, CaseCancelled):
                raise
            except failures as err:
                found = err
            with self._lock:
                kept[key] = found
                while len(kept) > KEPT[kind]:
                    kept.popitem(last=False)
        if isinstance(found, BaseException):
            again = type(found)(str(found))
            again.__dict__.update(found.__dict__)  # what it carries (a collapse's peak, where it failed)
            raise again
        return found

    def values(self, kind: str) -> list:
        with self._lock:
            return list(self._kinds[kind].values())

    def forget(self, kind: str = "solution") -> None:
        """Drop what is kept of one kind: a benchmark timing the same case twice solves it twice."""
        with self._lock:
            self._kinds[kind].clear()


class BuiltModel:
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
        self.width, self.height, self.side = g.width, g.height, spec.boundaries.side
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
        self.factorize(rows_of_model(spec.interface.model))
        self._units: dict[str, np.ndarray] = {}
        self._built: dict = {}
        #: what the model keeps of the solves it made (shared with its scaled views)
        self.kept = Kept()
        self._seepage: "OrderedDict[tuple, water.SeepageModel]" = OrderedDict()
        self._lock = threading.Lock()

    @property
    def m(self) -> int:
        return self.mesh.interface.size

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
        modes are pinned for ``K⁺`` and solved for (:mod:`solver.contact.floating`)."""
        iface, m, g = self.mesh.interface, self.m, spec.geometry
        stations, corners = self._joint_corners()
        other = iface.lining_node.copy()
        other[stations] = corners
        # each corner takes its own edge's Simpson share of the station's weight (L/6 of each edge;
        # an edge's middle node weighs 2L/3)
        before, after = iface.weight[stations - 1], iface.weight[stations + 1]
        share = np.ones(m)
        share[stations] = before / (before + after)
        Bl_other = interface_operator(lining, other[nodes], directions, -1.0)
        Bl = sp.diags(share[nodes]) @ Bl + sp.diags(1.0 - share[nodes]) @ Bl_other
        height = spec.lining.joints.contact_height or g.thickness
        rows = joints.joint_rows(lining, self.mesh.joints, height=height, shear=True)
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

    def rigid_motion(self, a) -> np.ndarray:
        """The lining's rigid motion of amplitude(s) ``a`` on its free DOFs."""
        return a * self.rigid if self.rigid.ndim == 1 else self.rigid @ a

    def mode_loads(self, f_lining: np.ndarray):
        """The lining's loads on its rigid modes: F2 (N/m, float) or a segmental lining's (k,)."""
        F = f_lining @ self.rigid
        return float(F) if np.ndim(F) == 0 else F

    def drop_factorizations(self) -> None:
        """Forget both bodies' factorizations and the flexibilities computed with them:
        their memory is freed and they are rebuilt, and timed, on next use
        (``python -m bench.solver`` times them repeatedly this way)."""
        for fb in (self.ground, self.lining):
            fb.drop()
        self._S.clear()
        self.timings["factorization"] = 0.0
        self.timings.pop("flexibility", None)

    def built(self, key: tuple, build):
        """``build()`` once for this model under ``key``: what its cases share beyond the factorizations
        (point bases, gradient operators, the results' samplers)."""
        if key not in self._built:
            self._built[key] = build()
        return self._built[key]

    def point_basis(self, body: str) -> "Basis":
        """``'ground'`` or ``'lining'`` basis at the sub-triangle centroids (built on first use)."""
        return self.built(("point basis", body), lambda: point_basis(getattr(self, body).body))

    def point_gradient(self, body: str):
        """``'ground'`` or ``'lining'``: the gradient at the sub-triangle centroids on the full DOF vector
        (:func:`~solver.fe.assembly.nodal_gradient_operator`: every case's stored stresses; built once)."""
        return self.built(("nodal gradient", body), lambda: nodal_gradient_operator(self.point_basis(body)))

    def gradient_operator(self, where: str):
        """The ground's displacement gradient, as an operator on its unknowns, at its quadrature
        points (``'gauss'``) or at the sub-triangle centroids (``'points'``); built on first use."""
        body = self.ground.body
        return self.built(("gradient", where), lambda: gradient_operator(
            body, body.basis if where == "gauss" else self.point_basis("ground")))

    def factorize(self, rows: Rows) -> None:
        """Both bodies' factorizations serving ``rows`` (built once; timed)."""
        t0 = time.perf_counter()
        self.ground.factor(rows)
        self.lining.factor(rows)
        self.timings["factorization"] += time.perf_counter() - t0

    def flexibility(self, rows: Rows) -> np.ndarray:
        """``S_ground / α + S_lining`` (each body's flexibility computed once per model)."""
        if rows not in self._S:
            self.factorize(rows)
            t0 = time.perf_counter()
            self._S[rows] = (self.ground.base.flexibility(rows), self.lining.flexibility(rows))  # each symmetric
            self.timings["flexibility"] = self.timings.get("flexibility", 0.0) + time.perf_counter() - t0
        ground, lining = self._S[rows]
        return ground / self.ground.scale + lining

    @property
    def S(self) -> np.ndarray:
        """(R, R) interface flexibility of the normal and tangential rows (built on first use)."""
        return self.flexibility("all")

    @property
    def S_normal(self) -> np.ndarray:
        """(m, m) normal block of the flexibility: all that frictionless contact needs (built
        on first use from its own factorization, so a result never depends on what the model
        solved before)."""
        return self.flexibility("normal")

    def accepts(self, spec: CaseSpec) -> bool:
        return model_key(spec) == self.key

    def for_case(self, spec: CaseSpec) -> "BuiltModel":
        """This model as ``spec``'s: itself, or, when the case's ground is this model's with
        every modulus times α, a view whose ground is :class:`ScaledBody` (α) sharing every
        factorization and cache."""
        scale = strata(spec)[0].young / self.ground_young
        if scale == 1.0:
            return self
        view = copy.copy(self)
        view.ground = ScaledBody(self.ground, scale)
        return view

    def _unit(self, name: str, compute) -> np.ndarray:
        """A unit load vector of this model, assembled on first use."""
        if name not in self._units:
            self._units[name] = compute()
        return self._units[name]

    def shapes(self, method: str) -> np.ndarray:
        """(N, 4 L) full-DOF ground load per :data:`~solver.ground.loads.LOAD_TERMS` term of each
        layer, assembled once per model (:func:`solver.ground.loads.load_shapes`): the applied loads
        (``method = "wished-in-place"``) or the excavation load ``f_ext - ∫Bᵀσ0``
        (``"deconfinement"``). Every ground load of a case is ``shapes @ load_coefficients(case)``:
        a sweep over loads, densities and K0 assembles nothing."""
        return self._unit(f"shapes_{method}", lambda: load_shapes(
            self.ground.body.basis, self.band, self.layers, width=self.width, height=self.height,
            side=self.side, method=method))

    def lining_shape(self) -> np.ndarray:
        """Full-DOF load of the lining's own weight per unit ρg (assembled once)."""
        return self._unit("lining_gravity", lambda: gravity_load(self.lining.body.basis, 1.0, 1.0))

    def seepage_model(self, table: float, permeability: np.ndarray) -> water.SeepageModel:
        """The head problem of a drained case with the water ``table`` (m below the surface) and
        each layer's ``permeability`` (m/s), its factorization kept per table depth and
        permeabilities (the two most recent)."""
        k = np.asarray(permeability, dtype=float)
        key = (table, tuple(k))
        with self._lock:
            if key not in self._seepage:
                self._seepage[key] = water.SeepageModel(self.mesh.ground, self.mesh.interface.ground_node,
                                                        k[self.band], table, self.width, self.height)
                while len(self._seepage) > 2:
                    self._seepage.popitem(last=False)
            return self._seepage[key]
