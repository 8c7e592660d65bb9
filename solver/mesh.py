"""Meshing of a case with gmsh's Python API (no files).

Both bodies live in one gmsh model. The lining is a structured (transfinite) half
annulus with ``lining_layers`` element layers and alternating diagonals, so every
interface node has a radial line of lining nodes below it (the sections where the
lining forces are evaluated). The ground is unstructured, graded by a distance
threshold field from ``interface_size`` at the tunnel to ``far_size``. With
``gap == 0`` the interface is one shared curve; with ``gap > 0`` it is two arcs
(radius b and b + g0) with the same number of uniformly spaced nodes, so the
nodes match at equal theta. Interface nodes are duplicated: each body gets its
own copy.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .sizing import interface_segments, lining_layers, size_field_distances
from .spec import CaseSpec

# gmsh keeps global state: one meshing at a time per process.
_GMSH_LOCK = threading.Lock()


@dataclass(frozen=True)
class BodyMesh:
    """Nodes ``p`` (2, N) in m and triangles ``t`` (3, E), 0-based, counter-clockwise."""

    p: np.ndarray
    t: np.ndarray


@dataclass(frozen=True)
class Interface:
    """Interface Γ, ordered crown (theta = 0) to invert (theta = 180).

    Attributes
    ----------
    theta : (m,) deg, at the tunnel axis, 0 at the crown.
    ground_node, lining_node : (m,) node indices into the ground / lining mesh.
    normal : (2, m) unit outward normal of the ground (points to the tunnel axis).
    weight : (m,) m, trapezoid weights of the paper's quadrature I.
    """

    theta: np.ndarray
    ground_node: np.ndarray
    lining_node: np.ndarray
    normal: np.ndarray
    weight: np.ndarray

    @property
    def size(self) -> int:
        return self.theta.size


@dataclass(frozen=True)
class TunnelMesh:
    ground: BodyMesh
    lining: BodyMesh
    interface: Interface
    center: tuple[float, float]
    layers: int


def build_mesh(spec: CaseSpec) -> TunnelMesh:
    """Mesh both bodies of ``spec`` and pair the interface nodes."""
    import gmsh

    with _GMSH_LOCK:
        gmsh.initialize(interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("General.Verbosity", 0)
            gmsh.model.add("tunnel")
            ground_surf, lining_surfs, hole_arcs, outer_arcs = _geometry(spec)
            gmsh.model.mesh.generate(2)
            ground = _body_mesh([ground_surf])
            lining = _body_mesh(lining_surfs)
            ground_ring = _arc_nodes(hole_arcs, ground)
            lining_ring = _arc_nodes(outer_arcs, lining)
        finally:
            gmsh.finalize()
    center = (0.0, -spec.geometry.depth)
    return TunnelMesh(ground.mesh, lining.mesh,
                      _interface(ground.mesh, lining.mesh, ground_ring, lining_ring, center),
                      center, lining_layers(spec))


def _geometry(spec: CaseSpec):
    import gmsh

    g, m = spec.geometry, spec.mesh
    geo = gmsh.model.geo
    a, b, rh, d = g.inner_radius, g.outer_radius, g.hole_radius, g.depth
    n_arc = interface_segments(spec) + 1
    n_rad = lining_layers(spec) + 1

    c = geo.addPoint(0, -d, 0)

    def ring(r):
        return geo.addPoint(0, -d + r, 0), geo.addPoint(r, -d, 0), geo.addPoint(0, -d - r, 0)

    def arcs(pts):
        return geo.addCircleArc(pts[0], c, pts[1]), geo.addCircleArc(pts[1], c, pts[2])

    inner_pts, outer_pts = ring(a), ring(b)
    inner, outer = arcs(inner_pts), arcs(outer_pts)
    if g.gap > 0:
        hole_pts = ring(rh)
        hole = arcs(hole_pts)
    else:
        hole_pts, hole = outer_pts, outer
    radial = [geo.addLine(inner_pts[k], outer_pts[k]) for k in range(3)]

    lining_surfs = []
    for q in range(2):
        loop = geo.addCurveLoop([outer[q], -radial[q + 1], -inner[q], radial[q]])
        lining_surfs.append(geo.addPlaneSurface([loop]))

    p_tl, p_tr = geo.addPoint(0, 0, 0), geo.addPoint(g.width, 0, 0)
    p_br, p_bl = geo.addPoint(g.width, -g.height, 0), geo.addPoint(0, -g.height, 0)
    border = [geo.addLine(p_tl, p_tr), geo.addLine(p_tr, p_br), geo.addLine(p_br, p_bl),
              geo.addLine(p_bl, hole_pts[2]), -hole[1], -hole[0], geo.addLine(hole_pts[0], p_tl)]
    ground_surf = geo.addPlaneSurface([geo.addCurveLoop(border)])
    geo.synchronize()

    mesh = gmsh.model.mesh
    for arc in set(inner + outer + hole):
        mesh.setTransfiniteCurve(arc, n_arc)
    for line in radial:
        mesh.setTransfiniteCurve(line, n_rad)
    for s in lining_surfs:
        mesh.setTransfiniteSurface(s, "Alternate")

    d_min, d_max = size_field_distances(spec)
    fields = gmsh.model.mesh.field
    dist = fields.add("Distance")
    fields.setNumbers(dist, "CurvesList", list(hole))
    fields.setNumber(dist, "Sampling", 4 * n_arc)
    thr = fields.add("Threshold")
    fields.setNumber(thr, "InField", dist)
    fields.setNumber(thr, "SizeMin", m.interface_size)
    fields.setNumber(thr, "SizeMax", m.far_size)
    fields.setNumber(thr, "DistMin", d_min)
    fields.setNumber(thr, "DistMax", d_max)
    fields.setAsBackgroundMesh(thr)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    return ground_surf, lining_surfs, hole, outer


class _Body:
    """A body's mesh plus the map from gmsh node tags to its local indices."""

    def __init__(self, mesh: BodyMesh, tag_to_local: dict[int, int]):
        self.mesh = mesh
        self.tag_to_local = tag_to_local


def _body_mesh(surfaces) -> _Body:
    import gmsh

    tris = []
    for s in surfaces:
        types, _, nodes = gmsh.model.mesh.getElements(2, s)
        for etype, conn in zip(types, nodes):
            if etype != 2:
                raise RuntimeError(f"unexpected gmsh element type {etype} (expected 3-node triangles)")
            tris.append(np.asarray(conn, dtype=np.int64).reshape(-1, 3))
    tri_tags = np.concatenate(tris)
    tags = np.unique(tri_tags)
    all_tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = dict(zip(all_tags.tolist(), np.asarray(coords).reshape(-1, 3)[:, :2]))
    p = np.array([xyz[int(k)] for k in tags]).T
    t = np.searchsorted(tags, tri_tags).T
    # counter-clockwise orientation
    e1, e2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    cw = e1[0] * e2[1] - e1[1] * e2[0] < 0
    t[1, cw], t[2, cw] = t[2, cw].copy(), t[1, cw].copy()
    return _Body(BodyMesh(p=p, t=np.ascontiguousarray(t)), {int(k): i for i, k in enumerate(tags)})


def _arc_nodes(arcs, body: _Body) -> np.ndarray:
    import gmsh

    tags = set()
    for arc in arcs:
        node_tags, _, _ = gmsh.model.mesh.getNodes(1, abs(arc), includeBoundary=True)
        tags.update(int(k) for k in node_tags)
    return np.array([body.tag_to_local[k] for k in tags])


def _theta(p: np.ndarray, center) -> np.ndarray:
    """Angle at the tunnel axis in degrees, 0 at the crown, 180 at the invert (x >= 0)."""
    return np.degrees(np.arctan2(p[0] - center[0], p[1] - center[1]))


def _interface(ground: BodyMesh, lining: BodyMesh, g_nodes, l_nodes, center) -> Interface:
    g_nodes = g_nodes[np.argsort(_theta(ground.p[:, g_nodes], center))]
    l_nodes = l_nodes[np.argsort(_theta(lining.p[:, l_nodes], center))]
    if g_nodes.size != l_nodes.size:
        raise RuntimeError(f"interface nodes do not match: {g_nodes.size} ground vs {l_nodes.size} lining")
    pg = ground.p[:, g_nodes]
    theta = _theta(pg, center)
    if np.max(np.abs(theta - _theta(lining.p[:, l_nodes], center))) > 1e-5:
        raise RuntimeError("interface nodes of ground and lining are not at the same angles")
    rel = pg - np.array(center)[:, None]
    normal = -rel / np.linalg.norm(rel, axis=0)
    seg = np.linalg.norm(np.diff(pg, axis=1), axis=0)
    weight = 0.5 * (np.r_[0.0, seg] + np.r_[seg, 0.0])
    theta[0], theta[-1] = 0.0, 180.0
    return Interface(theta=theta, ground_node=g_nodes, lining_node=l_nodes,
                     normal=normal, weight=weight)
