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

from ..ground.strata import mesh_lines
from .bands import ground_bands
from .joints import (
    JOINT_SIZE,
    JointCuts,
    joint_angles,
    joint_edge,
    radial_pieces,
    transfinite,
    zones_towards,
)
from .section import Profile
from .sizing import ground_size_field


def sector_params(spec) -> list[float]:
    """Turning angles (rad) where the lining is cut into structured sectors: crown, springline,
    invert, the arcs' tangent points, where a mesh line of the ground (a layer line, a drained
    case's table) meets the excavation (:func:`line_params`), a segmental lining's joints
    (:func:`joint_params`) and where the hoop grading towards each joint ends."""
    zones = profile_zones(spec)
    return sorted({*_fixed_params(spec), *joint_params(spec), *(z[0] for z in zones), *(z[1] for z in zones)})


def _fixed_params(spec) -> set[float]:
    return {0.0, 0.5 * math.pi, math.pi, *spec.geometry.profile().breaks(), *line_params(spec)}


def _hole(spec) -> Profile:
    g = spec.geometry
    return g.profile(g.thickness + g.gap)


def _param_where(hole: Profile, coordinate, target: float) -> float:
    """The turning angle (rad) in [0, π] where ``coordinate(points (2, 1))``, monotone along the
    half profile, equals ``target`` (Brent's method)."""
    from scipy.optimize import brentq

    return float(brentq(lambda phi: coordinate(hole.points(np.array([phi])))[0] - target, 0.0, math.pi, xtol=1e-14))


def line_params(spec) -> list[float]:
    """Turning angles (rad) where the ground's horizontal mesh lines cut the excavation. A convex
    profile's height falls monotonically from crown to invert along its turning angle, so each
    line inside the excavation's height meets the half profile once."""
    g, hole = spec.geometry, _hole(spec)
    top, bottom = (float(v) for v in hole.points(np.array([0.0, math.pi]))[1])
    out = []
    for z in mesh_lines(spec):
        y = g.depth - z  # the line's height above the section's centre
        if bottom < y < top:
            out.append(_param_where(hole, lambda p: -p[1], -y))
    return out


def joint_params(spec) -> list[float]:
    """Turning angles (rad) of a segmental lining's joints: each joint (SPEC §1.6, at the polar
    angle θ of :func:`~solver.geometry.joints.joint_angles`) cuts the lining along the normal
    through the excavation boundary's point at θ (the polar angle grows monotonically with the
    turning angle on a convex profile). Crown and invert exactly 0 and π."""
    hole = _hole(spec)
    out = []
    for theta in joint_angles(spec):
        if theta in (0.0, 180.0):
            out.append(math.radians(theta))
        else:
            out.append(_param_where(hole, lambda p: np.degrees(np.arctan2(np.abs(p[0]), p[1])), theta))
    return out


def param_at_length(profile: Profile, length: np.ndarray) -> np.ndarray:
    """Turning angles (rad) at arc lengths ``length`` (m) from the crown along ``profile``:
    interpolated on a fine sampling, polished by Newton's method (ds/dφ = ρ)."""
    grid = np.linspace(0.0, math.pi, 20001)
    phi = np.interp(length, profile.arc_length(grid), grid)
    for _ in range(3):
        phi = np.clip(phi - (profile.arc_length(phi) - length) * profile.curvature(phi), 0.0, math.pi)
    return phi


def profile_zones(spec) -> list[tuple[float, float, np.ndarray]]:
    """The hoop grading towards each joint (:func:`~solver.geometry.joints.zones_towards`, in arc
    length along the excavation): per zone its joint's and its end's turning angles (rad) and the
    turning angles of its stations, ascending, both ends included."""
    joints = joint_params(spec)
    if not joints:
        return []
    hole = _hole(spec)
    along = lambda phi: [float(v) for v in hole.arc_length(np.asarray(phi, float))]  # noqa: E731
    others = sorted(set(along(sorted(_fixed_params(spec) | set(joints)))))
    zones = zones_towards(along(joints), others, JOINT_SIZE * joint_edge(spec), spec.mesh.interface_size,
                          hole.length)
    joint_at = dict(zip(along(joints), joints))
    out = []
    for z in zones:
        joint = joint_at[z.start]
        k = np.arange(z.elements + 1)
        s = z.start + np.sign(z.end - z.start) * z.first * (z.growth**k - 1.0) / (z.growth - 1.0)
        phi = param_at_length(hole, np.sort(s))
        end = float(param_at_length(hole, np.array([z.end]))[0])
        lo, hi = (end, joint) if z.end < z.start else (joint, end)
        phi[0], phi[-1] = lo, hi
        out.append((joint, end, phi))
    return out


def station_params(spec) -> np.ndarray:
    """Turning angles (rad) of the interface's vertex stations, crown to invert: graded towards
    the joints (:func:`profile_zones`), elsewhere uniform in each sector at most
    ``interface_size`` apart."""
    hole = _hole(spec)
    cuts = sector_params(spec)
    graded = {(min(j, e), max(j, e)): phi for j, e, phi in profile_zones(spec)}
    out = [0.0]
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        if (lo, hi) in graded:
            out.extend(graded[(lo, hi)][1:])
            continue
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
    pieces = radial_pieces(spec)  # the lining's thickness in pieces (graded towards a joint's strip)
    offsets = [p.inner - g.inner_radius for p in pieces] + [g.thickness]
    curves = {k: g.profile(offset) for k, offset in enumerate(offsets)}
    curves["hole"] = g.profile(g.thickness + g.gap)
    pts, lines = {}, {}
    for name, profile in curves.items():
        if name == "hole" and g.gap == 0:
            pts["hole"], lines["hole"] = pts[len(pieces)], lines[len(pieces)]
            continue
        xy = profile.points(phi)
        xy[0, [0, -1]] = 0.0  # crown and invert exactly on the axis
        pts[name], lines[name] = add_polyline(geo, xy[0], xy[1] - d)
    radial = [{k: geo.addLine(pts[i][k], pts[i + 1][k]) for k in cuts} for i in range(len(pieces))]
    lining_surfs = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        for i in range(len(pieces)):
            loop = [*lines[i + 1][lo:hi], -radial[i][hi], *(-c for c in reversed(lines[i][lo:hi])), radial[i][lo]]
            lining_surfs.append((geo.addPlaneSurface([geo.addCurveLoop(loop)]),
                                 [pts[i][lo], pts[i][hi], pts[i + 1][hi], pts[i + 1][lo]]))
    p_tl, p_tr = geo.addPoint(0, 0, 0), geo.addPoint(g.width, 0, 0)
    p_br, p_bl = geo.addPoint(g.width, -g.height, 0), geo.addPoint(0, -g.height, 0)
    hole_pts, hole = pts["hole"], lines["hole"]
    lines_z = mesh_lines(spec)
    if lines_z:
        depths = list(d - curves["hole"].points(phi)[1])
        ground_surfs = ground_bands(geo, g, lines_z, depths, hole_pts, hole, (p_tl, p_tr, p_br, p_bl))
    else:
        border = [geo.addLine(p_tl, p_tr), geo.addLine(p_tr, p_br), geo.addLine(p_br, p_bl),
                  geo.addLine(p_bl, hole_pts[-1]), *(-c for c in reversed(hole)), geo.addLine(hole_pts[0], p_tl)]
        ground_surfs = [geo.addPlaneSurface([geo.addCurveLoop(border)])]
    geo.synchronize()

    mesh = gmsh.model.mesh
    for group in lines.values():
        for c in group:
            mesh.setTransfiniteCurve(c, 2)
    for piece, lines_i in zip(pieces, radial):
        for c in lines_i.values():
            transfinite(c, piece.elements, piece.growth)
    for s, corners in lining_surfs:
        mesh.setTransfiniteSurface(s, "Alternate", corners)
    _size_field(spec, hole)
    return ground_surfs, [s for s, _ in lining_surfs], hole, lines[len(pieces)], lines[0]


def _size_field(spec, hole) -> None:
    import gmsh

    ground_size_field(spec, hole, sampling=3)
    for name, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                        ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.Algorithm", 6)):
        gmsh.option.setNumber(name, value)


def profile_cuts(spec, center) -> JointCuts:
    """A non-circular lining's joints: cuts normal to it (:func:`joint_params`), found in the
    turning angle of the normal through a point (the intrados's :meth:`Profile.parameter`)."""
    g = spec.geometry
    intrados, mid = g.profile(), g.profile(0.5 * g.thickness)
    phi = joint_params(spec)
    c = np.asarray(center, float)[:, None]
    at = np.asarray(phi, float)
    reach = np.sum(mid.points(at) * mid.normals(at), axis=0) if phi else np.zeros(0)
    return JointCuts(theta=joint_angles(spec), cuts=[math.degrees(v) for v in phi],
                     normal=[math.degrees(v) for v in phi], mid=[float(v) for v in reach],
                     angle_of=lambda p: np.degrees(intrados.parameter(np.asarray(p, float) - c)))


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
