"""The meshed section as data: each body's quadratic triangles, the interface between them, a
segmental lining's joints, and the whole (:class:`TunnelMesh`). :mod:`.mesh` builds them."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .section import Profile


@dataclass(frozen=True)
class BodyMesh:
    """A body's quadratic triangles.

    ``p`` (2, N) node coordinates in m, vertices first then edge nodes; ``t`` (6, E)
    0-based node indices per triangle: vertices counter-clockwise, then the edge nodes
    of edges (0, 1), (1, 2), (0, 2) (scikit-fem's order).
    """

    p: np.ndarray
    t: np.ndarray

    @property
    def n_vertices(self) -> int:
        return int(self.t[:3].max()) + 1

    def skfem_mesh(self):
        """The isoparametric scikit-fem mesh (``MeshTri2``) of this body."""
        from skfem import MeshTri2

        return MeshTri2(self.p, self.t[:3].copy(), validate=False)


@dataclass(frozen=True)
class Joints:
    """The longitudinal joints of a segmental lining (SPEC §1.6), ordered crown to invert.

    theta : (J,) deg at the tunnel axis (of the joint's station on the excavation boundary).
    before, after : per joint, the lining nodes of the face on the crown side (θ < θj) and on
        the invert side, ordered from the intrados out (vertices and edge nodes). A joint on the
        symmetry line has one face in the half model: ``after`` at the crown, ``before`` at the
        invert, the other empty (the mirror segment's face moves symmetrically).
    segment : (N,) the segment of each lining node, numbered crown to invert.
    normal : (J,) deg, the turning angle of the lining's outward normal along which each joint
        cuts it (its hoop direction is (cos, −sin), its outward one (sin, cos)); θ on a circle.
    across : per joint, each face node's distance (m) from the lining's mid-surface along the
        cut, outward positive (``r − r_mid`` on a circle), in the order of the face's nodes.
    """

    theta: np.ndarray
    before: tuple[np.ndarray, ...]
    after: tuple[np.ndarray, ...]
    segment: np.ndarray
    normal: np.ndarray
    across: tuple[np.ndarray, ...]

    @property
    def size(self) -> int:
        return self.theta.size

    @property
    def segments(self) -> int:
        return int(self.segment.max()) + 1

    def on_axis(self, j: int) -> bool:
        """Whether joint ``j`` lies on the symmetry line (crown or invert)."""
        return self.before[j].size == 0 or self.after[j].size == 0


@dataclass(frozen=True)
class Interface:
    """Interface Γ, ordered crown (theta = 0) to invert (theta = 180).

    Attributes
    ----------
    theta : (m,) deg, at the tunnel axis, 0 at the crown.
    ground_node, lining_node : (m,) node indices into the ground / lining mesh.
    normal : (2, m) unit outward normal of the ground (points to the tunnel axis).
    weight : (m,) m, the nodal quadrature I of the quadratic edges (Simpson's rule:
        L/6 at each vertex, 2L/3 at the edge node, L the arc length of the edge).
    vertex : (m,) bool, True at element vertices (every other node, crown and invert
        included); the lining's radial lines of nodes lie below these stations.
    """

    theta: np.ndarray
    ground_node: np.ndarray
    lining_node: np.ndarray
    normal: np.ndarray
    weight: np.ndarray
    vertex: np.ndarray

    @property
    def tangent(self) -> np.ndarray:
        """(2, m) unit tangent τ: ν turned 90° so that it points towards increasing θ."""
        return np.stack([-self.normal[1], self.normal[0]])

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
    #: (E,) index of the ground band (layer) of each ground triangle, surface down.
    ground_band: np.ndarray | None = None
    #: the lining's joints (None: a monolithic ring)
    joints: Joints | None = None
    #: a section that is not a circle: its intrados (:class:`~solver.geometry.section.Profile`,
    #: relative to ``center``); None for a circle
    profile: Profile | None = None
