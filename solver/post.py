"""Post-processing: stresses, lining section forces, KKT check and scalars.

Lining forces use the section-equilibrium (nodal force) method: at the radial
line of lining nodes below interface node i (the structured lining has one per
station), the force that the invert-side part exerts on the crown-side part is
the sum over crown-side elements of their internal nodal forces at the cut
nodes, minus the crown side's share of the body and contact loads there. It
satisfies the discrete equilibrium exactly, so no stress smoothing error enters.
At the crown and invert the cut is the symmetry line and the force is the
symmetry reaction.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .assembly import element_stress, p1_gradients
from .mesh import BodyMesh, TunnelMesh
from .spec import CaseSpec


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


def lining_forces(spec: CaseSpec, mesh: TunnelMesh, u_lining: np.ndarray, lam: np.ndarray) -> LiningForces:
    """Section forces at every interface station from the lining's nodal forces.

    ``u_lining`` is (2, N) nodal displacement of the lining (m), ``lam`` (m,) Pa.
    """
    body: BodyMesh = mesh.lining
    iface = mesh.interface
    center = np.array(mesh.center)
    theta = np.radians(iface.theta)
    m = theta.size
    p, t = body.p, body.t

    node_ang = _angles(p, center)
    station = np.clip(np.searchsorted(theta, node_ang), 0, m - 1)
    lower = np.clip(station - 1, 0, m - 1)
    closer = np.abs(theta[lower] - node_ang) < np.abs(theta[station] - node_ang)
    station = np.where(closer, lower, station)
    if np.max(np.abs(theta[station] - node_ang)) > 1e-7:
        raise RuntimeError("lining mesh is not structured along the interface stations")

    sigma = element_stress(body, spec.lining, u_lining)
    grads, area = p1_gradients(body)
    # internal nodal force of element e at its local node k, minus its body-load share
    fx = area * (sigma[0] * grads[0] + sigma[2] * grads[1])
    fy = area * (sigma[2] * grads[0] + sigma[1] * grads[1])
    fy = fy + spec.lining.density * spec.loads.gravity * area / 3.0
    cen = p[:, t].mean(axis=1)
    elem_ang = _angles(cen, center)

    node = t.ravel()
    s = station[node]
    crown_side = np.broadcast_to(elem_ang, t.shape).ravel() < theta[s]
    take = crown_side | (s == 0) | (s == m - 1)
    s, node = s[take], node[take]
    Fx, Fy = fx.ravel()[take], fy.ravel()[take]

    # contact: force on the lining at node i is w λ ν; the crown side holds half a segment
    seg = np.linalg.norm(np.diff(p[:, iface.lining_node], axis=1), axis=0)
    share = np.r_[iface.weight[0], 0.5 * seg[:-1], iface.weight[-1]]
    cx = np.bincount(s, Fx, m)
    cy = np.bincount(s, Fy, m)
    cx -= share * lam * iface.normal[0]
    cy -= share * lam * iface.normal[1]

    tangent = np.stack([np.cos(theta), -np.sin(theta)])
    radial = np.stack([np.sin(theta), np.cos(theta)])
    n_out = tangent.copy()
    n_out[:, 0] *= -1.0  # at the crown the free body is the whole half lining
    r_mid = spec.geometry.inner_radius + 0.5 * spec.geometry.thickness
    r_node = np.hypot(*(p[:, node] - center[:, None]))
    along = Fx * n_out[0, s] + Fy * n_out[1, s]
    thrust = -(cx * n_out[0] + cy * n_out[1])
    moment = np.bincount(s, (r_node - r_mid) * along, m)
    # the contact share acts at the outer node; it is radial, so adds nothing to N or M
    shear = cx * radial[0] + cy * radial[1]
    shear[0] *= -1.0
    return LiningForces(thrust=thrust, moment=moment, shear=shear)


def contact_extent(theta_deg: np.ndarray, in_contact: np.ndarray) -> float:
    """Degrees of interface in contact (each node owns half of its neighbouring intervals)."""
    dth = np.diff(theta_deg)
    own = 0.5 * (np.r_[0.0, dth] + np.r_[dth, 0.0])
    return float(np.sum(own * in_contact))


def kkt_residual(*, K_u_minus_f: list[tuple[np.ndarray, np.ndarray]], balance: float, F2: float,
                 lam: np.ndarray, gap: np.ndarray, p_ref: float, u_ref: float) -> float:
    """Largest relative violation of the discrete KKT conditions (dimensionless).

    ``K_u_minus_f`` holds per body the residual ``K u + B^T W λ - f`` and the size
    of the forces it balances (``|f| + |B^T W λ|``); ``balance`` is ``F2 + I(λ ν2)`` (N/m). Pressures are
    scaled by ``p_ref`` (Pa), gaps by ``u_ref`` (m).
    """
    parts = [np.max(np.abs(r)) / max(np.max(np.abs(f)), 1e-300) for r, f in K_u_minus_f]
    parts.append(abs(balance) / abs(F2))
    parts.append(max(0.0, -float(lam.min())) / p_ref)
    parts.append(max(0.0, -float(gap.min())) / u_ref)
    parts.append(float(np.max(np.abs(lam * gap))) / (p_ref * u_ref))
    return float(max(parts))
