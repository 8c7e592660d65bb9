"""The whole model of one case, as an engineer checks it before reading any result: the
ground's layers over the full width and depth, the water table, the boundary conditions, the
mesh and the tunnel with its lining (SPEC §9.3, plot ``model``)."""
from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from .case_plots import _WATER_COLOR, _title, case_spec

#: One colour per layer (earth tones, repeated past the last).
_LAYER_COLOURS = ("#d9c49a", "#b99b6b", "#a3b18a", "#c9ad7f", "#8f7f62", "#d4b483", "#9c8a6b", "#bfae8e")
#: What each boundary condition holds, as drawn.
_SIDE = {"roller": "roller: u_x = 0", "fixed": "fixed: u = 0", "pressure": "in-situ pressure K0 σv"}
_BOTTOM = {"fixed": "fixed: u = 0", "roller": "roller: u_y = 0"}


def _layer_of_faces(ds: xr.Dataset) -> np.ndarray:
    return ds["layer"].values if "layer" in ds else np.where(ds["body"].values == 0, 0, -1)


def _supports(ax, width: float, height: float, side: str, bottom: str) -> None:
    """Boundary symbols: small triangles (rollers) or hatched ground (fixed) along the side and
    the bottom; arrows for a pressure side."""
    size = 0.02 * max(width, height)
    ys = np.linspace(-height, 0.0, 9)[1:-1]
    xs = np.linspace(0.0, width, 9)[1:-1]
    if side == "pressure":
        for y in ys:
            ax.annotate("", xy=(width, y), xytext=(width + 3 * size, y),
                        arrowprops={"arrowstyle": "->", "color": "tab:red", "lw": 1.0})
    else:
        for y in ys:
            ax.plot([width, width + size, width + size, width], [y, y + size / 1.5, y - size / 1.5, y],
                    color="k", lw=0.8)
            if side == "fixed":
                ax.plot([width + size, width + 1.8 * size], [y - size, y + size], color="k", lw=0.6)
    for x in xs:
        ax.plot([x, x - size / 1.5, x + size / 1.5, x], [-height, -height - size, -height - size, -height],
                color="k", lw=0.8)
        if bottom == "fixed":
            ax.plot([x - size, x + size], [-height - 1.8 * size, -height - size], color="k", lw=0.6)
    ax.plot([0.0, 0.0], [-height, 0.0], color="0.3", lw=1.2, ls=(0, (6, 3)))


def plot_model(ds: xr.Dataset) -> Figure:
    """The whole model: the ground's layers (one colour each, the mesh over them), the water
    table, the symmetry axis, the side and bottom conditions, the lining, and the dimensions."""
    spec = case_spec(ds)
    geometry, bounds = spec.get("geometry", {}), spec.get("boundaries", {})
    width, height = float(geometry.get("width", 0.0)), float(geometry.get("height", 0.0))
    x, y = ds["node_x"].values, ds["node_y"].values
    width = width or float(x.max())
    height = height or float(-y.min())
    tri = ds["face_nodes"].values.astype(np.int64)[:, :3]
    layer, body = _layer_of_faces(ds), ds["body"].values
    fig = Figure(figsize=(7.5, 7.5 * min(max(height / width, 0.6), 1.6) + 0.6), layout="constrained")
    ax = fig.add_subplot()
    handles = []
    for k in sorted(set(layer[body == 0].tolist())):
        faces = tri[(body == 0) & (layer == k)]
        colour = _LAYER_COLOURS[k % len(_LAYER_COLOURS)]
        ax.add_collection(PolyCollection(np.stack([x[faces], y[faces]], axis=-1), facecolors=colour,
                                         edgecolors="0.35", linewidths=0.1, rasterized=True))
        handles.append(Patch(facecolor=colour, edgecolor="0.35", label=_layer_label(spec, k)))
    lining = tri[body == 1]
    ax.add_collection(PolyCollection(np.stack([x[lining], y[lining]], axis=-1), facecolors="0.55",
                                     edgecolors="0.25", linewidths=0.1, rasterized=True))
    handles.append(Patch(facecolor="0.55", label=f"lining, t = {geometry.get('thickness', 0):g} m"))
    table = (spec.get("water") or {}).get("table")
    if table is not None:
        ax.axhline(-float(table), color=_WATER_COLOR, lw=1.5, ls="--")
        ax.plot([], [], color=_WATER_COLOR, lw=1.5, ls="--",
                label=f"water table {float(table):g} m ({(spec.get('water') or {}).get('lining', 'watertight')} lining)")
    side, bottom = bounds.get("side", "roller"), bounds.get("bottom", "fixed")
    _supports(ax, width, height, side, bottom)
    ax.plot([], [], color="0.3", lw=1.2, ls=(0, (6, 3)), label="symmetry axis: u_x = 0")
    pad = 0.08 * max(width, height)
    ax.set_xlim(-0.02 * width, width + pad)
    ax.set_ylim(-height - pad, 0.04 * height)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m, ground surface at 0)")
    lines, labels = ax.get_legend_handles_labels()
    ax.legend(handles=handles + lines, fontsize="x-small", loc="lower right", framealpha=0.9)
    depth = float(geometry.get("depth", 0.0))
    ax.set_title(f"The model, {_title(ds)}: {width:g} m × {height:g} m half section, axis depth {depth:g} m\n"
                 f"side {_SIDE.get(side, side)}; bottom {_BOTTOM.get(bottom, bottom)}; "
                 f"{int(tri.shape[0]) // 4:,} quadratic triangles", fontsize="medium")
    return fig


def _layer_label(spec: dict, k: int) -> str:
    """``layer k: from–to m, E`` from the case's layers (or the one ground)."""
    ground = spec.get("ground", {})
    layers = ground.get("layers") or []
    if not layers:
        return f"ground, E = {float(ground.get('young', 0)) / 1e6:.4g} MPa"
    top = sum(float(layers[i].get("thickness") or 0.0) for i in range(k))
    this = layers[k] if k < len(layers) else {}
    thick = this.get("thickness")
    young = this.get("young", ground.get("young", 0.0))
    span = f"{top:g}–{top + float(thick):g} m" if thick else f"from {top:g} m"
    return f"layer {k}: {span}, E = {float(young) / 1e6:.4g} MPa"
