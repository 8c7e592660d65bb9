"""The lining's section forces N, M, V at every interface station.

Lining forces use the section-equilibrium (nodal force) method: at the radial line of
lining nodes below a vertex station i (the structured lining has one per element
vertex along the interface), the force that the invert-side part exerts on the
crown-side part is the sum over crown-side elements of their internal nodal forces
at the cut nodes, minus the crown side's share of the body and interface loads there
(the interface load at the cut node is split as Simpson's rule splits it: the
crown-side edge's L/6). It satisfies the discrete equilibrium exactly, so no stress
smoothing error enters. At the crown and invert the cut is the symmetry line and the
force is the symmetry reaction. At the edge-node stations between two vertices no
radial line of nodes exists; N, M and V there are interpolated linearly in θ.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fe.assembly import Body, element_nodal_forces
from ..geometry.bodies import Interface
from ..spec import CaseSpec


@dataclass(frozen=True)
class LiningForces:
    """Per interface station: thrust N (N/m, compression +), moment M (N·m/m, + when
    the inner fibre is in compression), shear V (N/m, radial force of the invert
    side on the crown side, outward +)."""

    thrust: np.ndarray
    moment: np.ndarray
    shear: np.ndarray


def _angles(p: np.ndarray, center) -> np.ndarray:
    return np.arctan2(p[0] - center[0], p[1] - center[1])  # rad, 0 at crown


class _Cuts:
    """Where a lining node lies for the cuts: ``angle`` (rad) of the cut it is on (the polar
    angle on a circle, the turning angle φ of the mid-surface's normal otherwise) and ``lever``
    (m) its distance outward from the mid-surface; ``of_stations`` the cut angles of the interface
    stations; ``between`` the extrados's length between consecutive vertex stations."""

    def __init__(self, spec: CaseSpec, p: np.ndarray, iface: Interface, center: np.ndarray, profile):
        g = spec.geometry
        vtx = np.flatnonzero(iface.vertex)
        self.profile = None
        if profile is None:
            self.angle = _angles(p, center)
            self.of_stations = np.radians(iface.theta)
            r_mid = g.inner_radius + 0.5 * g.thickness
            self.lever = np.hypot(*(p - center[:, None])) - r_mid
            self.outer_lever = g.outer_radius - r_mid
            self.between = np.diff(np.radians(iface.theta[vtx])) * np.linalg.norm(p[:, iface.lining_node[0]] - center)
        else:
            mid = self.profile = profile.offset_by(0.5 * g.thickness)
            self.angle = mid.parameter(p - center[:, None])
            self.of_stations = self.angle[iface.lining_node]
            self.of_stations[0], self.of_stations[-1] = 0.0, np.pi
            self.angle[iface.lining_node] = self.of_stations
            foot = mid.points(self.angle)
            self.lever = np.sum((p - center[:, None] - foot) * mid.normals(self.angle), axis=0)
            self.outer_lever = 0.5 * g.thickness
            self.between = np.diff(profile.offset_by(g.thickness).arc_length(self.of_stations[vtx]))

    def of_points(self, xy: np.ndarray, center: np.ndarray) -> np.ndarray:
        """Cut angles of points inside the lining (element centroids)."""
        if self.profile is None:
            return _angles(xy, center)
        return self.profile.parameter(xy - center[:, None])


def lining_forces(spec: CaseSpec, lining: Body, iface: Interface, center, u_lining: np.ndarray,
                  lam: np.ndarray, shear_traction: np.ndarray, profile=None) -> LiningForces:
    """Section forces at every interface station from the lining's nodal forces.

    ``u_lining`` (2, N) m is the lining's nodal displacement, ``lam`` and
    ``shear_traction`` (m,) Pa the interface tractions on the lining; ``profile`` the intrados of
    a section that is not a circle (cuts normal to the mid-surface), None for a circle (radial cuts).
    """
    center = np.asarray(center, float)
    p = lining.mesh.p
    cuts = _Cuts(spec, p, iface, center, profile)
    vtx = np.flatnonzero(iface.vertex)
    theta = cuts.of_stations[vtx]
    ms = theta.size

    node_ang = cuts.angle
    station = np.clip(np.searchsorted(theta, node_ang), 0, ms - 1)
    lower = np.clip(station - 1, 0, ms - 1)
    closer = np.abs(theta[lower] - node_ang) < np.abs(theta[station] - node_ang)
    station = np.where(closer, lower, station)
    on_line = np.abs(theta[station] - node_ang) <= 1e-7
    if np.bincount(station[on_line], minlength=ms).min() < 2:
        raise RuntimeError("lining mesh is not structured along the interface stations")

    force, dofs = element_nodal_forces(lining, spec.lining.young, spec.lining.poisson, u_lining,
                                       spec.lining.density, spec.loads.gravity)
    node_of = np.empty(lining.basis.N, np.int64)
    comp_of = np.empty(lining.basis.N, np.int64)
    node_of[lining.dof_of_node] = np.broadcast_to(np.arange(p.shape[1]), lining.dof_of_node.shape)
    comp_of[lining.dof_of_node] = np.arange(2)[:, None]
    t = lining.mesh.t
    elem_ang = cuts.of_points(p[:, t[:3]].mean(axis=1), center)

    node, comp = node_of[dofs], comp_of[dofs]  # (12, E)
    keep = on_line[node]
    s = station[node]
    crown_side = np.broadcast_to(elem_ang, node.shape) < theta[s]
    take = keep & (crown_side | (s == 0) | (s == ms - 1))
    s, node, comp, F = s[take], node[take], comp[take], force[take]
    cx = np.bincount(s[comp == 0], F[comp == 0], ms)
    cy = np.bincount(s[comp == 1], F[comp == 1], ms)

    # interface load at the cut node: the crown side's Simpson share (L/6 of its edge)
    share = np.r_[iface.weight[0], cuts.between[:-1] / 6.0, iface.weight[-1]]
    nu, tau = iface.normal[:, vtx], iface.tangent[:, vtx]
    load = share * (lam[vtx] * nu + shear_traction[vtx] * tau)  # (2, ms) on the lining
    cx -= load[0]
    cy -= load[1]

    tangent = np.stack([np.cos(theta), -np.sin(theta)])
    radial = np.stack([np.sin(theta), np.cos(theta)])
    n_out = tangent.copy()
    n_out[:, 0] *= -1.0  # at the crown the free body is the whole half lining
    dirn = np.where(comp == 0, n_out[0, s], n_out[1, s])
    moment = np.bincount(s, cuts.lever[node] * F * dirn, ms)
    moment -= cuts.outer_lever * (load[0] * n_out[0] + load[1] * n_out[1])
    thrust = -(cx * n_out[0] + cy * n_out[1])
    shear = cx * radial[0] + cy * radial[1]
    shear[0] *= -1.0

    th_all = cuts.of_stations
    return LiningForces(*(np.interp(th_all, theta, f) for f in (thrust, moment, shear)))
