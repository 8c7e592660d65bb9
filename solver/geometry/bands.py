"""The ground of the gmsh model as horizontal bands between its mesh lines (layer lines, a
drained case's water table), for a circular section (:mod:`.mesh`) and any other
(:mod:`.profile_mesh`) alike."""
from __future__ import annotations

import numpy as np


def ground_bands(geo, g, lines: list[float], hole_depths: list[float], hole_pts, hole, corners) -> list[int]:
    """The ground as horizontal bands between the mesh ``lines`` (depths, m), surface down.

    The ground's left edge, from the surface to the bottom, is monotone in depth: the symmetry
    line down to the crown, the excavation's curves (``hole``, joining the points ``hole_pts``,
    whose depths are ``hole_depths``, crown to invert) to the invert, the symmetry line to the
    bottom. Each line runs from its point on that edge (on the symmetry line, or on the
    excavation where it cuts it: a hole point, which the caller puts there) to the right side.
    Each band is bounded by its top line, the right side, its bottom line and the piece of the
    left edge between them."""
    p_tl, p_tr, p_br, p_bl = corners
    crown, invert = hole_depths[0], hole_depths[-1]
    # the left edge as (depth, point) vertices and the curve from each to the next, top down
    left = [(0.0, p_tl)]
    curves = []

    def axis_to(z, point):
        curves.append(geo.addLine(left[-1][1], point))
        left.append((z, point))

    for z in lines:
        if z < crown:
            axis_to(z, geo.addPoint(0, -z, 0))
    axis_to(crown, hole_pts[0])
    for k, curve in enumerate(hole):
        curves.append(curve)
        left.append((hole_depths[k + 1], hole_pts[k + 1]))
    for z in lines:
        if z > invert:
            axis_to(z, geo.addPoint(0, -z, 0))
    axis_to(g.height, p_bl)

    def left_point(z):
        return min(range(len(left)), key=lambda i: abs(left[i][0] - z))

    rights = [p_tr] + [geo.addPoint(g.width, -z, 0) for z in lines] + [p_br]
    tops = [geo.addLine(p_tl, p_tr)] + [geo.addLine(left[left_point(z)][1], rights[k + 1])
                                         for k, z in enumerate(lines)]
    bottom = geo.addLine(p_br, p_bl)
    sides = [geo.addLine(rights[k], rights[k + 1]) for k in range(len(rights) - 1)]
    at = [0] + [left_point(z) for z in lines] + [len(left) - 1]
    surfaces = []
    for k in range(len(lines) + 1):
        lower = -tops[k + 1] if k < len(lines) else bottom
        up = [-curves[i] for i in range(at[k + 1] - 1, at[k] - 1, -1)]
        surfaces.append(geo.addPlaneSurface([geo.addCurveLoop([tops[k], sides[k], lower, *up])]))
    return surfaces


def circle_hole_depths(g, angles: list[float]) -> list[float]:
    """Depths (m) of a circular excavation's points at ``angles`` (deg from the crown)."""
    return [float(g.depth - g.hole_radius * np.cos(np.radians(a))) for a in angles]
