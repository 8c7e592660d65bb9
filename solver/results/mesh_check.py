"""The mesh check of a case (SPEC §9.2, ``solver.mesh_check``): the key results on a mesh refined
once against the case's own."""
from __future__ import annotations

import json

import numpy as np
import xarray as xr

from ..spec import CaseSpec

#: The results compared, and the relative change above which the result carries a warning.
CHECKED = ("max_abs_moment", "max_thrust", "max_contact_pressure", "max_utilization", "ground_loss")
MESH_CHANGE_LIMIT = 0.01


def refined(spec: CaseSpec) -> CaseSpec:
    """``spec`` on a mesh refined once: every size halved (the interface and far sizes, and with
    them the lining's layers and the refinements towards the joints), without a mesh check."""
    m = spec.mesh
    return spec.model_copy(update={
        "mesh": m.model_copy(update={"interface_size": 0.5 * m.interface_size, "far_size": 0.5 * m.far_size}),
        "solver": spec.solver.model_copy(update={"mesh_check": False})})


def mesh_changes(default: xr.Dataset, fine: xr.Dataset) -> dict[str, float]:
    """``(refined − default)/|refined|`` of each :data:`CHECKED` result (0 where both are 0)."""
    out = {}
    for name in CHECKED:
        a, b = float(default[name]), float(fine[name])
        out[name] = 0.0 if a == b else (b - a) / abs(b) if b != 0 else np.inf
    return out


def add_mesh_check(ds: xr.Dataset, changes: dict[str, float]) -> xr.Dataset:
    """``ds`` with the ``mesh_change_<name>`` scalars and a warning per change above
    :data:`MESH_CHANGE_LIMIT`."""
    for name, change in changes.items():
        ds[f"mesh_change_{name}"] = xr.Variable((), change, attrs={
            "units": "1", "long_name": f"relative change of {name} on a mesh refined once (every size halved): "
                                       "(refined - default)/|refined|"})
    warnings = [f"{name} changes by {change:+.2%} on a mesh refined once (every size halved): the default mesh "
                f"does not resolve it to {MESH_CHANGE_LIMIT:.0%}; use a smaller mesh.interface_size"
                for name, change in changes.items() if abs(change) > MESH_CHANGE_LIMIT]
    if warnings:
        old = ds.attrs.get("warnings", "[]")
        listed = json.loads(old) if isinstance(old, str) else list(old)
        ds.attrs["warnings"] = json.dumps(listed + warnings)
    return ds
