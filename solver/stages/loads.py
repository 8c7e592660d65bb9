"""The loads of each construction stage (SPEC §1.1, §1.4), from a built model's unit loads.

Every ground load is linear in ρg, q, K0·q and K0·ρg (:data:`~solver.ground.loads.LOAD_TERMS`):
a model assembles those shapes once (:meth:`~solver.model.TunnelModel.shapes`) and a case
combines them with its own coefficients, so a sweep over loads, densities and K0 assembles
nothing. The excavation load is the discrete one, ``r = f_ext - ∫Bᵀσ0`` (zero at every free
node off the excavation boundary); below a water table the water's share is added so that the
effective traction is released.
"""
from __future__ import annotations

import numpy as np

from ..build import BuiltModel
from ..ground import water
from ..ground.loads import load_coefficients as _layer_coefficients
from ..ground.strata import layer_at, strata
from ..spec import CaseSpec
from .state import StageLoads


def load_coefficients(spec: CaseSpec) -> np.ndarray:
    """The case's values of :data:`~solver.ground.loads.LOAD_TERMS`, layer after layer."""
    return _layer_coefficients(spec, strata(spec))


def ground_loads(model: BuiltModel, spec: CaseSpec) -> np.ndarray:
    """Full-DOF external loads on the ground (N/m): gravity, surface load, a 'pressure' side."""
    return model.shapes("wished-in-place") @ load_coefficients(spec)


def excavation_load(model: BuiltModel, spec: CaseSpec) -> np.ndarray:
    """Full-DOF excavation load (N/m): what the in-situ state leaves unbalanced, ``f_ext -
    ∫Bᵀσ0``, and below a water table the water's share, so that the effective traction
    is released (:func:`solver.ground.water.effective_release`)."""
    r = model.shapes("deconfinement") @ load_coefficients(spec)
    if spec.water.table is not None:
        r = r + effective_release(model, spec)
    return r


def effective_release(model: BuiltModel, spec: CaseSpec) -> np.ndarray:
    """The water's share of the excavation load below the table (full DOFs, N/m)."""
    layers, w = strata(spec), spec.water
    k0 = np.array([s.k0 for s in layers])
    body, iface = model.ground.body, model.mesh.interface
    return water.effective_release(body, iface.ground_node, model.mesh.center, w.table, w.unit_weight,
                                   lambda x: k0[layer_at(layers, -x[1])])


def stage_loads(model: BuiltModel, spec: CaseSpec) -> StageLoads:
    """Free-DOF loads of the case's stages: the contact stage's ground and lining loads and the
    whole excavation load (stage 1 releases λd of it, the contact stage the rest)."""
    ground, lining = model.ground.body, model.lining.body
    f_l = lining.restrict(spec.lining.density * spec.loads.gravity * model.lining_shape())
    w = spec.water
    if w.table is not None and w.lining == "watertight":
        f_l = f_l + lining.restrict(water_on_lining(model, w.table, w.unit_weight))
    if spec.excavation.method == "wished-in-place":
        return StageLoads(ground.restrict(ground_loads(model, spec)), f_l, None)
    loads = ground.restrict(excavation_load(model, spec))
    stage2 = (1.0 - spec.excavation.deconfinement) * loads
    seep = None
    if spec.drained:
        seep = ground.restrict(seepage_force(model, spec))
        stage2 = stage2 + seep
    return StageLoads(stage2, f_l, loads, seep)


def water_on_lining(model: BuiltModel, table: float, unit_weight: float) -> np.ndarray:
    """Full-DOF load of the hydrostatic water on the lining's extrados (watertight)."""
    return water.pressure_load(model.lining.body, model.mesh.interface.lining_node, model.mesh.center,
                               table, unit_weight)


def seepage(model: BuiltModel, spec: CaseSpec) -> water.Seepage:
    """Steady seepage of a drained case (:class:`solver.ground.water.SeepageModel`)."""
    k = np.array([s.permeability for s in strata(spec)])
    return model.seepage_model(spec.water.table, k).solve(spec.water.unit_weight)


def seepage_force(model: BuiltModel, spec: CaseSpec) -> np.ndarray:
    """Full-DOF seepage force of a drained case: the excess pore pressure over hydrostatic."""
    k = np.array([s.permeability for s in strata(spec)])
    sm = model.seepage_model(spec.water.table, k)
    seep = sm.solve(spec.water.unit_weight)
    u0 = water.hydrostatic(model.mesh.ground.p[1], spec.water.table, spec.water.unit_weight)
    return water.seepage_load(model.ground.body.basis, sm.basis, seep.pore - u0)


def lining_weight(model: BuiltModel, density: float, gravity: float) -> float:
    """The (half) lining's weight (N/m, positive)."""
    return density * gravity * float(model.vertical @ model.lining.body.restrict(model.lining_shape()))
