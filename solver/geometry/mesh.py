"""Meshing of a case with gmsh's Python API (no files): quadratic (P2) triangles.

Both bodies live in one gmsh model, meshed with 3-node triangles; each edge gets its
quadratic node here (:func:`_body_mesh`), on the circle for the edges on the circular
arcs (isoparametric 6-node triangles, curved interface). The lining is a structured (transfinite) half
annulus with ``lining_layers`` element layers and alternating diagonals (a segmental lining's
graded towards its joints, through the thickness and along the ring:
:mod:`solver.geometry.joints`), so every
interface node has a radial line of lining nodes below it (the sections where the
lining forces are evaluated). The ground is unstructured, graded by a distance
threshold field from ``interface_size`` at the tunnel to ``far_size``. With
``gap == 0`` the interface is one shared curve; with ``gap > 0`` it is two arcs
(radius b and b + g0) with the same number of uniformly spaced nodes, so the
nodes match at equal theta. Interface nodes are duplicated: each body gets its
own copy.

Node numbering of a body follows scikit-fem's P2 DOF order (vertices first, then one
node per edge in the order of ``MeshTri2``'s facets), so node ``j`` of a body is
scalar DOF ``j`` of its P2 basis.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .sizing import (
    ground_size_field,
    check_mesh_size,
    interface_segments,
)
from ..spec import CaseSpec
from ..ground.strata import band_layers, mesh_lines
from .bands import circle_hole_depths, ground_bands
from .bodies import BodyMesh, Interface, TunnelMesh
from .joints import (
    circle_cuts,
    cut_along,
    graded_zones,
    hoop_divisions,
    joint_angles,
    joint_faces,
    joint_layers,
    line_angles,
    polar_angle as _theta,
    radial_pieces,
    transfinite,
)
from .profile_mesh import curve_placer, profile_cuts, profile_geometry, profile_interface

# gmsh keeps global state: one meshing at a time per process.
_GMSH_LOCK = threading.Lock()


def build_mesh(spec: CaseSpec) -> TunnelMesh:
    """Mesh both bodies of ``spec`` and pair the interface nodes."""
    import gmsh

    with _GMSH_LOCK:
        gmsh.initialize(interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("General.Verbosity", 0)
            gmsh.model.add("tunnel")
            g = spec.geometry
            shaped = not g.circle  # a section of arcs or an ellipse (SPEC §9.4): :mod:`.profile_mesh`
            ground_surfs, lining_surfs, hole_arcs, outer_arcs, inner_arcs = (profile_geometry if shaped
                                                                              else _geometry)(spec)
            gmsh.model.mesh.generate(2)
            center = (0.0, -g.depth)
            on = [curve_placer(g.profile(o), center) for o in (g.thickness + g.gap, g.thickness, 0.0)] if shaped \
                else [None] * 3
            model_nodes = _model_nodes()
            ground, (ground_ring,), band = _body_mesh(ground_surfs, [hole_arcs], center, model_nodes, onto=on[:1])
            cut = (profile_cuts if shaped else circle_cuts)(spec, center)
            inside = [a for a, n in zip(cut.cuts, cut.normal) if 0.0 < n < 180.0]
            lining, (lining_ring, _), _ = _body_mesh(lining_surfs, [outer_arcs, inner_arcs], center, model_nodes,
                                                     cuts=inside, angle_of=cut.angle_of, onto=on[1:])
        finally:
            gmsh.finalize()
    check_mesh_size(ground.t.shape[1] + lining.t.shape[1])
    joints = joint_faces(lining, cut, center) if spec.lining.joints.count else None
    band = band_layers(spec)[band]  # a band between a table line and a layer line is in that layer
    iface = (Interface(**profile_interface(ground, lining, ground_ring, lining_ring, center,
                                           g.profile(g.thickness + g.gap)))
             if shaped else _interface(ground, lining, ground_ring, lining_ring, center))
    return TunnelMesh(ground, lining, iface, center, joint_layers(spec), band, joints,
                      g.profile() if shaped else None)


def sector_angles(spec: CaseSpec) -> list[float]:
    """Angles (deg from the crown) where the lining is cut into structured sectors: crown,
    springline, invert, where a mesh line of the ground meets the excavation boundary (the
    interface nodes of ground and lining then meet there too), at the joints of a segmental
    lining and where the hoop grading towards each joint ends (:func:`graded_zones`)."""
    return sorted({0.0, 90.0, 180.0, *joint_angles(spec), *line_angles(spec), *(z.end for z in graded_zones(spec))})


def _geometry(spec: CaseSpec):
    import gmsh

    g = spec.geometry
    geo = gmsh.model.geo
    angles = sector_angles(spec)
    per_quarter = interface_segments(spec)
    c = geo.addPoint(0, -g.depth, 0)
    lining = _lining(geo, spec, c, angles)
    hole_pts, hole = lining.hole_pts, lining.hole
    p_tl, p_tr = geo.addPoint(0, 0, 0), geo.addPoint(g.width, 0, 0)
    p_br, p_bl = geo.addPoint(g.width, -g.height, 0), geo.addPoint(0, -g.height, 0)
    lines = mesh_lines(spec)
    if not lines:
        border = [geo.addLine(p_tl, p_tr), geo.addLine(p_tr, p_br), geo.addLine(p_br, p_bl),
                  geo.addLine(p_bl, hole_pts[-1]), *(-arc for arc in reversed(hole)),
                  geo.addLine(hole_pts[0], p_tl)]
        ground_surfs = [geo.addPlaneSurface([geo.addCurveLoop(border)])]
    else:
        ground_surfs = ground_bands(geo, g, lines, circle_hole_depths(g, angles), hole_pts, hole,
                                    (p_tl, p_tr, p_br, p_bl))
    geo.synchronize()

    mesh = gmsh.model.mesh
    for group in (*lining.rings, *([hole] if g.gap > 0 else [])):
        for arc, (n, growth) in zip(group, lining.divisions):
            transfinite(arc, n, growth)
    for lines_k, (n, growth) in zip(lining.radial, lining.pieces):
        for line in lines_k:
            transfinite(line, n, growth)
    for s in lining.surfaces:
        mesh.setTransfiniteSurface(s, "Alternate")

    ground_size_field(spec, hole, sampling=4 * (per_quarter + 1))
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    return ground_surfs, lining.surfaces, hole, lining.rings[-1], lining.rings[0]


@dataclass(frozen=True)
class _LiningGeometry:
    """The lining's gmsh entities: arcs of each ring (intrados first, extrados last), the
    excavation's points and arcs, radial lines per piece of the thickness, the structured
    surfaces, the hoop ``divisions`` of the sectors and the radial ``pieces``' (elements, growth)."""

    rings: list
    hole_pts: tuple
    hole: tuple
    radial: list
    surfaces: list
    divisions: list
    pieces: list


def _lining(geo, spec: CaseSpec, c: int, angles: list[float]) -> _LiningGeometry:
    """The structured lining: a quadrilateral per sector (between consecutive ``angles``) and piece
    of its thickness (:func:`~solver.geometry.joints.radial_pieces`), and the excavation's arcs."""
    g, d = spec.geometry, spec.geometry.depth
    pieces = radial_pieces(spec)

    def ring(r):
        return tuple(geo.addPoint(r * np.sin(np.radians(t)), -d + r * np.cos(np.radians(t)), 0)
                     if t not in (0.0, 90.0, 180.0) else
                     geo.addPoint({0.0: 0, 90.0: r, 180.0: 0}[t], {0.0: -d + r, 90.0: -d, 180.0: -d - r}[t], 0)
                     for t in angles)

    def arcs(pts):
        return tuple(geo.addCircleArc(p, c, q) for p, q in zip(pts[:-1], pts[1:]))

    points = [ring(r) for r in [p.inner for p in pieces] + [g.outer_radius]]
    rings = [arcs(pts) for pts in points]
    if g.gap > 0:
        hole_pts = ring(g.hole_radius)
        hole = arcs(hole_pts)
    else:
        hole_pts, hole = points[-1], rings[-1]
    radial = [[geo.addLine(points[i][k], points[i + 1][k]) for k in range(len(angles))] for i in range(len(pieces))]
    surfaces = [geo.addPlaneSurface([geo.addCurveLoop([rings[i + 1][q], -radial[i][q + 1], -rings[i][q],
                                                        radial[i][q]])])
                for q in range(len(angles) - 1) for i in range(len(pieces))]
    return _LiningGeometry(rings=rings, hole_pts=hole_pts, hole=hole, radial=radial, surfaces=surfaces,
                           divisions=hoop_divisions(spec, angles),
                           pieces=[(p.elements, p.growth) for p in pieces])


def _model_nodes() -> tuple[np.ndarray, np.ndarray]:
    """Every node of the gmsh model: its tags sorted, and their (x, y) coordinates (N, 2)."""
    import gmsh

    all_tags, coords, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(all_tags)
    return all_tags[order], np.asarray(coords).reshape(-1, 3)[order, :2]


def _body_mesh(surfaces, arcs: list, center, model_nodes: tuple[np.ndarray, np.ndarray],
               cuts: list[float] = (), angle_of=None, onto: list | None = None) -> tuple[BodyMesh, list[np.ndarray], np.ndarray]:
    """A body's P2 mesh from gmsh's linear triangles on ``surfaces``, the nodes on each
    group of circle ``arcs`` (vertices and edge nodes) and the index into ``surfaces`` of each
    triangle; ``model_nodes``: :func:`_model_nodes`.

    The edge nodes are made here rather than by gmsh's ``setOrder(2)`` (0.47 of 1.65 s of
    gmsh's time at 152k DOF): the midpoint of each straight edge, and on the circle arcs the
    point of the arc halfway between the edge's vertices (the chord's midpoint pushed out
    radially from the tunnel axis), which is where ``setOrder`` puts it.

    ``cuts`` (deg): lines where ``angle_of`` (points → deg) takes these values, along which the
    body is cut (a segmental lining's joints): the triangles on the invert side of each get their
    own copies of the vertices on it (:func:`~solver.geometry.joints.cut_along`), so the edges on
    it, and their edge nodes, are made twice.

    ``onto``: per group of curves, None (a circle about ``center``) or a function of the edge's
    vertices giving its node on the true curve (a section's profile: :func:`.profile_mesh.curve_placer`).
    """
    import gmsh
    from skfem import MeshTri1

    tris, owner = [], []
    for k, s in enumerate(surfaces):
        types, _, nodes = gmsh.model.mesh.getElements(2, s)
        for etype, conn in zip(types, nodes):
            if etype != 2:
                raise RuntimeError(f"unexpected gmsh element type {etype} (expected 3-node triangles)")
            tris.append(np.asarray(conn, dtype=np.int64).reshape(-1, 3))
            owner.append(np.full(tris[-1].shape[0], k, np.int64))
    tri_tags = np.concatenate(tris)
    tags = np.unique(tri_tags)
    all_tags, xy = model_nodes
    p = np.ascontiguousarray(xy[np.searchsorted(all_tags, tags)].T)
    t = np.ascontiguousarray(np.searchsorted(tags, tri_tags).T)  # (3, E), vertices numbered in tag order
    e1, e2 = p[:, t[1]] - p[:, t[0]], p[:, t[2]] - p[:, t[0]]
    cw = e1[0] * e2[1] - e1[1] * e2[0] < 0
    t[1, cw], t[2, cw] = t[2, cw].copy(), t[1, cw].copy()  # counter-clockwise
    n_tagged = p.shape[1]
    p, t, origin = cut_along(p, t, cuts, angle_of)
    # scikit-fem's P2 DOF order: vertices, then one node per facet in MeshTri2's facet order
    # (MeshTri2 keeps t as given, hence sort_t=False)
    facets = MeshTri1(p, t, sort_t=False, validate=False)
    f = facets.facets
    edge = 0.5 * (p[:, f[0]] + p[:, f[1]])
    nv = p.shape[1]
    c = np.asarray(center, dtype=float)[:, None]
    rings = []
    boundary = facets.boundary_facets()
    for k, group in enumerate(arcs):
        on_arc = np.zeros(nv, bool)
        on_arc[_arc_vertices(group, tags)] = True
        on_arc[n_tagged:] = on_arc[origin]  # a cut's copies of the arc's vertices are on it too
        arc_facets = boundary[on_arc[f[0, boundary]] & on_arc[f[1, boundary]]]
        if onto is not None and onto[k] is not None:
            edge[:, arc_facets] = onto[k](p[:, f[0, arc_facets]], p[:, f[1, arc_facets]])
        else:
            radius = np.mean(np.hypot(*(p[:, on_arc] - c)))
            rel = edge[:, arc_facets] - c
            edge[:, arc_facets] = c + radius * rel / np.hypot(*rel)
        # one node per station: a cut's copy of a vertex is left out (the original stands for both)
        rings.append(np.r_[np.flatnonzero(on_arc[:n_tagged]), nv + arc_facets])
    mesh = BodyMesh(p=np.ascontiguousarray(np.hstack([p, edge])),
                    t=np.ascontiguousarray(np.vstack([t, nv + facets.t2f])))
    return mesh, rings, np.concatenate(owner)


def _arc_vertices(arcs, tags: np.ndarray) -> np.ndarray:
    """Vertex indices (into the sorted ``tags`` of a body) of the nodes on gmsh ``arcs``."""
    import gmsh

    on = [gmsh.model.mesh.getNodes(1, abs(arc), includeBoundary=True)[0] for arc in arcs]
    arc_tags = np.unique(np.concatenate(on).astype(np.int64))
    at = np.searchsorted(tags, arc_tags)
    if np.any(at >= tags.size) or not np.array_equal(tags[np.minimum(at, tags.size - 1)], arc_tags):
        raise RuntimeError("an arc node is not a vertex of the body's triangles")
    return at


def _interface(ground: BodyMesh, lining: BodyMesh, g_nodes, l_nodes, center) -> Interface:
    g_nodes = g_nodes[np.argsort(_theta(ground.p[:, g_nodes], center))]
    l_nodes = l_nodes[np.argsort(_theta(lining.p[:, l_nodes], center))]
    if g_nodes.size != l_nodes.size or g_nodes.size % 2 == 0:
        raise RuntimeError(f"interface nodes do not match: {g_nodes.size} ground vs {l_nodes.size} lining")
    pg = ground.p[:, g_nodes]
    theta = _theta(pg, center)
    if np.max(np.abs(theta - _theta(lining.p[:, l_nodes], center))) > 1e-5:
        raise RuntimeError("interface nodes of ground and lining are not at the same angles")
    vertex = np.arange(g_nodes.size) % 2 == 0
    if not np.all(g_nodes[vertex] < ground.n_vertices) or np.any(g_nodes[~vertex] < ground.n_vertices):
        raise RuntimeError("interface nodes do not alternate vertex / edge node")
    rel = pg - np.array(center)[:, None]
    normal = -rel / np.linalg.norm(rel, axis=0)
    theta[0], theta[-1] = 0.0, 180.0
    # Simpson's rule per quadratic edge, on the arc length of the edge
    radius = np.linalg.norm(rel, axis=0).mean()
    length = radius * np.radians(np.diff(theta[vertex]))
    weight = np.zeros(theta.size)
    weight[0:-1:2] += length / 6.0
    weight[2::2] += length / 6.0
    weight[1::2] += 2.0 * length / 3.0
    return Interface(theta=theta, ground_node=g_nodes, lining_node=l_nodes,
                     normal=normal, weight=weight, vertex=vertex)
