"""``run_case``: CaseSpec -> mesh -> assembled system -> contact solve -> Dataset."""
from __future__ import annotations

import logging
import time
from importlib.metadata import PackageNotFoundError, version

import numpy as np
import xarray as xr

from .assembly import assemble_system, element_stress
from .contact import solve_contact
from .dataset import CaseResult, to_dataset
from .flexibility import condense_interface, recover_displacements
from .mesh import build_mesh
from .post import contact_extent, kkt_residual, lining_forces
from .spec import CaseSpec

log = logging.getLogger(__name__)

#: Relative gap (to the largest displacement) below which a node counts as closed.
CONTACT_GAP_TOL = 1e-6

try:
    SOFTWARE_VERSION = version("tunnel-contact")
except PackageNotFoundError:  # pragma: no cover - source tree without install
    SOFTWARE_VERSION = "0+unknown"


def run_case(spec: CaseSpec) -> xr.Dataset:
    """Solve one case (pure: no files, no network). Raises :class:`solver.SolverError`."""
    t0 = time.perf_counter()
    timings = {}
    mesh = build_mesh(spec)
    timings["mesh"] = time.perf_counter() - t0
    system = assemble_system(spec, mesh)
    timings["assembly"] = time.perf_counter() - t0 - timings["mesh"]
    iface = mesh.interface
    t1 = time.perf_counter()
    dual, g, l = condense_interface(system, iface, spec.geometry.gap)
    timings["factorization"] = time.perf_counter() - t1
    sv = spec.solver
    sol = solve_contact(dual, iface.theta, inner=sv.inner, tol=sv.tolerance,
                        max_iterations=sv.max_iterations, bolt=sv.bolt)
    u_g, u_l = recover_displacements(g, l, sol.lam, sol.a, iface.weight)
    timings["contact"] = time.perf_counter() - t1 - timings["factorization"]

    ug, ul = system.ground.expand(u_g), system.lining.expand(u_l)
    nu = iface.normal
    jump = np.sum(ug[:, iface.ground_node] * nu, axis=0) - np.sum(ul[:, iface.lining_node] * nu, axis=0)
    gap = spec.geometry.gap - jump
    force = iface.weight * sol.lam
    u_ref = max(float(np.max(np.abs(np.concatenate([ug, ul], axis=1)))), spec.geometry.gap, 1e-300)
    p_ref = max(float(np.max(np.abs(sol.lam))), dual.pressure_scale)
    residuals = [(body.system.K @ u + body.B.T @ force - body.system.f,
                  np.abs(body.system.f) + np.abs(body.B.T @ force)) for body, u in ((g, u_g), (l, u_l))]
    balance = dual.F2 + float(np.sum(dual.nu2 * force))
    kkt = kkt_residual(K_u_minus_f=residuals, balance=balance, F2=dual.F2, lam=sol.lam, gap=gap,
                       p_ref=p_ref, u_ref=u_ref)
    in_contact = gap <= CONTACT_GAP_TOL * u_ref
    forces = lining_forces(spec, mesh, ul, sol.lam)
    crown = iface.lining_node[0]
    scalars = {
        "max_contact_pressure": float(sol.lam.max()),
        "contact_extent": contact_extent(iface.theta, in_contact),
        "crown_settlement": float(-ul[1, crown]),
        "max_thrust": float(forces.thrust.max()),
        "max_abs_moment": float(np.abs(forces.moment).max()),
        "lining_weight": float(-dual.F2),
        "bolt_theta": float(iface.theta[sol.bolt]),
        "bolt_trials": np.int32(len(sol.trials)),
        "iterations": np.int32(sol.iterations),
        "converged": np.int8(sol.admissible),
        "kkt_residual": kkt,
        "solve_seconds": 0.0,
    }
    attrs = {
        "bolt_search": [vars(t) for t in sol.trials],
        "timings_seconds": timings,
        "lining_translation_m": float(sol.a),
    }
    if not sol.admissible:
        log.warning("bolt at theta=%.2f has a negative reaction %.4g Pa: not a contact solution",
                    iface.theta[sol.bolt], sol.lam[sol.bolt])
    result = CaseResult(
        spec=spec, mesh=mesh, u_ground=ug, u_lining=ul,
        stress_ground=element_stress(mesh.ground, spec.ground, ug),
        stress_lining=element_stress(mesh.lining, spec.lining, ul),
        lam=sol.lam, normal_jump=jump, gap=gap, in_contact=in_contact,
        thrust=forces.thrust, moment=forces.moment, shear=forces.shear,
        scalars=scalars, attrs=attrs)
    ds = to_dataset(result, software_version=SOFTWARE_VERSION)
    ds["solve_seconds"].values = np.float64(time.perf_counter() - t0)
    return ds
