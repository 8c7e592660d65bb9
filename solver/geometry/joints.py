"""The joints of a segmental lining in its mesh (SPEC §1.6): their angles, the lining's layer
count that puts the contact strip's ends on nodes, the cut along each joint's radial line and
the faces and segments the cut makes."""
from __future__ import annotations

import math

import numpy as np

from ..spec import CaseSpec
from .bodies import BodyMesh, Joints
from .sizing import lining_layers

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


#: Node spacings across a joint's contact strip, at least: an open joint carries its thrust on a
#: zone near the strip's edge that the strip's nodes must resolve (with 2, the default mesh put the
#: whole thrust of every open joint on the edge node).
STRIP_SPACINGS = 8


#: Element layers through a segmental lining, at most.
MAX_JOINT_LAYERS = 24


def joint_layers(spec: CaseSpec) -> int:
    """Element layers through the lining: :func:`~solver.geometry.sizing.lining_layers`; for a segmental
    lining at least enough for :data:`STRIP_SPACINGS` node spacings across the joints' strip
    (the radial lines carry 2L + 1 equally spaced nodes), and the least such count for which the
    strip ends at nodes (``L a / t`` whole) if one is below :data:`MAX_JOINT_LAYERS`; else the
    strip is the nodes within ``a`` (:func:`solver.lining.joints.joint_rows`)."""
    layers = lining_layers(spec)
    j, t = spec.lining.joints, spec.geometry.thickness
    if not j.count:
        return layers
    a = j.contact_height or t
    least = max(layers, math.ceil(STRIP_SPACINGS * t / (2.0 * a) - 1e-9))
    for n in range(least, MAX_JOINT_LAYERS + 1):
        ratio = n * a / t
        if abs(ratio - round(ratio)) <= 1e-6:
            return n
    return min(least, MAX_JOINT_LAYERS)


def cut_along(p: np.ndarray, t: np.ndarray, angles, center) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut linear triangles ``t`` along the radial lines at ``angles`` (deg): the vertices on a
    line get copies (appended to ``p``) that the triangles on its invert side use instead.
    Returns the new ``p``, ``t`` and, per copy, the vertex it copies."""
    c = np.asarray(center, dtype=float)
    origin = np.zeros(0, np.int64)
    for a in angles:
        ang = polar_angle(p, c)
        centroid = polar_angle(p[:, t].mean(axis=1), c)
        on = np.flatnonzero(np.abs(ang - a) <= 1e-6)
        if on.size < 2:
            raise RuntimeError(f"no radial line of lining nodes at the joint at {a:g} deg")
        remap = np.arange(p.shape[1])
        remap[on] = p.shape[1] + np.arange(on.size)
        t = np.where(centroid[None, :] > a, remap[t], t)
        p = np.hstack([p, p[:, on]])
        origin = np.r_[origin, on]
    return p, t, origin


def joint_faces(lining: BodyMesh, angles: list[float], center) -> Joints:
    """The faces of the lining's joints at ``angles`` (deg) and the segment of each node."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    c = np.asarray(center, dtype=float)
    n = lining.p.shape[1]
    e = lining.t.shape[1]
    incidence = coo_matrix((np.ones(6 * e), (lining.t.ravel(), np.tile(np.arange(e), 6))), shape=(n, e)).tocsr()
    count, label = connected_components(incidence @ incidence.T, directed=False)
    ang = polar_angle(lining.p, c)
    mean = np.array([ang[label == k].mean() for k in range(count)])
    segment = np.argsort(np.argsort(mean))[label]
    radius = np.hypot(*(lining.p - c[:, None]))
    centroid = polar_angle(lining.p[:, lining.t[:3]].mean(axis=1), c)
    before, after = [], []
    for a in angles:
        on = np.flatnonzero(np.abs(ang - a) <= 1e-6)
        if a == 0.0:
            sides = (np.zeros(0, np.int64), on)
        elif a == 180.0:
            sides = (on, np.zeros(0, np.int64))
        else:
            early = np.zeros(n, bool)
            early[lining.t[:, centroid < a].ravel()] = True
            sides = (on[early[on]], on[~early[on]])
        for group, side in zip((before, after), sides):
            group.append(side[np.argsort(radius[side])])
        if a not in (0.0, 180.0) and before[-1].size != after[-1].size:
            raise RuntimeError(f"the joint at {a:g} deg has faces of {before[-1].size} and {after[-1].size} nodes")
    inner = len([a for a in angles if 0.0 < a < 180.0])
    if count != inner + 1:
        raise RuntimeError(f"the lining's {inner} joints inside the half model make {count} segments, not {inner + 1}")
    return Joints(theta=np.array(angles, dtype=float), before=tuple(before), after=tuple(after), segment=segment)
