"""Figures of the fields of one case on its mesh: contours near the tunnel and the deformed mesh.

Displacements are node values (contoured on the mesh's triangles); stresses, pore pressure
and plastic strain are face values (one colour per triangle, as the FE stores them). The
view is the half plane x ≥ 0 (the model's symmetry) around the tunnel; the yielded zone, if
the ground yields, is outlined on every panel. Units: mm, kPa.
"""
from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from . import joint_plots
from .case_plots import _CONTACT_COLOR, _ground_lines, _title

#: Half width of the view around the tunnel, in excavation radii.
VIEW_RADII = 2.6


def _frame(ds: xr.Dataset) -> tuple[float, float, float]:
    """``(centre y, excavation radius, view half width)`` of the tunnel (m)."""
    cy = float(np.mean(ds["interface_y"].values[[0, -1]]))
    radius = float(np.max(np.hypot(ds["interface_x"].values, ds["interface_y"].values - cy)))
    return cy, radius, VIEW_RADII * radius


def _window(ax, ds: xr.Dataset) -> None:
    cy, _, view = _frame(ds)
    ax.set_xlim(0.0, view)
    ax.set_ylim(cy - view, min(cy + view, 0.0 + 0.02 * view))
    ax.set_aspect("equal")
    ax.tick_params(labelsize="x-small")


def _near(ds: xr.Dataset) -> np.ndarray:
    """Faces with a corner inside the view (their values set the colour range)."""
    cy, _, view = _frame(ds)
    tri = ds["face_nodes"].values.astype(np.int64)
    x, y = ds["node_x"].values[tri], ds["node_y"].values[tri]
    return np.any((x < 1.05 * view) & (np.abs(y - cy) < 1.05 * view), axis=1)


def _in_view(ds: xr.Dataset, tri: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Faces whose bounding box meets the view (:func:`_window`, with a margin): no other face
    can show in it, so drawing only these gives the same picture at a fraction of the polygons
    (far from the tunnel the mesh is coarse, but the model is many views wide)."""
    cy, _, view = _frame(ds)
    xs, ys = x[tri], y[tri]
    margin = 0.05 * view
    return ((xs.min(axis=1) <= view + margin) & (xs.max(axis=1) >= -margin)
            & (ys.min(axis=1) <= cy + view + margin) & (ys.max(axis=1) >= cy - view - margin))


def zone_border(ds: xr.Dataset, tri: np.ndarray, name: str = "plastic") -> np.ndarray | None:
    """The edges (k, 2) (node pairs) between a face where the flag ``name`` is set and one where
    it is not (or the mesh's edge): the outline of the yielded zone, at the end or before the
    lining (``stage1_plastic``); None where no face has the flag."""
    if name not in ds or not np.any(ds[name].values > 0):
        return None
    plastic = ds[name].values > 0
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    n = int(tri.max()) + 1
    keys, inverse = np.unique(edges[:, 0] * n + edges[:, 1], return_inverse=True)  # one integer per edge
    state = np.bincount(inverse.ravel(), weights=np.tile(plastic, 3), minlength=keys.size)
    border = keys[state == 1]  # exactly one flagged face beside the edge
    return np.column_stack([border // n, border % n])


def _yielded_outline(ax, border: np.ndarray | None, x: np.ndarray, y: np.ndarray, *, color: str = "magenta",
                     label: str = "yielded zone", style: str = "-") -> None:
    """Draw a yielded zone's outline (:func:`zone_border`; nothing where it is None) at nodes ``x``, ``y``."""
    if border is None:
        return
    segs = np.stack([np.column_stack([x[border[:, 0]], y[border[:, 0]]]),
                     np.column_stack([x[border[:, 1]], y[border[:, 1]]])], axis=1)
    ax.add_collection(LineCollection(segs, colors=color, linewidths=1.2, linestyles=style, label=label))


def _lining(ax, ds: xr.Dataset, tri: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    lining = tri[ds["body"].values == 1]
    ax.add_collection(PolyCollection(np.stack([x[lining], y[lining]], axis=-1), facecolors="0.8",
                                     edgecolors="none", label="lining", rasterized=True))


def _panel(fig, ax, ds, tri, near, values, *, label: str, cmap: str, faces: bool, symmetric: bool = False,
           drawn: np.ndarray, borders: tuple) -> None:
    """One field on the ground near the tunnel (``near``: the ground faces in view, which set
    the colour range; ``drawn``: the ground faces that can show in the view, :func:`_in_view`;
    ``borders``: the two yielded zones' outlines, :func:`zone_border`)."""
    x, y = ds["node_x"].values, ds["node_y"].values
    shown = values[near] if faces else values[np.unique(tri[near])]
    lo, hi = (float(np.min(shown)), float(np.max(shown))) if shown.size else (0.0, 1.0)
    if symmetric:
        top = max(abs(lo), abs(hi)) or 1.0
        lo, hi = -top, top
    elif hi <= lo:
        hi = lo + (abs(lo) or 1.0) * 1e-6
    levels = np.linspace(lo, hi, 13)
    if faces:
        art = ax.tripcolor(Triangulation(x, y, tri[drawn]), facecolors=values[drawn], cmap=cmap,
                           vmin=lo, vmax=hi, shading="flat", rasterized=True)
    else:
        art = ax.tricontourf(Triangulation(x, y, tri[drawn]), values, levels=levels, cmap=cmap, extend="both")
        art.set_rasterized(True)
    _lining(ax, ds, tri, x, y)
    joint_plots.draw_on_mesh(ax, ds)
    _yielded_outline(ax, borders[0], x, y)
    _yielded_outline(ax, borders[1], x, y, color="darkorange", label="yielded before the lining", style="--")
    _ground_lines(ax, ds)
    _window(ax, ds)
    bar = fig.colorbar(art, ax=ax, shrink=0.85)
    bar.ax.tick_params(labelsize="x-small")
    ax.set_title(label, fontsize="small")


def plot_contours(ds: xr.Dataset) -> Figure:
    """Contours near the tunnel: displacement magnitude (mm), effective stresses σ'xx, σ'yy,
    τxy (kPa, compression negative), and where the case has them pore pressure (kPa) and
    equivalent plastic strain, the yielded zone outlined in magenta on every panel, a segmental
    lining's joints as lines across the lining."""
    tri = ds["face_nodes"].values.astype(np.int64)[:, :3]
    stress = "effective_stress" if "effective_stress_xx" in ds else "stress"
    panels = [("|u| displacement magnitude (mm)", "viridis", False, False,
               1e3 * np.hypot(ds["displacement_x"].values, ds["displacement_y"].values)),
              ("σ'xx horizontal effective stress (kPa)", "plasma", True, False,
               ds[f"{stress}_xx"].values / 1e3),
              ("σ'yy vertical effective stress (kPa)", "plasma", True, False,
               ds[f"{stress}_yy"].values / 1e3),
              ("τxy shear stress (kPa)", "PuOr", True, True, ds[f"{stress}_xy"].values / 1e3)]
    if "pore_pressure" in ds and np.any(ds["pore_pressure"].values != 0):
        panels.append(("p pore pressure (kPa)", "Blues", True, False,
                       ds["pore_pressure"].values / 1e3))
    if "equivalent_plastic_strain" in ds and np.any(ds["plastic"].values > 0):
        panels.append(("ε̄p equivalent plastic strain (%)", "magma_r", True, False,
                       100 * ds["equivalent_plastic_strain"].values))
    ncols = 3 if len(panels) > 4 else 2
    nrows = -(-len(panels) // ncols)
    fig = Figure(figsize=(4.2 * ncols, 4.4 * nrows + 0.5), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    near = _near(ds) & (ds["body"].values == 0)
    drawn = _in_view(ds, tri, ds["node_x"].values, ds["node_y"].values) & (ds["body"].values == 0)
    borders = (zone_border(ds, tri), zone_border(ds, tri, "stage1_plastic"))
    for ax, (label, cmap, faces, symmetric, values) in zip(axes, panels):
        _panel(fig, ax, ds, tri, near, values, label=label, cmap=cmap, faces=faces, symmetric=symmetric,
               drawn=drawn, borders=borders)
    for ax in axes[len(panels) - ncols:len(panels)]:
        ax.set_xlabel("x (m)", fontsize="x-small")
    yielded = "plastic" in ds and bool(np.any(ds["plastic"].values > 0))
    joints = joint_plots.summary(ds)
    fig.suptitle(f"Fields near the tunnel, {_title(ds)} (lining grey"
                 + (f"; {joints}: lines across the lining, orange open, dark closed" if joints else "")
                 + ("; yielded zone outlined in magenta" if yielded else "; the ground stays elastic")
                 + "; stresses: compression negative)", fontsize="medium")
    return fig


#: The views of the deformed mesh (``stage``): stage 1 (the unsupported ground, before the lining),
#: stage 2 (both bodies from the lining's placement on), and the total (since excavation).
STAGES = ("total", "1", "2")


def _placement_shift(ds: xr.Dataset, lining_nodes: np.ndarray) -> np.ndarray:
    """(2, n) where each lining node was placed: the stage-1 displacement of the excavation
    boundary at the node's angle (the lining is built in the hole as stage 1 left it), so that
    the lining's displacement since placement plus this is its displacement since excavation."""
    cy = float(np.mean(ds["interface_y"].values[[0, -1]]))
    gn = ds["ground_node"].values.astype(np.int64)
    theta = ds["theta"].values
    x, y = ds["node_x"].values[lining_nodes], ds["node_y"].values[lining_nodes] - cy
    at = np.degrees(np.arctan2(x, y))
    return np.stack([np.interp(at, theta, ds[f"stage1_displacement_{c}"].values[gn]) for c in "xy"])


def stage_displacements(ds: xr.Dataset, stage: str = "total") -> tuple[np.ndarray, np.ndarray, bool]:
    """Node displacements (m) of every body in one reference for a view of the construction:
    ``"1"`` the ground's of stage 1 (the lining is not there yet: ``False``), ``"2"`` both bodies'
    since the lining was placed, ``"total"`` both since excavation (the lining's since placement
    plus where it was placed). The ground is never drawn inside the lining: in every view the
    interface's drawn gap is the contact's normal jump (zero where closed)."""
    if stage not in STAGES:
        raise ValueError(f"stage: one of {', '.join(STAGES)}, not {stage!r}")
    ux, uy = ds["displacement_x"].values.copy(), ds["displacement_y"].values.copy()
    lining = np.unique(ds["face_nodes"].values[ds["body"].values == 1])
    u1x, u1y = ds["stage1_displacement_x"].values, ds["stage1_displacement_y"].values
    if stage == "1":
        return u1x.copy(), u1y.copy(), False
    if stage == "2":
        ground = np.ones(ux.size, bool)
        ground[lining] = False
        ux[ground] -= u1x[ground]
        uy[ground] -= u1y[ground]
        return ux, uy, True
    shift = _placement_shift(ds, lining)
    ux[lining] += shift[0]
    uy[lining] += shift[1]
    return ux, uy, True


_STAGE_TITLES = {"total": "total since excavation (the lining from where it was placed)",
                 "1": "stage 1: the unsupported ground before the lining",
                 "2": "stage 2: both bodies since the lining was placed"}


def plot_deformed_mesh(ds: xr.Dataset, *, scale: float | None = None, stage: str = "total") -> Figure:
    """The ground and lining near the tunnel deformed by scaled displacements, every body in the
    same reference (:func:`stage_displacements`: ``stage`` ``"total"``, ``"1"`` or ``"2"``),
    coloured by the displacement magnitude (mm); the undeformed excavation boundary dashed, the
    contact zone red, a segmental lining's joints as lines across the lining (each face deformed
    with its segment, so an open joint gapes; :mod:`workflows.joint_plots`).

    The lining's own deformation (its ovalization, the displacement since placement less the
    ring's mean translation) is what the eye should see, so by default the scale makes the largest
    of it 12 % of the radius (stage 1: the wall's largest displacement); the translation is stated
    in the title.
    """
    ux, uy, with_lining = stage_displacements(ds, stage)
    x, y = ds["node_x"].values, ds["node_y"].values
    tri = ds["face_nodes"].values.astype(np.int64)[:, :3]
    body = ds["body"].values
    cy, radius, view = _frame(ds)
    ring = ds["lining_node"].values.astype(np.int64)
    lx, ly = ds["displacement_x"].values[ring], ds["displacement_y"].values[ring]
    shift = np.array([0.0, float(np.mean(ly))])  # symmetric: no mean horizontal motion
    own = float(np.max(np.hypot(lx - shift[0], ly - shift[1])))
    if not with_lining:
        gn = ds["ground_node"].values.astype(np.int64)
        own = float(np.max(np.hypot(ux[gn], uy[gn])))
    if scale is None:
        scale = 0.12 * radius / own if own > 0 else 1.0
    xd, yd = x + scale * ux, y + scale * uy
    magnitude = 1e3 * np.hypot(ux, uy)
    fig = Figure(figsize=(6.4, 7), layout="constrained")
    ax = fig.add_subplot()
    ground = tri[(body == 0) & _in_view(ds, tri, xd, yd)]  # the faces that can show (the same picture)
    art = ax.tripcolor(Triangulation(xd, yd, ground), magnitude, cmap="viridis", shading="gouraud", rasterized=True)
    for line in ax.triplot(Triangulation(xd, yd, ground), color="w", lw=0.15, alpha=0.5):
        line.set_rasterized(True)
    if with_lining:
        _deformed_lining(ax, ds, tri[body == 1], xd, yd, ring, scale, (ux, uy))
    ix, iy = ds["interface_x"].values, ds["interface_y"].values
    ax.plot(ix, iy, color="k", lw=1.0, ls="--", label="excavation boundary (undeformed)")
    _yielded_outline(ax, zone_border(ds, tri), xd, yd)
    _ground_lines(ax, ds)
    ax.set_xlim(0.0, view)
    ax.set_ylim(cy - view, cy + view)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    bar = fig.colorbar(art, ax=ax, shrink=0.8)
    bar.set_label("displacement magnitude |u| (mm)", fontsize="small")
    ax.legend(loc="upper right", fontsize="x-small")
    joints = joint_plots.summary(ds) if with_lining else ""
    ax.set_title(f"Deformed mesh ×{scale:.3g}, {_title(ds)}\n{_STAGE_TITLES[stage]}\n"
                 + (f"ring translation {1e3 * shift[1]:+.3g} mm (up +), ring deformation up to {1e3 * own:.3g} mm"
                    if with_lining else f"wall displacement up to {1e3 * own:.3g} mm")
                 + (f"\nsegmental lining: {joints}, largest opening {1e3 * float(ds['max_joint_opening']):.3g} mm"
                    if joints else ""), fontsize="medium")
    return fig


def _deformed_lining(ax, ds, lining, xd, yd, ring, scale, displacement) -> None:
    """The deformed lining, the contact zone on its extrados and its joints."""
    ax.add_collection(PolyCollection(np.stack([xd[lining], yd[lining]], axis=-1), facecolors="0.75",
                                     edgecolors="0.45", linewidths=0.2, label="lining (deformed)", rasterized=True))
    on = ds["in_contact"].values.astype(bool)
    pts = np.column_stack([xd[ring], yd[ring]])
    segs = [pts[i:i + 2] for i in range(len(pts) - 1) if on[i] and on[i + 1]]
    ax.add_collection(LineCollection(segs, colors=_CONTACT_COLOR, linewidths=2.5, label="in contact"))
    joint_plots.draw_on_mesh(ax, ds, scale=scale, displacement=displacement)
