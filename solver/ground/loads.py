"""The ground's stiffness and in-situ loads, layer by layer (SPEC §1.1, §1.4), as plain functions.

The mesh conforms to the layer lines (:func:`solver.geometry.mesh.build_mesh` gives each ground
triangle its band, the index of its :class:`~solver.ground.strata.Stratum`), so within a triangle the
ground is one layer: E may grow linearly with depth (``young_gradient``), ν is constant, and
the geostatic stress is linear in depth. Each layer's in-situ stress is linear in four terms
(:data:`LOAD_TERMS` per layer): ρg of the layer, the vertical stress at its top σv(top), and
these two times the layer's K0. A model assembles the load shapes of those terms once
(:func:`load_shapes`), and any case's ground load is ``shapes @ load_coefficients(case)``: a
sweep over loads, densities or K0 of a fixed geometry assembles nothing. With one layer this
is exactly the homogeneous ground of the first rounds: the same four shapes, the same
coefficients (ρg, q, K0·q, K0·ρg).
"""
from __future__ import annotations

import numpy as np

from ..fe.assembly import (
    gravity_load,
    initial_stress_forces,
    side_pressure_load,
    surface_load,
)
from .strata import Stratum, geostatic_state

#: The terms each layer's ground load is linear in: its ρg (N/m³), the total vertical stress at
#: its top σv(top) (Pa; the surface load q for the first layer), K0·σv(top) and K0·ρg.
LOAD_TERMS = ("rho_g", "q", "k0_q", "k0_rho_g")


def moduli(layers: list[Stratum], band: np.ndarray, y: np.ndarray):
    """Young's modulus (Pa) and Poisson ratio of the ground at points ``y`` (E, P) (m, up
    positive) of triangles in layers ``band`` (E,): scalars for one layer of constant E
    (what the homogeneous ground always was), else (E, P) and (E, 1) arrays."""
    if len(layers) == 1 and layers[0].young_gradient == 0.0:
        return layers[0].young, layers[0].poisson
    young = np.array([s.young for s in layers])[band][:, None]
    gradient = np.array([s.young_gradient for s in layers])[band][:, None]
    top = np.array([s.top for s in layers])[band][:, None]
    poisson = np.array([s.poisson for s in layers])[band][:, None]
    return young + gradient * (-np.asarray(y) - top), poisson


def vertical_at_tops(spec, layers: list[Stratum]) -> np.ndarray:
    """Total vertical stress σv (Pa, compression positive) at each layer's top."""
    return geostatic_state(spec, layers, np.array([s.top for s in layers]),
                           np.arange(len(layers)))["sigma_v"]


def load_coefficients(spec, layers: list[Stratum]) -> np.ndarray:
    """The case's values of :data:`LOAD_TERMS`, layer after layer ((4 L,))."""
    gravity = spec.loads.gravity
    if len(layers) == 1:
        rho_g, q, k0 = layers[0].density * gravity, spec.loads.surface_load, layers[0].k0
        return np.array([rho_g, q, k0 * q, k0 * rho_g])
    top = vertical_at_tops(spec, layers)
    return np.concatenate([[s.density * gravity, top[i], s.k0 * top[i], s.k0 * s.density * gravity]
                           for i, s in enumerate(layers)])


def load_shapes(basis, band: np.ndarray, layers: list[Stratum], *, width: float, height: float,
                side: str, method: str) -> np.ndarray:
    """(N, 4 L) full-DOF ground load per :data:`LOAD_TERMS` term of each layer.

    ``method = "wished-in-place"``: the applied loads (gravity, surface load, a 'pressure'
    side); ``"deconfinement"``: the excavation load ``f_ext - ∫Bᵀσ0``, what the geostatic
    stress σ0 leaves unbalanced on the ground with its hole (zero at every free node off the
    excavation boundary: the layers' σ0 is in equilibrium and the mesh conforms to their lines).
    """
    scale = max(width, height)
    one = len(layers) == 1
    shapes = np.zeros((basis.N, 4 * len(layers)))
    for i, s in enumerate(layers):
        where = None if one else band == i
        top = 0.0 if one else s.top
        cols = shapes[:, 4 * i:4 * i + 4]
        cols[:, 0] = gravity_load(basis, 1.0, 1.0, where)
        if i == 0:
            cols[:, 1] = surface_load(basis, 1.0, scale=scale)
        if side == "pressure":
            depths = None if one else (s.top, s.bottom)
            cols[:, 2] = side_pressure_load(basis, q=1.0, rho_g=0.0, k0=1.0, width=width, scale=scale, depths=depths)
            cols[:, 3] = side_pressure_load(basis, q=0.0, rho_g=1.0, k0=1.0, width=width, scale=scale, depths=depths)
        if method == "deconfinement":
            # ∫Bᵀσ0 = K0·(xx part) + (yy part), for (σv(top), ρg) = (1, 0) and (0, 1)
            q_xx, q_yy, g_xx, g_yy = (
                initial_stress_forces(basis, q=q, rho_g=rho_g, k0=k0, vertical=vertical, top=top, where=where)
                for q, rho_g in ((1.0, 0.0), (0.0, 1.0)) for k0, vertical in ((1.0, 0.0), (0.0, 1.0)))
            cols -= np.column_stack([g_yy, q_yy, q_xx, g_xx])
    return shapes


def in_situ_stress(spec, layers: list[Stratum], band: np.ndarray, y: np.ndarray) -> dict:
    """The geostatic state at points ``y`` (E, P) of triangles in layers ``band`` (E,), as
    tension-positive stress components: ``effective`` and ``total`` (4, E, P) (xx, yy, xy,
    zz; K0 on the effective stress, σzz = σxx) and the hydrostatic ``pore`` pressure (E, P),
    compression positive."""
    y = np.asarray(y)
    state = geostatic_state(spec, layers, -y, np.broadcast_to(np.asarray(band)[:, None], y.shape))
    zero = np.zeros_like(y)
    eff_h, eff_v, pore = state["effective_h"], state["effective_v"], state["pore"]
    effective = np.stack([-eff_h, -eff_v, zero, -eff_h])
    total = np.stack([-state["sigma_h"], -state["sigma_v"], zero, -state["sigma_h"]])
    return {"effective": effective, "total": total, "pore": pore}
