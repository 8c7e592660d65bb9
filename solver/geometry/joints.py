"""The joints of a segmental lining in its mesh (SPEC §1.6, §9.2): their angles, the lining's
grading towards them (through the thickness, with the contact strip's ends on nodes, and along the
ring: :func:`radial_pieces`, :func:`graded_zones`, :func:`hoop_divisions`), the cut along each
joint's radial line and the faces and segments the cut makes."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..spec import CaseSpec
from .bodies import BodyMesh, Joints
from .sizing import interface_segments, lining_layers

def polar_angle(p: np.ndarray, center) -> np.ndarray:
    """Angle at the tunnel axis in degrees, 0 at the crown, 180 at the invert (x >= 0)."""
    return np.degrees(np.arctan2(p[0] - center[0], p[1] - center[1]))


def joint_angles(spec: CaseSpec) -> list[float]:
    """Angles (deg from the crown) of the lining's joints in the half model [0°, 180°]
    (SPEC §1.6: ``offset + k·360°/n``); empty for a monolithic ring."""
    j = spec.lining.joints
    if not j.count:
        return []
    step = 360.0 / j.count
    angles = (j.offset + step * np.arange(j.count)) % 360.0
    return sorted(round(float(t), 9) for t in angles if t <= 180.0 + 1e-9)


#: The radial element size at the edges of a joint's contact strip, as a fraction of
#: ``interface_size``: an opening joint carries its thrust on a zone near the strip's edge (7.5 mm
#: to 5 cm in the default segmental case) that the faces' nodes must resolve.
JOINT_EDGE = 0.05

#: Growth of successive radial elements away from the strip's edges, at most.
RADIAL_GROWTH = 1.3


@dataclass(frozen=True)
class RadialPiece:
    """A piece of the lining's thickness between radii ``inner`` and ``outer`` (m), meshed with
    ``elements`` radial elements in geometric progression (``growth`` outwards)."""

    inner: float
    outer: float
    elements: int
    growth: float


def radial_pieces(spec: CaseSpec) -> list[RadialPiece]:
    """The lining's thickness in pieces with their radial element counts.

    A monolithic ring: one piece of :func:`~solver.geometry.sizing.lining_layers` uniform layers.
    A segmental one: pieces bounded by the faces, the mid-surface and the edges of the joints'
    contact strip, each graded (at most :data:`RADIAL_GROWTH`) from :data:`JOINT_EDGE` times
    ``interface_size`` at the strip's edges, so that the strip ends at nodes and the zone an
    opening joint bears on is resolved."""
    g, j = spec.geometry, spec.lining.joints
    a, b = g.inner_radius, g.inner_radius + g.thickness  # radii on a circle; a + offset on another section
    if not j.count:
        return [RadialPiece(a, b, lining_layers(spec), 1.0)]
    t = g.thickness
    height = min(j.contact_height or t, t)
    mid = a + 0.5 * t
    edge = min(joint_edge(spec), height / 4.0)
    if height >= t * (1.0 - 1e-9):
        bounds, fine = [a, mid, b], [True, False]  # per piece: whether its fine end is its inner one
    else:
        lo, hi = mid - 0.5 * height, mid + 0.5 * height
        bounds, fine = [a, lo, mid, hi, b], [False, True, False, True]
    pieces = []
    for r0, r1, at_inner in zip(bounds[:-1], bounds[1:], fine):
        n, q = _progression(r1 - r0, edge, RADIAL_GROWTH)
        pieces.append(RadialPiece(r0, r1, n, q if at_inner else 1.0 / q))
    return pieces


def joint_edge(spec: CaseSpec) -> float:
    """The radial element size at a joint's strip edges (m): :data:`JOINT_EDGE` × ``interface_size``."""
    return JOINT_EDGE * spec.mesh.interface_size


def _progression(length: float, first: float, growth: float) -> tuple[int, float]:
    """Elements and ratio of a geometric progression over ``length`` whose first element is at
    most ``first`` and whose ratio is at most ``growth`` (the ratio that fits exactly)."""
    n = max(1, math.ceil(math.log(1.0 + length * (growth - 1.0) / first) / math.log(growth) - 1e-9))
    if n * first >= length:  # uniform elements no longer than the first
        return n, 1.0
    lo, hi = 1.0, growth
    for _ in range(60):  # first · (q^n - 1)/(q - 1) = length, increasing in q
        q = 0.5 * (lo + hi)
        lo, hi = (q, hi) if first * (q**n - 1.0) / (q - 1.0) < length else (lo, q)
    return n, 0.5 * (lo + hi)


def joint_layers(spec: CaseSpec) -> int:
    """Element layers through the lining (the sum over :func:`radial_pieces`)."""
    return sum(p.elements for p in radial_pieces(spec))


#: A joint's hoop element size (along the excavation), as a fraction of the radial one at the
#: strip's edges (:func:`joint_edge`).
JOINT_SIZE = 1.0

#: Growth of successive hoop elements away from a joint, at most (to the ring's uniform size).
JOINT_GROWTH = 1.3


@dataclass(frozen=True)
class GradedZone:
    """The lining's hoop elements graded away from a joint: from the joint's angle ``start`` to
    ``end`` (deg; on either side), ``elements`` elements growing by ``growth`` each away from the
    joint (the first ``first`` deg long)."""

    start: float
    end: float
    elements: int
    growth: float

    @property
    def first(self) -> float:
        q, n = self.growth, self.elements
        return abs(self.end - self.start) * (q - 1.0) / (q**n - 1.0)


def graded_zones(spec: CaseSpec) -> list[GradedZone]:
    """Hoop grading of a segmental lining's mesh towards each joint (empty for a monolithic ring).

    At a joint the hoop element is :data:`JOINT_SIZE` times the radial one at the strip's edges
    (:func:`joint_edge`); away from it the elements grow geometrically (at most
    :data:`JOINT_GROWTH`, exactly so that the next one is the ring's uniform element of
    ``interface_size``), over about one lining thickness. A zone never reaches past half the way
    to the next sector angle (a joint, the springline, a layer line): there it is cut short."""
    joints = joint_angles(spec)
    if not joints:
        return []
    g = spec.geometry
    uniform = 90.0 / interface_segments(spec)  # deg
    size = math.degrees(JOINT_SIZE * joint_edge(spec) / g.hole_radius)
    others = sorted({0.0, 90.0, 180.0, *joints, *line_angles(spec)})
    return zones_towards(joints, others, size, uniform, 180.0)


def zones_towards(joints: list[float], others: list[float], size: float, uniform: float,
                  end: float) -> list[GradedZone]:
    """The graded zones of :func:`graded_zones` in any coordinate along the ring from 0 (the
    crown) to ``end`` (the invert): degrees on a circle, arc length on another section.
    ``size``: the element at a joint; ``uniform``: the ring's element it grows to; ``others``:
    the ring's sector cuts, which a zone reaches at most half the way to."""
    if size >= uniform:
        return []
    n = max(1, math.ceil(math.log(uniform / size) / math.log(JOINT_GROWTH) - 1e-9))
    q = (uniform / size) ** (1.0 / n)
    tiny = 1e-9 * end
    zones = []
    for t in joints:
        for side in (-1.0, 1.0):
            if not 0.0 <= t + side * tiny <= end:
                continue
            room = min(abs(a - t) for a in others if (a - t) * side > tiny)
            m = n
            while m > 1 and size * (q**m - 1.0) / (q - 1.0) > 0.5 * room:
                m -= 1
            length = size * (q**m - 1.0) / (q - 1.0)
            if length > 0.5 * room:
                continue
            zones.append(GradedZone(start=t, end=round(t + side * length, 9), elements=m, growth=q))
    return zones


def line_angles(spec: CaseSpec) -> list[float]:
    """Angles (deg) where the ground's mesh lines meet the excavation boundary."""
    from ..ground.strata import mesh_lines

    g = spec.geometry
    out = []
    for z in mesh_lines(spec):
        c = (g.depth - z) / g.hole_radius
        if -1.0 < c < 1.0:
            out.append(float(np.degrees(np.arccos(c))))
    return out


def hoop_divisions(spec: CaseSpec, angles: list[float]) -> list[tuple[int, float]]:
    """Elements and growth (gmsh's geometric progression, along increasing θ) of each sector of the
    ring between consecutive ``angles`` (:func:`solver.geometry.mesh.sector_angles`): a graded zone's
    (:func:`graded_zones`), else uniform at ``interface_size``."""
    per_quarter = interface_segments(spec)
    zones = {(min(z.start, z.end), max(z.start, z.end)): z for z in graded_zones(spec)}
    out = []
    for lo, hi in zip(angles[:-1], angles[1:]):
        z = zones.get((lo, hi))
        if z is None:
            out.append((max(1, round((hi - lo) / 90.0 * per_quarter)), 1.0))
        else:
            out.append((z.elements, z.growth if z.end > z.start else 1.0 / z.growth))
    return out


def cut_along(p: np.ndarray, t: np.ndarray, cuts, angle_of) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut linear triangles ``t`` along the lines where ``angle_of`` (of points (2, n)) equals each
    of ``cuts``: the radial lines at the polar angles (deg) on a circle, the normals at the turning
    angles on another section. The vertices on a line get copies (appended to ``p``) that the
    triangles on its invert side use instead. Returns the new ``p``, ``t`` and, per copy, the
    vertex it copies."""
    origin = np.zeros(0, np.int64)
    # once: a cut appends copies at the same places and renumbers corners, moving no point
    ang = angle_of(p) if len(cuts) else None
    centroid = angle_of(p[:, t].mean(axis=1)) if len(cuts) else None
    for a in cuts:
        on = np.flatnonzero(np.abs(ang - a) <= 1e-6)
        if on.size < 2:
            raise RuntimeError(f"no line of lining nodes across the joint at {a:g} deg")
        remap = np.arange(p.shape[1])
        remap[on] = p.shape[1] + np.arange(on.size)
        t = np.where(centroid[None, :] > a, remap[t], t)
        p = np.hstack([p, p[:, on]])
        ang = np.r_[ang, ang[on]]
        origin = np.r_[origin, on]
    return p, t, origin


@dataclass(frozen=True)
class JointCuts:
    """Where a lining's joints cut it: ``theta`` (deg at the axis, as reported), ``cuts`` in the
    coordinate of ``angle_of`` (points (2, n) → deg: the polar angle on a circle, the turning
    angle of the normal cut through the point on another section), ``normal`` (deg, the turning
    angle of each cut's outward normal) and ``mid`` (m, each cut's mid-surface point projected
    on that normal from the section's centre)."""

    theta: list[float]
    cuts: list[float]
    normal: list[float]
    mid: list[float]
    angle_of: object


def circle_cuts(spec: CaseSpec, center) -> JointCuts:
    """A circular lining's joints: radial cuts at their polar angles."""
    theta = joint_angles(spec)
    g = spec.geometry
    return JointCuts(theta=theta, cuts=theta, normal=theta, mid=[g.inner_radius + 0.5 * g.thickness] * len(theta),
                     angle_of=lambda p: polar_angle(p, center))


def joint_faces(lining: BodyMesh, cut: JointCuts, center) -> Joints:
    """The faces of the lining's joints where ``cut`` says and the segment of each node."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    c = np.asarray(center, dtype=float)[:, None]
    n = lining.p.shape[1]
    e = lining.t.shape[1]
    incidence = coo_matrix((np.ones(6 * e), (lining.t.ravel(), np.tile(np.arange(e), 6))), shape=(n, e)).tocsr()
    count, label = connected_components(incidence @ incidence.T, directed=False)
    ang = cut.angle_of(lining.p)
    mean = np.array([ang[label == k].mean() for k in range(count)])
    segment = np.argsort(np.argsort(mean))[label]
    centroid = cut.angle_of(lining.p[:, lining.t[:3]].mean(axis=1))
    before, after, across = [], [], []
    for a, normal, mid in zip(cut.cuts, cut.normal, cut.mid):
        on = np.flatnonzero(np.abs(ang - a) <= 1e-6)
        out = np.array([np.sin(np.radians(normal)), np.cos(np.radians(normal))]) @ (lining.p[:, on] - c) - mid
        if normal == 0.0:
            sides = (np.zeros(0, np.int64), on)
        elif normal == 180.0:
            sides = (on, np.zeros(0, np.int64))
        else:
            early = np.zeros(n, bool)
            early[lining.t[:, centroid < a].ravel()] = True
            sides = (on[early[on]], on[~early[on]])
        for group, side in zip((before, after), sides):  # ordered from the intrados out
            group.append(side[np.argsort(out[np.searchsorted(on, side)])])
        face = before[-1] if before[-1].size else after[-1]
        across.append(out[np.searchsorted(on, face)])
        if 0.0 < normal < 180.0 and before[-1].size != after[-1].size:
            raise RuntimeError(f"the joint at {a:g} deg has faces of {before[-1].size} and {after[-1].size} nodes")
    inner = len([t for t in cut.normal if 0.0 < t < 180.0])
    if count != inner + 1:
        raise RuntimeError(f"the lining's {inner} joints inside the half model make {count} segments, not {inner + 1}")
    return Joints(theta=np.array(cut.theta, dtype=float), before=tuple(before), after=tuple(after), segment=segment,
                  normal=np.array(cut.normal, dtype=float), across=tuple(across))


def transfinite(curve: int, elements: int, growth: float) -> None:
    """``elements`` on a gmsh curve, uniform or in geometric progression (``growth`` along it)."""
    import gmsh

    if growth == 1.0:
        gmsh.model.mesh.setTransfiniteCurve(curve, elements + 1)
    else:
        gmsh.model.mesh.setTransfiniteCurve(curve, elements + 1, "Progression", growth)
