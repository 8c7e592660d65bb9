"""A solved case as an xarray Dataset (SPEC §3): UGRID-1.0 mesh, fields, interface, scalars."""
from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import datetime, timezone

import numpy as np
import xarray as xr

from .mesh import TunnelMesh
from .spec import CaseSpec

SCALARS = {
    "max_contact_pressure": ("Pa", "maximum contact pressure"),
    "contact_extent": ("degree", "angular extent of the interface in contact"),
    "crown_settlement": ("m", "settlement of the lining crown (downward positive)"),
    "max_thrust": ("N m-1", "maximum lining thrust (compression positive)"),
    "max_abs_moment": ("N m m-1", "maximum absolute lining bending moment"),
    "lining_weight": ("N m-1", "weight of the (half) lining per metre of tunnel"),
    "bolt_theta": ("degree", "position of the accepted bolt point"),
    "bolt_trials": ("1", "number of bolt points tried"),
    "iterations": ("1", "inner solver iterations over all bolt trials"),
    "converged": ("1", "1 if the contact solve converged to an admissible solution"),
    "kkt_residual": ("1", "relative residual of the discrete KKT conditions"),
    "solve_seconds": ("s", "wall-clock seconds from case to dataset"),
}


@dataclass(frozen=True)
class CaseResult:
    """Everything ``to_dataset`` needs, in SI units, per body or per interface node."""

    spec: CaseSpec
    mesh: TunnelMesh
    u_ground: np.ndarray   # (2, Ng) m
    u_lining: np.ndarray   # (2, Nl) m
    stress_ground: np.ndarray  # (4, Eg) Pa: xx, yy, xy, zz
    stress_lining: np.ndarray  # (4, El) Pa
    lam: np.ndarray        # (m,) Pa
    normal_jump: np.ndarray  # (m,) m
    gap: np.ndarray        # (m,) m
    in_contact: np.ndarray  # (m,) bool
    thrust: np.ndarray
    moment: np.ndarray
    shear: np.ndarray
    scalars: dict
    attrs: dict


def _var(dims, data, units, long_name, **attrs):
    return xr.Variable(dims, data, {"units": units, "long_name": long_name, **attrs})


def to_dataset(res: CaseResult, *, software_version: str) -> xr.Dataset:
    """Build the SPEC §3 dataset; interface nodes appear once per body in ``node``."""
    mg, ml, iface = res.mesh.ground, res.mesh.lining, res.mesh.interface
    ng = mg.p.shape[1]
    node_xy = np.concatenate([mg.p, ml.p], axis=1)
    faces = np.concatenate([mg.t, ml.t + ng], axis=1).T.astype(np.int32)
    body = np.r_[np.zeros(mg.t.shape[1], np.int8), np.ones(ml.t.shape[1], np.int8)]
    u = np.concatenate([res.u_ground, res.u_lining], axis=1)
    stress = np.concatenate([res.stress_ground, res.stress_lining], axis=1)
    on_node = {"mesh": "mesh", "location": "node"}
    on_face = {"mesh": "mesh", "location": "face"}

    coords = {
        "node_x": _var("node", node_xy[0], "m", "x of mesh node", standard_name="projection_x_coordinate"),
        "node_y": _var("node", node_xy[1], "m", "y of mesh node", standard_name="projection_y_coordinate"),
        "theta": _var("interface", iface.theta, "degree", "interface position at the tunnel axis from the crown"),
        "interface_x": _var("interface", node_xy[0, iface.ground_node], "m", "x of interface node"),
        "interface_y": _var("interface", node_xy[1, iface.ground_node], "m", "y of interface node"),
    }
    data = {
        "mesh": _var((), np.int32(0), "1", "mesh topology", cf_role="mesh_topology", topology_dimension=np.int32(2),
                     node_coordinates="node_x node_y", face_node_connectivity="face_nodes",
                     face_dimension="face"),
        "face_nodes": _var(("face", "max_face_nodes"), faces, "1", "vertex nodes of each triangle",
                           cf_role="face_node_connectivity", start_index=np.int32(0)),
        "body": _var("face", body, "1", "body of the face (0 ground, 1 lining)", **on_face,
                     flag_values=np.array([0, 1], np.int8), flag_meanings="ground lining"),
        "displacement_x": _var("node", u[0], "m", "horizontal displacement", **on_node),
        "displacement_y": _var("node", u[1], "m", "vertical displacement", **on_node),
        "stress_xx": _var("face", stress[0], "Pa", "normal stress xx (tension positive)", **on_face),
        "stress_yy": _var("face", stress[1], "Pa", "normal stress yy (tension positive)", **on_face),
        "stress_xy": _var("face", stress[2], "Pa", "shear stress xy", **on_face),
        "stress_zz": _var("face", stress[3], "Pa", "out-of-plane normal stress zz (plane strain)", **on_face),
        "normal_x": _var("interface", iface.normal[0], "1", "x of the ground's outward normal"),
        "normal_y": _var("interface", iface.normal[1], "1", "y of the ground's outward normal"),
        "weight": _var("interface", iface.weight, "m", "trapezoid quadrature weight of the interface node"),
        "ground_node": _var("interface", iface.ground_node.astype(np.int32), "1", "ground copy of the interface node (index into node)"),
        "lining_node": _var("interface", (iface.lining_node + ng).astype(np.int32), "1", "lining copy of the interface node (index into node)"),
        "contact_pressure": _var("interface", res.lam, "Pa", "contact pressure"),
        "normal_jump": _var("interface", res.normal_jump, "m", "normal displacement jump [u]nu"),
        "gap": _var("interface", res.gap, "m", "remaining gap g0 - [u]nu"),
        "in_contact": _var("interface", res.in_contact.astype(np.int8), "1", "1 where the interface is closed"),
        "thrust": _var("interface", res.thrust, "N m-1", "lining thrust (compression positive)"),
        "moment": _var("interface", res.moment, "N m m-1", "lining bending moment (positive: inner fibre in compression)"),
        "shear": _var("interface", res.shear, "N m-1", "lining shear force (outward force of the invert side on the crown side)"),
    }
    for name, (units, long_name) in SCALARS.items():
        data[name] = _var((), res.scalars[name], units, long_name)
    ds = xr.Dataset(data, coords=coords)
    now = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    ds.attrs = {
        "Conventions": "CF-1.10 UGRID-1.0",
        "title": "tunnel-contact result",
        "case_id": res.spec.case_id,
        "case_spec": res.spec.canonical_json(),
        "software_version": software_version,
        "history": f"{now}: solved by tunnel-contact {software_version} (bolt-point method, "
                   f"inner solver {res.spec.solver.inner})",
        **{k: (json.dumps(v) if isinstance(v, (list, dict)) else v) for k, v in res.attrs.items()},
    }
    return ds
