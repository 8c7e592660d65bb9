"""The contact stage recovered from its tractions: both bodies' displacements by one backward
solve each, the interface's state, the checks every answer passes (the discrete KKT
conditions, the balance of the lining's modes) and the water state of the result."""
from __future__ import annotations

import time
import numpy as np

from ..build import BuiltModel
from ..contact.bolt import pressure_scale
from ..contact.kkt import kkt_residual
from ..fe.flexibility import Rows
from ..ground import water
from ..lining import joints
from ..spec import CaseSpec
from .contact import contact_tractions
from .loads import lining_weight, seepage
from .state import CONTACT_GAP_TOL, Forward, Solution, StageLoads


def _displacements(model: BuiltModel, rows: Rows, stage: Forward, Wt: np.ndarray, u1: np.ndarray | None):
    """Free-DOF displacements of the contact stage (ground, lining without its rigid motion) and
    of stage 1: ``u1`` if given (the yielding ground's), else ``λd K⁻¹ r`` from the same sweep."""
    ground, lining = model.ground, model.lining
    if u1 is not None:
        u_g = ground.backward(stage.ground, rows, Wt)
    elif stage.release is not None and stage.deconfinement > 0.0:
        # the contact stage and stage 1 (λd r alone) in one backward sweep over the factor
        u = ground.backward(np.column_stack([stage.ground, stage.release]), rows,
                            np.column_stack([Wt, np.zeros_like(Wt)]))
        u_g, u1 = u[:, 0], stage.deconfinement * u[:, 1]
    else:
        u_g = ground.backward(stage.ground, rows, Wt)
        u1 = np.zeros_like(u_g)
    return u_g, lining.backward(stage.lining, rows, Wt), u1


def _balance(model: BuiltModel, F2, Wt: np.ndarray) -> tuple[float, float]:
    """The lining's balance on its rigid modes and its scale (:func:`kkt_residual`)."""
    if model.joint_rows is None:
        return F2 + float(np.sum(model.r * Wt)), abs(F2) + float(np.sum(np.abs(model.r * Wt)))
    # every segment's modes: the worst relative to its own scale
    wrench = F2 + model.G.T @ Wt
    scale = np.maximum(np.abs(F2) + np.abs(model.G).T @ np.abs(Wt), 1e-300)
    return float(np.max(np.abs(wrench) / scale)), 1.0


def finish(model: BuiltModel, spec: CaseSpec, rows: Rows, loads: StageLoads, stage: Forward, d: np.ndarray,
           F2, t0: float, u1: np.ndarray | None = None) -> Solution:
    """The contact stage solved from its forward-solved loads: the contact problem, the
    backward solves, the checks. ``u1`` (free DOFs) is a stage-1 displacement computed
    elsewhere (the yielding ground's), else stage 1 is ``λd K⁻¹ r``."""
    ground, lining = model.ground, model.lining
    iface, m, g0, kind = model.mesh.interface, model.m, spec.geometry.gap, spec.interface.model
    sol, t = contact_tractions(model, spec, d, F2)
    t_solve = time.perf_counter()
    Wt = model.w * t
    u_g, u_l, u1 = _displacements(model, rows, stage, Wt, u1)
    u_l = u_l + model.rigid_motion(sol.a)
    J = ground.B @ u_g + lining.B @ u_l
    lam = t[:m]
    shear = np.zeros(m)
    shear[model.tangential] = t[model.tangential_rows]
    jt = np.zeros(m)
    jt[model.tangential] = J[model.tangential_rows]
    u_lining = lining.body.expand(u_l)
    # scales of the contact stage (the increment contact acts on)
    u_ref = max(float(np.max(np.abs(u_g))), float(np.max(np.abs(u_l))), g0, 1e-300)
    F_vertical = F2 if model.joint_rows is None else float(model.vertical @ loads.lining)
    p_ref = max(float(np.max(np.abs(t))), pressure_scale(F_vertical, iface.normal[1], iface.weight))
    closed = (g0 - J[:m] <= CONTACT_GAP_TOL * u_ref) | (kind == "bonded")
    slipping = closed & (np.abs(jt) > CONTACT_GAP_TOL * u_ref)
    residuals = [(fb.stiffness() @ u + fb.B.T @ Wt - f, np.abs(f) + np.abs(fb.B.T @ Wt))
                 for fb, u, f in ((ground, u_g, loads.ground), (lining, u_l, loads.lining))]
    balance, balance_scale = _balance(model, F2, Wt)
    kkt = kkt_residual(K_u_minus_f=residuals, balance=balance, balance_scale=balance_scale, lam=lam,
                       normal_jump=J[:m], g0=g0, p_ref=p_ref, u_ref=u_ref, model=kind, shear=shear,
                       tangential_jump=jt, mu=spec.interface.friction)
    joint_state = None
    if model.joint_rows is not None:
        jr, nj = model.joint_rows, model.joint_rows.size
        tj, Jj = t[m:m + nj], J[m:m + nj]
        kkt = max(kkt, joints.joint_kkt(jr, tj, Jj, spec.lining.joints, p_ref=p_ref, u_ref=u_ref))
        joint_state = joints.joint_results(
            model.mesh, jr, tj, Jj, u_lining,
            height=spec.lining.joints.contact_height or spec.geometry.thickness, gap_tol=CONTACT_GAP_TOL * u_ref)
    a = float(sol.a) if np.ndim(sol.a) == 0 else np.asarray(sol.a, float)
    return Solution(spec=spec, u_ground=ground.body.expand(u_g + u1), u_stage1=ground.body.expand(u1),
                    u_lining=u_lining, lam=lam, shear=shear, normal_jump=J[:m], tangential_jump=jt,
                    in_contact=closed, slipping=slipping, a=a, bolt=sol.bolt, trials=sol.trials,
                    iterations=int(sol.iterations), admissible=bool(sol.admissible), F2=F_vertical,
                    kkt_residual=kkt,
                    timings={"contact": t_solve - t0, "recovery": time.perf_counter() - t_solve},
                    joints=joint_state, **water_state(model, spec, F_vertical))


def water_state(model: BuiltModel, spec: CaseSpec, F2: float) -> dict:
    """The lining's weight and water uplift (N/m), the ground's pore pressure after stage 2
    at its nodes, the water pressure on the extrados and the inflow (:class:`Solution`)."""
    w = spec.water
    y = model.mesh.ground.p[1]
    out = {"lining_weight": -F2, "water_uplift": 0.0, "pore": water.hydrostatic(y, w.table, w.unit_weight),
           "water_pressure": np.zeros(model.m), "water_inflow": 0.0}
    if w.table is not None and w.lining == "watertight":
        weight = -lining_weight(model, spec.lining.density, spec.loads.gravity)
        out.update(lining_weight=weight, water_uplift=F2 + weight,
                   water_pressure=water.hydrostatic(model.mesh.lining.p[1, model.mesh.interface.lining_node],
                                                    w.table, w.unit_weight))
    elif w.table is not None:
        seep = seepage(model, spec)
        out["pore"], out["water_inflow"], out["water_head"] = seep.pore, seep.inflow, seep.head
    return out
