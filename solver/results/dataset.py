"""A solved case as an xarray Dataset (SPEC §3): UGRID-1.0 mesh, fields, interface, scalars.

:func:`to_dataset` is the one function that turns a :class:`~solver.model.Solution` into
the result. The quadratic triangles are written as their corner triangulation: each
6-node triangle becomes four 3-node faces over the same nodes (vertices and edge
nodes), so every node carries its exact displacement and each face its stress at the
sub-triangle's centroid.

A segmental lining (SPEC §1.6) adds its joints on dim ``joint`` (:data:`JOINT_VARIABLES`, with
``joint_eccentricity`` = |M|/(N a/2) beside the contract's), their maxima as scalars (0 for a
monolithic lining, so they stack across cases), and leaves ``utilization`` NaN at the joints'
stations: the section there is the joint's contact strip, whose checks are ``joint_eccentricity``
≤ 1 (the thrust inside the strip) and ``joint_utilization`` ≤ 1 (EN 1992-1-1 (12.10) on the strip,
:func:`solver.lining.design.joint_utilization`), so ``max_utilization`` is the section's away from the
joints.
"""
from __future__ import annotations

import json
import logging
import time
from datetime import datetime, timezone

import numpy as np
import xarray as xr

from ..fe.assembly import SUBTRIANGLES, stress_at
from ..ground.loads import in_situ_stress, moduli
from ..ground.strata import moved_lines, strata
from ..ground.water import hydrostatic, phreatic_sampler
from .variables import JOINT_UTILIZATION, JOINT_VARIABLES, SCALARS
from .settlement import TROUGH_WIDTH_FACTOR, design_trough, gaussian_trough, ground_loss, surface_warnings
from ..lining.checks import crack_width, shear_utilization
from ..lining.design import design_utilization, governing_thrust, joint_utilization
from ..model import Solution, TunnelModel
from ..spec.plausible import plausibility_warnings
from ..lining.forces import lining_forces
from ..geometry.profile_mesh import extrados_arc_length
from .installation import installation_attrs, installation_scalars
from .post import contact_extent, mean_convergence, surface_trough

log = logging.getLogger(__name__)

#: Largest displacement, as a fraction of the excavation radius, inside the small-displacement model.
SMALL_DISPLACEMENT_LIMIT = 0.02

def _var(dims, data, units, long_name, **attrs):
    return xr.Variable(dims, data, {"units": units, "long_name": long_name, **attrs})


def _faces(t: np.ndarray) -> np.ndarray:
    """(4E, 3) corner sub-triangles of (6, E) quadratic triangles, element-major."""
    return np.transpose(t[SUBTRIANGLES], (2, 0, 1)).reshape(-1, 3)


def _lining_stress(model: TunnelModel, spec, u_nodes: np.ndarray) -> np.ndarray:
    """(4, 4E) stress in the lining at the sub-triangle centroids."""
    basis = model.point_basis("lining")
    return stress_at(model.lining.body, spec.lining.young, spec.lining.poisson, u_nodes, basis.dx.shape,
                     model.point_gradient("lining")).reshape(4, -1)


def _ground_state(model: TunnelModel, sol: Solution) -> dict:
    """The ground at the sub-triangle centroids (each (…, 4E)): ``effective`` and ``total``
    stress (4 components; the in-situ state plus the increment, since the stress-free start for
    ``wished-in-place``) and the ``pore`` pressure after stage 2 (Pa, compression positive)."""
    spec = sol.spec
    basis = model.point_basis("ground")
    y = model.built(("point y", "ground"), lambda: np.asarray(basis.global_coordinates())[1])  # (E, 4)
    young, poisson = moduli(strata(spec), model.band, y)  # the case's moduli
    if sol.plastic is not None:  # the return-mapped history at these points, not Hooke's law
        effective = sol.plastic["stress"].reshape((4,) + y.shape)
    else:
        effective = stress_at(model.ground.body, young, poisson, sol.u_ground, y.shape,
                              model.point_gradient("ground"))  # (4, E, 4)
    if spec.excavation.method == "deconfinement" and sol.plastic is None:
        effective = effective + in_situ_stress(spec, strata(spec), model.band, y)["effective"]
    if spec.water.table is None:
        pore, total = np.zeros_like(y), effective
    else:
        if spec.drained:  # the seepage's P2 field (clipped: its interpolant may dip below 0 near the wall)
            from skfem import Basis, ElementTriP2

            scalar = model.built(("scalar P2 basis", "ground"),
                                 lambda: Basis(basis.mesh, ElementTriP2(), quadrature=basis.quadrature))
            pore = np.maximum(np.asarray(scalar.interpolate(sol.pore)), 0.0)
        else:  # hydrostatic, exact at the points
            pore = hydrostatic(y, spec.water.table, spec.water.unit_weight)
        total = effective - np.stack([pore, pore, np.zeros_like(pore), pore])
    return {"effective": effective.reshape(4, -1), "total": total.reshape(4, -1), "pore": pore.reshape(-1)}


def _plastic_scalars(sol: Solution, node_xy: np.ndarray, ground_faces: np.ndarray, center) -> dict:
    """``plastic_area`` (m², both halves) and ``max_plastic_extent`` (m from the tunnel axis) of
    the final state, and ``stage1_…`` of the state before the lining was placed."""
    out = {}
    for prefix, key in (("", "at_yield"), ("stage1_", "stage1_at_yield")):
        on = None if sol.plastic is None else sol.plastic.get(key)
        if on is None or not on.any():
            out.update({f"{prefix}plastic_area": 0.0, f"{prefix}max_plastic_extent": 0.0})
            continue
        xy = node_xy[:, ground_faces[on]]  # (2, F, 3)
        e1, e2 = xy[:, :, 1] - xy[:, :, 0], xy[:, :, 2] - xy[:, :, 0]
        area = 0.5 * np.abs(e1[0] * e2[1] - e1[1] * e2[0])
        reach = np.hypot(xy[0] - center[0], xy[1] - center[1]).mean(axis=1)
        out.update({f"{prefix}plastic_area": float(2.0 * area.sum()), f"{prefix}max_plastic_extent": float(reach.max())})
    return out


def volume_loss(x: np.ndarray, settlement: np.ndarray, hole_radius: float) -> float:
    """Area of the settlement trough over the excavated area (half model: both halves).

    The trough is where the surface settles: the heave that an elastic ground shows far
    from a shallow tunnel (the base rebounds when the tunnel's weight is removed) is not
    part of it, as it is not in a measured trough. The settling part is integrated
    exactly for the piecewise-linear interpolant, zero crossings included.
    """
    s0, s1 = settlement[:-1], settlement[1:]
    dx = np.diff(x)
    both = (s0 >= 0) & (s1 >= 0)
    cross = (s0 > 0) != (s1 > 0)
    area = np.sum(np.where(both, 0.5 * (s0 + s1) * dx, 0.0))
    pos = np.maximum(s0, s1)
    frac = np.divide(pos, np.abs(s1 - s0), out=np.zeros_like(pos), where=cross & (s1 != s0))
    area += np.sum(np.where(cross & ~both, 0.5 * pos * frac * dx, 0.0))
    return float(area / (0.5 * np.pi * hole_radius**2))


def joint_stations(theta: np.ndarray, joint_theta: np.ndarray) -> np.ndarray:
    """Indices of the interface stations at the joints (the station nearest each joint's θ,
    deg; the mesh puts a station on every joint)."""
    return np.abs(np.asarray(theta)[None, :] - np.asarray(joint_theta)[:, None]).argmin(axis=1)


def _joint_results(sol: Solution) -> tuple[dict, dict, dict]:
    """``(coords, data, scalars)`` of a segmental lining's joints (SPEC §3: dim ``joint``, crown to
    invert); no coordinates or variables and zero maxima for a monolithic lining."""
    joints = sol.joints
    if joints is None:
        return {}, {}, {"max_joint_opening": 0.0, "max_joint_rotation": 0.0, "max_joint_eccentricity": 0.0,
                        "max_joint_utilization": 0.0}
    ratio = joints.eccentricity_ratio
    eta = joint_utilization(joints.thrust, joints.moment, joints.contact_height, sol.spec.design)
    values = {"joint_thrust": joints.thrust, "joint_moment": joints.moment, "joint_opening": joints.opening,
              "joint_rotation": joints.rotation, "joint_open": joints.open.astype(np.int8),
              "joint_eccentricity": ratio, "joint_utilization": eta}
    data = {name: _var("joint", values[name], *JOINT_VARIABLES[name]) for name in JOINT_VARIABLES}
    data["joint_open"].attrs.update(flag_values=np.array([0, 1], np.int8), flag_meanings="closed open")
    data["joint_eccentricity"].attrs["contact_height_m"] = float(joints.contact_height)
    coords = {"joint_theta": _var("joint", joints.theta, "degree", "joint position at the tunnel axis from the crown")}
    scalars = {"max_joint_opening": float(np.max(joints.opening, initial=0.0)),
               "max_joint_rotation": float(np.max(np.abs(joints.rotation), initial=0.0)),
               "max_joint_eccentricity": float(np.max(ratio, initial=0.0)),
               "max_joint_utilization": float(np.max(eta, initial=0.0))}
    return coords, data, scalars


def _plain(value):
    """``value`` with numpy scalars and arrays as Python numbers and lists (for JSON)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    return value.item() if isinstance(value, np.generic) else value


def _convergence(u: np.ndarray, iface, nodes: np.ndarray, theta: float) -> float:
    """Inward radial displacement (m) of the ground wall at the station nearest ``theta`` deg."""
    i = int(np.argmin(np.abs(iface.theta - theta)))
    return float(np.sum(u[:, nodes[i]] * iface.normal[:, i]))


def _mesh_variables(model: TunnelModel, sol: Solution) -> tuple[dict, dict, dict]:
    """``(coords, data, geometry)`` on the UGRID mesh of both bodies: displacements, stresses,
    pore pressure, layers and yield on nodes and sub-triangle faces; ``geometry`` holds the node
    coordinates, the ground's faces and the displacement for the scalars and warnings."""
    spec = sol.spec
    mg, ml = model.mesh.ground, model.mesh.lining
    ng = mg.p.shape[1]
    node_xy = np.concatenate([mg.p, ml.p], axis=1)
    faces = np.concatenate([_faces(mg.t), _faces(ml.t) + ng]).astype(np.int32)
    n_fg = 4 * mg.t.shape[1]
    n_fl = faces.shape[0] - n_fg
    body = np.r_[np.zeros(n_fg, np.int8), np.ones(n_fl, np.int8)]
    u = np.concatenate([sol.u_ground, sol.u_lining], axis=1)
    u1 = np.concatenate([sol.u_stage1, np.zeros_like(sol.u_lining)], axis=1)
    state = _ground_state(model, sol)
    lining_stress = _lining_stress(model, spec, sol.u_lining)
    stress = np.concatenate([state["total"], lining_stress], axis=1)
    effective = np.concatenate([state["effective"], lining_stress], axis=1)
    pore = np.r_[state["pore"], np.zeros(n_fl)]
    layer = np.r_[np.repeat(model.band, 4), np.full(n_fl, -1)].astype(np.int16)
    stage1 = np.zeros(n_fg, np.int8)
    if sol.plastic is not None:
        plastic, eqps = sol.plastic["at_yield"].astype(np.int8), sol.plastic["eqps"]
        stage1 = sol.plastic["stage1_at_yield"].astype(np.int8)
    else:
        plastic, eqps = np.zeros(n_fg, np.int8), np.zeros(n_fg)
    on_node = {"mesh": "mesh", "location": "node"}
    on_face = {"mesh": "mesh", "location": "face"}
    since = _since(spec)
    coords = {
        "node_x": _var("node", node_xy[0], "m", "x of mesh node", standard_name="projection_x_coordinate"),
        "node_y": _var("node", node_xy[1], "m", "y of mesh node", standard_name="projection_y_coordinate"),
    }
    data = {
        "mesh": xr.Variable((), np.int32(0), {
            "cf_role": "mesh_topology", "long_name": "mesh topology", "topology_dimension": np.int32(2),
            "node_coordinates": "node_x node_y", "face_node_connectivity": "face_nodes", "face_dimension": "face"}),
        "face_nodes": _var(("face", "max_face_nodes"), faces, "1", "vertex nodes of each triangle",
                           cf_role="face_node_connectivity", start_index=np.int32(0)),
        "body": _var("face", body, "1", "body of the face (0 ground, 1 lining)", **on_face,
                     flag_values=np.array([0, 1], np.int8), flag_meanings="ground lining"),
        "displacement_x": _var("node", u[0], "m", f"horizontal displacement (ground {since}, lining since placement)", **on_node),
        "displacement_y": _var("node", u[1], "m", f"vertical displacement (ground {since}, lining since placement)", **on_node),
        "stage1_displacement_x": _var("node", u1[0], "m", "horizontal ground displacement of stage 1 (excavation, before the lining)", **on_node),
        "stage1_displacement_y": _var("node", u1[1], "m", "vertical ground displacement of stage 1 (excavation, before the lining)", **on_node),
        "stress_xx": _var("face", stress[0], "Pa", "normal stress xx (tension positive)", **on_face),
        "stress_yy": _var("face", stress[1], "Pa", "normal stress yy (tension positive)", **on_face),
        "stress_xy": _var("face", stress[2], "Pa", "shear stress xy", **on_face),
        "stress_zz": _var("face", stress[3], "Pa", "out-of-plane normal stress zz (plane strain)", **on_face),
        "pore_pressure": _var("face", pore, "Pa", "pore pressure after stage 2 (compression positive; 0 in the lining)", **on_face),
        "effective_stress_xx": _var("face", effective[0], "Pa", "effective normal stress xx (tension positive)", **on_face),
        "effective_stress_yy": _var("face", effective[1], "Pa", "effective normal stress yy (tension positive)", **on_face),
        "effective_stress_xy": _var("face", effective[2], "Pa", "effective shear stress xy", **on_face),
        "effective_stress_zz": _var("face", effective[3], "Pa", "effective out-of-plane normal stress zz", **on_face),
        "layer": _var("face", layer, "1", "index of the ground layer of the face (into ground.layers; -1 in the lining)", **on_face),
        "plastic": _var("face", np.r_[plastic, np.zeros(n_fl, np.int8)], "1", "1 where the ground is at yield at the end", **on_face),
        "stage1_plastic": _var("face", np.r_[stage1, np.zeros(n_fl, np.int8)], "1",
                               "1 where the ground was at yield at the end of stage 1 (before the lining)", **on_face),
        "equivalent_plastic_strain": _var("face", np.r_[eqps, np.zeros(n_fl)], "1",
                                          "accumulated equivalent plastic strain sqrt(2/3 dep:dep)", **on_face),
    }
    return coords, data, {"node_xy": node_xy, "ground_faces": faces[:n_fg], "u": u}


def _since(spec) -> str:
    return "since excavation" if spec.excavation.method == "deconfinement" else "since the stress-free start"


def _interface_variables(model: TunnelModel, sol: Solution) -> tuple[dict, dict]:
    """``(coords, data)`` of the interface stations: geometry, water, contact state."""
    iface, ng = model.mesh.interface, model.mesh.ground.p.shape[1]
    p_ground = model.mesh.ground.p
    coords = {
        "theta": _var("interface", iface.theta, "degree", "interface position at the tunnel axis from the crown"),
        "interface_x": _var("interface", p_ground[0, iface.ground_node], "m", "x of interface node"),
        "interface_y": _var("interface", p_ground[1, iface.ground_node], "m", "y of interface node"),
        "arc_length": _var("interface", extrados_arc_length(model.mesh, sol.spec), "m",
                           "length along the lining's extrados from the crown"),
    }
    data = {
        "water_pressure": _var("interface", sol.water_pressure, "Pa", "water pressure on the lining's extrados (0 when dry or drained)"),
        "normal_x": _var("interface", iface.normal[0], "1", "x of the ground's outward normal"),
        "normal_y": _var("interface", iface.normal[1], "1", "y of the ground's outward normal"),
        "weight": _var("interface", iface.weight, "m", "quadrature weight of the interface node (Simpson's rule per quadratic edge)"),
        "ground_node": _var("interface", iface.ground_node.astype(np.int32), "1", "ground copy of the interface node (index into node)"),
        "lining_node": _var("interface", (iface.lining_node + ng).astype(np.int32), "1", "lining copy of the interface node (index into node)"),
        "contact_pressure": _var("interface", sol.lam, "Pa", "contact pressure"),
        "normal_jump": _var("interface", sol.normal_jump, "m", "normal displacement jump [u]nu"),
        "gap": _var("interface", sol.gap, "m", "remaining gap g0 - [u]nu"),
        "in_contact": _var("interface", sol.in_contact.astype(np.int8), "1", "1 where the interface is closed"),
        "shear_traction": _var("interface", sol.shear, "Pa", "interface shear traction on the lining (positive towards increasing theta)"),
        "tangential_jump": _var("interface", sol.tangential_jump, "m", "tangential displacement jump [u]tau"),
        "slipping": _var("interface", sol.slipping.astype(np.int8), "1", "1 where the interface slips"),
    }
    return coords, data


def _lining_variables(model: TunnelModel, sol: Solution) -> tuple[dict, dict]:
    """``(data, scalars)`` of the lining's section forces and their EN 1992 check."""
    spec, iface = sol.spec, model.mesh.interface
    forces = lining_forces(spec, model.lining.body, iface, model.mesh.center, sol.u_lining, sol.lam, sol.shear,
                           profile=model.mesh.profile)
    h, design = spec.geometry.thickness, spec.design
    eta, env_n, env_m = design_utilization(forces.thrust, forces.moment, h, design)
    n_ed = governing_thrust(forces.thrust, forces.moment, h, design)
    shear_eta = shear_utilization(forces.thrust, forces.moment, forces.shear, h, design)
    crack = crack_width(forces.thrust, forces.moment, h, design)
    if sol.joints is not None:  # the section at a joint is its contact strip: checked by joint_eccentricity
        for checked in (eta, shear_eta, crack):  # fresh arrays of this case
            checked[joint_stations(iface.theta, sol.joints.theta)] = np.nan
    data = {
        "thrust": _var("interface", forces.thrust, "N m-1", "lining thrust (compression positive)"),
        "moment": _var("interface", forces.moment, "N m m-1", "lining bending moment (positive: inner fibre in compression)"),
        "shear": _var("interface", forces.shear, "N m-1", "lining shear force (outward force of the invert side on the crown side)"),
        "utilization": _var("interface", eta, "1", JOINT_UTILIZATION if sol.joints is not None
                            else "EN 1992-1-1 utilization of the lining section (<= 1 passes)"),
        "design_thrust": _var("interface", n_ed, "N m-1", "design thrust N_Ed of the governing N-M combination "
                              "(gamma_F N, or 1.0 N where a lower thrust is unfavourable)"),
        "shear_utilization": _var("interface", shear_eta, "1", "EN 1992-1-1 shear utilization |gamma_F V| / V_Rd,c "
                                  "(6.2.2 reinforced, 12.6.3 plain; <= 1 passes)"),
        "crack_width": _var("interface", crack, "m", "characteristic crack width w_k (EN 1992-1-1 7.3.4, gamma_F = 1; "
                            "0 uncracked or where the tension bars are compressed, inf where a plain section cracks)",
                            crack_width_limit=float(design.crack_width_limit)),
        "capacity_thrust": _var("envelope", env_n, "N m-1", "design N-M resistance envelope: thrust (compression positive)"),
        "capacity_moment": _var("envelope", env_m, "N m m-1", "design N-M resistance envelope: moment"),
    }
    scalars = {"max_thrust": float(forces.thrust.max()), "max_abs_moment": float(np.abs(forces.moment).max()),
               "max_utilization": float(np.nanmax(eta)), "max_shear_utilization": float(np.nanmax(shear_eta)),
               "max_crack_width": float(np.nanmax(crack))}
    return data, scalars


def _surface_variables(model: TunnelModel, sol: Solution) -> tuple[dict, dict, dict, tuple]:
    """``(coords, data, scalars, (x, settlement))`` of the ground surface: the FE trough and the
    Gaussian trough holding the ground loss."""
    g, iface = sol.spec.geometry, model.mesh.interface
    surf_x, settlement = surface_trough(model.mesh.ground.p, sol.u_ground, scale=max(g.width, g.height))
    loss = ground_loss(sol.u_ground, iface.ground_node, iface.normal, iface.weight, g.hole_radius)
    trough, trough_max = gaussian_trough(surf_x, loss, g.hole_radius, g.depth)
    design = design_trough(surf_x, loss, g.hole_radius, g.depth, sol.spec.settlement)
    coords = {"surface_x": _var("surface", surf_x, "m", "x of ground surface node")}
    data = {
        "surface_settlement": _var("surface", settlement, "m", f"FE ground surface settlement (downward positive, "
                                   f"{_since(sol.spec)}; depends on the model's size, see gaussian_settlement)"),
        "gaussian_settlement": _var("surface", trough, "m", "Gaussian settlement trough holding the ground loss "
                                    "(Peck; O'Reilly and New), downward positive",
                                    trough_width_factor=TROUGH_WIDTH_FACTOR),
        # no attribute of a case's own values (its volume loss, its K): cases of a study share the
        # variables' attributes, so the index stacks them in one block (design_volume_loss is a scalar)
        "design_settlement": _var("surface", design["settlement"], "m", "design settlement trough (Gaussian, "
                                  "design_volume_loss and settlement.trough_width_factor), downward positive"),
    }
    phreatic = phreatic_surface(model, sol, surf_x)
    data["phreatic_depth"] = _var("surface", phreatic, "m", "depth of the phreatic surface below the ground surface "
                                  "(the water table, or where a drained lining's seepage lowered it; NaN: dry to the "
                                  "bottom)")
    scalars = {
        "phreatic_drawdown": float(phreatic[0] - sol.spec.water.table) if sol.spec.water.table is not None
        else 0.0,  # dry ground: nothing drawn down (absent scalars are 0, as the joints' of a monolithic ring)
        "max_surface_settlement": float(settlement.max()),
        "volume_loss": volume_loss(surf_x, settlement, g.hole_radius),
        "ground_loss": loss,
        "gaussian_max_settlement": trough_max,
        "design_volume_loss": design["volume_loss"],
        "design_max_settlement": design["max_settlement"],
        "max_slope": design["max_slope"],
        "max_horizontal_strain": design["max_horizontal_strain"],
        "axis_settlement": float(settlement[0]),
        "max_surface_heave": float(max(-settlement.min(), 0.0)),
    }
    return coords, data, scalars, (surf_x, settlement)


def phreatic_surface(model: TunnelModel, sol: Solution, x: np.ndarray) -> np.ndarray:
    """Depth (m) of the phreatic surface above each surface ``x``: the table (hydrostatic), the
    drained seepage's (:func:`solver.ground.water.phreatic_sampler`, once per model), NaN in dry ground."""
    spec = sol.spec
    if spec.water.table is None:
        return np.full(x.size, np.nan)
    if sol.water_head is None:
        return np.full(x.size, float(spec.water.table))
    g = spec.geometry  # the model's (height, radius and mesh size are part of its key): x alone varies
    sampler = model.built(("phreatic", np.asarray(x, float).tobytes()),
                          lambda: phreatic_sampler(model.mesh.ground, x, height=g.height, center=model.mesh.center,
                                                   radius=g.hole_radius, step=0.5 * spec.mesh.interface_size))
    return sampler.depth(sol.water_head)


def _contact_scalars(model: TunnelModel, sol: Solution) -> dict:
    iface = model.mesh.interface
    return {
        "max_contact_pressure": float(sol.lam.max()),
        "contact_extent": contact_extent(iface.theta, sol.in_contact),
        "crown_settlement": float(-sol.u_lining[1, iface.lining_node[0]]),
        "lining_weight": float(sol.lining_weight),
        "bolt_theta": float(iface.theta[sol.bolt]) if sol.bolt is not None else np.nan,
        "bolt_trials": np.int32(len(sol.trials)),
        "iterations": np.int32(sol.iterations),
        "converged": np.int8(sol.admissible),
        "kkt_residual": sol.kkt_residual,
        "solve_seconds": 0.0,
        "ground_crown_settlement": float(-sol.u_ground[1, iface.ground_node[0]]),
        "water_inflow": float(sol.water_inflow),
    }


def _warnings(model: TunnelModel, sol: Solution, u: np.ndarray, surface: tuple) -> list[str]:
    """What the reader of this result must know: moved layer lines, a heaving surface, large
    displacements, an inadmissible bolt."""
    spec, g, iface = sol.spec, sol.spec.geometry, model.mesh.interface
    warnings = [f"the line between layers {i - 1} and {i} ({z:.4g} m deep) is drawn at {drawn:.4g} m: it met the "
                "tunnel's crown or invert level, where the mesh cannot follow a line tangent to the excavation"
                for i, z, drawn in moved_lines(spec)]
    warnings += surface_warnings(*surface) + plausibility_warnings(spec)
    largest = float(np.max(np.hypot(u[0], u[1])))
    if largest > SMALL_DISPLACEMENT_LIMIT * g.hole_radius:
        warnings.append(
            f"largest displacement {largest:.4g} m exceeds {SMALL_DISPLACEMENT_LIMIT:.0%} of the excavation "
            f"radius ({g.hole_radius:.4g} m): outside the small-displacement model")
    retried = sol.plastic.get("retried") if sol.plastic is not None else None
    if retried is not None:
        warnings.append(f"solver.plastic_tolerance: the yielding ground did not converge at the asked "
                        f"{spec.solver.plastic_tolerance:g} and was solved at {retried[0]:g}, a stricter stop test "
                        f"(at {spec.solver.plastic_tolerance:g}: {retried[1]})")
    if not sol.admissible:
        where = f"bolt at theta={iface.theta[sol.bolt]:.2f} deg" if sol.bolt is not None else "the bolt set"
        warnings.append(f"{where} has a negative reaction: not a contact solution")
    for w in warnings:
        log.warning("case %s: %s", spec.case_id, w)
    return warnings


def _stage_attrs(model: TunnelModel, sol: Solution) -> dict:
    """A staged excavation's λd, ground reaction curve and wall convergences (attributes)."""
    spec, iface = sol.spec, model.mesh.interface
    if spec.excavation.method != "deconfinement":
        return {}
    gn = iface.ground_node
    # the wall's mean convergence against the share of the excavation load released, over
    # stage 1 (the unsupported ground): each increment of a yielding ground, else the one
    # straight segment an elastic ground follows
    curve = (sol.plastic["ground_reaction"] if sol.plastic is not None
             else [(spec.excavation.deconfinement, mean_convergence(sol.u_stage1, iface))])
    where = {"crown": 0.0, "springline": 90.0, "invert": 180.0}
    return {
        "deconfinement": spec.excavation.deconfinement,
        "ground_reaction_curve": [{"released": f, "wall_convergence_m": c} for f, c in curve],
        "stage1_convergence_m": {k: _convergence(sol.u_stage1, iface, gn, th) for k, th in where.items()},
        "final_convergence_m": {k: _convergence(sol.u_ground, iface, gn, th) for k, th in where.items()},
    }


def _attrs(model: TunnelModel, sol: Solution, warnings: list[str], software_version: str) -> dict:
    """The dataset's global attributes (lists and dicts as JSON)."""
    spec = sol.spec
    attrs = {
        "bolt_search": [_plain(vars(t)) for t in sol.trials],
        "timings_seconds": {**model.timings, **sol.timings},
        # a segmental lining: the amplitudes of its segments' rigid modes (``lining_modes``)
        "lining_translation_m": float(sol.a) if np.ndim(sol.a) == 0 else _plain(sol.a),
        "interface_model": spec.interface.model,
        "excavation_method": spec.excavation.method,
        **({"plastic_iterations": int(sol.plastic["iterations"])} if sol.plastic is not None else {}),
        "water_uplift_N_per_m": float(sol.water_uplift),
        "warnings": warnings,
    }
    if sol.joints is not None:
        attrs["lining_modes"] = list(model.modes.label)
        attrs["joint_contact_height_m"] = float(sol.joints.contact_height)
    attrs.update(_stage_attrs(model, sol))
    attrs.update(installation_attrs(sol))
    now = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    return {
        "Conventions": "CF-1.10 UGRID-1.0",
        "title": "tunnel-contact result",
        "case_id": spec.case_id,
        "case_spec": spec.canonical_json(),
        **({"case_name": spec.name} if spec.name is not None else {}),
        "software_version": software_version,
        "history": f"{now}: solved by tunnel-contact {software_version} (P2 elements, "
                   f"{spec.excavation.method}, {spec.interface.model} interface, inner solver {spec.solver.inner})",
        **{k: (json.dumps(v) if isinstance(v, (list, dict)) else v) for k, v in attrs.items()},
    }


def to_dataset(model: TunnelModel, sol: Solution, *, software_version: str, started: float | None = None) -> xr.Dataset:
    """Build the SPEC §3 dataset of a solved case; interface nodes appear once per body in ``node``."""
    mesh_coords, mesh_data, geo = _mesh_variables(model, sol)
    iface_coords, iface_data = _interface_variables(model, sol)
    lining_data, lining_scalars = _lining_variables(model, sol)
    surf_coords, surf_data, surf_scalars, surface = _surface_variables(model, sol)
    joint_coords, joint_data, joint_scalars = _joint_results(sol)
    scalars = {**_contact_scalars(model, sol), **lining_scalars, **surf_scalars, **installation_scalars(sol),
               **_plastic_scalars(sol, geo["node_xy"], geo["ground_faces"], model.mesh.center), **joint_scalars}
    coords = {**mesh_coords, **iface_coords, **surf_coords, **joint_coords}
    data = {**mesh_data, **iface_data, **lining_data, **surf_data, **joint_data}
    for name, (units, long_name) in SCALARS.items():
        data[name] = _var((), scalars[name], units, long_name)
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = _attrs(model, sol, _warnings(model, sol, geo["u"], surface), software_version)
    if started is not None:
        ds["solve_seconds"].values = np.float64(time.perf_counter() - started)
    return ds
