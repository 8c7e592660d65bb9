"""The gmsh model of a section that is not a circle (SPEC §9.4), for :mod:`.mesh`.

The intrados, the extrados (its normal offset by the thickness) and the excavation (by the
thickness and the clearance) are each a polyline through points of the true curve
(:class:`~solver.geometry.section.Profile`) at the same turning angles φ, so the lining's
structured sectors have their lines of nodes on the normals of the mid-surface: the cuts the
section forces are taken on (:mod:`solver.lining.forces`). The P2 edge nodes of the curved edges
are put on the true curve, at the mean turning angle of their vertices (:func:`curve_placer`).
Sectors are cut at the crown, the springline, the invert and every tangent point of the arcs
(a polycentric profile's curvature changes there), each with as many segments as its length
on the excavation holds interface sizes.
"""
from __future__ import annotations

import math

import numpy as np

from .joints import joint_layers
from .section import Profile
from .sizing import ground_size_field


def sector_params(spec) -> list[float]:
    """Turning angles (rad) where the lining is cut into structured sectors."""
    hole = spec.geometry.profile()
    cuts = {0.0, 0.5 * math.pi, math.pi, *hole.breaks()}
    return sorted(cuts)


def station_params(spec) -> np.ndarray:
    """Turning angles (rad) of the interface's vertex stations, crown to invert."""
    g = spec.geometry
    hole = g.profile(g.thickness + g.gap)
    cuts = sector_params(spec)
    out = [0.0]
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        length = float(np.diff(hole.arc_length(np.array([lo, hi])))[0])
        n = max(2, math.ceil(length / spec.mesh.interface_size - 1e-9))
        out.extend(np.linspace(lo, hi, n + 1)[1:])
    return np.array(out)


def profile_geometry(spec):
    """The gmsh built-in model of ground and lining of a non-circular section: the same
    ``(ground surfaces, lining surfaces, hole curves, extrados curves, intrados curves)`` as
    the circle's, the curves being the polylines' segments crown to invert."""
    import gmsh

    g = spec.geometry
    geo = gmsh.model.geo
    d = g.depth
    phi = station_params(spec)
    cuts = [int(np.argmin(np.abs(phi - c))) for c in sector_params(spec)]
    curves = {name: g.profile(offset) for name, offset in
              (("inner", 0.0), ("outer", g.thickness), ("hole", g.thickness + g.gap))}
    pts, lines = {}, {}
    for name, profile in curves.items():
        if name == "hole" and g.gap == 0:
            pts["hole"], lines["hole"] = pts["outer"], lines["outer"]
            continue
        xy = profile.points(phi)
        xy[0, [0, -1]] = 0.0  # crown and invert exactly on the axis
        pts[name], lines[name] = add_polyline(geo, xy[0], xy[1] - d)
    radial = {k: geo.addLine(pts["inner"][k], pts["outer"][k]) for k in cuts}
    lining_surfs = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        loop = [*lines["outer"][lo:hi], -radial[hi], *(-c for c in reversed(lines["inner"][lo:hi])), radial[lo]]
        lining_surfs.append((geo.addPlaneSurface([geo.addCurveLoop(loop)]),
                             [pts["inner"][lo], pts["inner"][hi], pts["outer"][hi], pts["outer"][lo]]))
    p_tl, p_tr = geo.addPoint(0, 0, 0), geo.addPoint(g.width, 0, 0)
    p_br, p_bl = geo.addPoint(g.width, -g.height, 0), geo.addPoint(0, -g.height, 0)
    hole_pts, hole = pts["hole"], lines["hole"]
    border = [geo.addLine(p_tl, p_tr), geo.addLine(p_tr, p_br), geo.addLine(p_br, p_bl),
              geo.addLine(p_bl, hole_pts[-1]), *(-c for c in reversed(hole)), geo.addLine(hole_pts[0], p_tl)]
    ground_surfs = [geo.addPlaneSurface([geo.addCurveLoop(border)])]
    geo.synchronize()

    mesh = gmsh.model.mesh
    for group in ("inner", "outer", "hole"):
        for c in lines[group]:
            mesh.setTransfiniteCurve(c, 2)
    for c in radial.values():
        mesh.setTransfiniteCurve(c, joint_layers(spec) + 1)
    for s, corners in lining_surfs:
        mesh.setTransfiniteSurface(s, "Alternate", corners)
    _size_field(spec, hole)
    return ground_surfs, [s for s, _ in lining_surfs], hole, lines["outer"], lines["inner"]


def _size_field(spec, hole) -> None:
    import gmsh

    ground_size_field(spec, hole, sampling=3)
    for name, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                        ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.Algorithm", 6)):
        gmsh.option.setNumber(name, value)


def curve_placer(profile: Profile, center):
    """Where a curved edge's P2 node goes: ``place(a, b)`` of its vertices (2, n) → the point
    (2, n) of ``profile`` (relative to ``center``) at their mean turning angle."""
    c = np.asarray(center, float)[:, None]

    def place(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        phi = 0.5 * (profile.parameter(a - c) + profile.parameter(b - c))
        return c + profile.points(phi)

    return place


def add_polyline(geo, x: np.ndarray, y: np.ndarray) -> tuple[list[int], list[int]]:
    """gmsh points at (x, y) and the straight lines joining them in order."""
    pts = [geo.addPoint(float(a), float(b), 0) for a, b in zip(x, y)]
    return pts, [geo.addLine(p, q) for p, q in zip(pts[:-1], pts[1:])]


def profile_interface(ground, lining, g_nodes, l_nodes, center, hole: Profile) -> dict:
    """The interface of a non-circular section: stations ordered crown → invert by their turning
    angle on the excavation ``hole`` (relative to ``center``), the ground's outward normal
    −n(φ), Simpson weights on the arc length of each quadratic edge, ``theta`` the polar angle:
    the fields of :class:`~solver.geometry.mesh.Interface`."""
    c = np.asarray(center, float)[:, None]
    phi_g = hole.parameter(ground.p[:, g_nodes] - c)
    phi_l = hole.parameter(lining.p[:, l_nodes] - c)  # the extrados's φ is the hole's along a normal
    g_nodes, phi_g = g_nodes[np.argsort(phi_g)], np.sort(phi_g)
    l_nodes, phi_l = l_nodes[np.argsort(phi_l)], np.sort(phi_l)
    if g_nodes.size != l_nodes.size or g_nodes.size % 2 == 0 or np.max(np.abs(phi_g - phi_l)) > 1e-6:
        raise RuntimeError("interface nodes of ground and lining do not pair on the normals")
    vertex = np.arange(g_nodes.size) % 2 == 0
    if not np.all(g_nodes[vertex] < ground.n_vertices) or np.any(g_nodes[~vertex] < ground.n_vertices):
        raise RuntimeError("interface nodes do not alternate vertex / edge node")
    rel = ground.p[:, g_nodes] - c
    theta = np.degrees(np.arctan2(rel[0], rel[1]))
    theta[0], theta[-1] = 0.0, 180.0
    phi_g[0], phi_g[-1] = 0.0, math.pi
    length = np.diff(hole.arc_length(phi_g[vertex]))
    weight = np.zeros(theta.size)
    weight[0:-1:2] += length / 6.0
    weight[2::2] += length / 6.0
    weight[1::2] += 2.0 * length / 3.0
    return dict(theta=theta, ground_node=g_nodes, lining_node=l_nodes, normal=-hole.normals(phi_g),
                weight=weight, vertex=vertex)


def extrados_arc_length(mesh, spec) -> np.ndarray:
    """(m,) length (m) along the lining's extrados from the crown to each interface station:
    b·θ on a circle, the profile's arc length at the station's turning angle otherwise."""
    g = spec.geometry
    if mesh.profile is None:
        return g.outer_radius * np.radians(mesh.interface.theta)
    extrados = mesh.profile.offset_by(g.thickness)
    phi = extrados.parameter(mesh.lining.p[:, mesh.interface.lining_node] - np.asarray(mesh.center, float)[:, None])
    phi[0], phi[-1] = 0.0, math.pi
    return extrados.arc_length(phi)
