"""Figures of one result or of combined results (matplotlib, Agg: no display needed).

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot, so
nothing is kept in a global figure registry; save it with ``fig.savefig(path)``.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import xarray as xr
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

_CONTACT_COLOR = "tab:red"


def _contact_spans(ax, ds: xr.Dataset) -> None:
    """Shade the theta ranges where the interface is in contact."""
    theta, on = ds["theta"].values, ds["in_contact"].values.astype(bool)
    labelled = False
    for run in np.split(np.arange(theta.size), np.flatnonzero(np.diff(on.astype(int))) + 1):
        if run.size and on[run[0]]:
            ax.axvspan(theta[run[0]], theta[run[-1]], color=_CONTACT_COLOR, alpha=0.12, lw=0,
                       label=None if labelled else "in contact")
            labelled = True


def _theta_axis(ax) -> None:
    ax.set_xlim(0, 180)
    ax.set_xticks(np.arange(0, 181, 30))
    ax.set_xlabel("θ (deg from crown)")
    ax.grid(True, alpha=0.3)


def _title(ds: xr.Dataset) -> str:
    return f"case {ds.attrs.get('case_id', '?')}"


def plot_contact_pressure(ds: xr.Dataset) -> Figure:
    """Contact pressure λ (kPa) and remaining gap (mm) along the interface."""
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    _contact_spans(ax, ds)
    ax.plot(ds["theta"], ds["contact_pressure"] / 1e3, color="k", lw=1.5, label="contact pressure λ")
    ax.set_ylabel("contact pressure λ (kPa)")
    _theta_axis(ax)
    gap_ax = ax.twinx()
    gap_ax.plot(ds["theta"], ds["gap"] * 1e3, color="tab:blue", lw=1, ls="--", label="gap g0 − [u]ν")
    gap_ax.set_ylabel("gap (mm)", color="tab:blue")
    lines = ax.get_legend_handles_labels()
    gap_lines = gap_ax.get_legend_handles_labels()
    ax.legend(lines[0] + gap_lines[0], lines[1] + gap_lines[1], loc="upper right", fontsize="small")
    ax.set_title(f"Contact pressure, {_title(ds)}: max {float(ds['max_contact_pressure']) / 1e3:.4g} kPa, "
                 f"extent {float(ds['contact_extent']):.4g}°", fontsize="medium")
    return fig


def plot_lining_forces(ds: xr.Dataset) -> Figure:
    """Thrust (kN/m, compression positive) and bending moment (kN·m/m) along the lining."""
    fig = Figure(figsize=(7, 6), layout="constrained")
    ax_n, ax_m = fig.subplots(2, 1, sharex=True)
    for ax, name, scale, label in ((ax_n, "thrust", 1e3, "thrust N (kN/m)"),
                                   (ax_m, "moment", 1e3, "moment M (kN·m/m),\n+ = inner fibre compressed")):
        _contact_spans(ax, ds)
        ax.plot(ds["theta"], ds[name] / scale, color="k", lw=1.5)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(label)
        _theta_axis(ax)
    ax_n.set_xlabel("")
    ax_n.set_title(f"Lining forces, {_title(ds)}", fontsize="medium")
    return fig


def plot_deformed_mesh(ds: xr.Dataset, *, scale: float | None = None) -> Figure:
    """The mesh near the tunnel, deformed by scaled displacements, contact zone marked.

    Parameters
    ----------
    ds : a case result.
    scale : displacement magnification; default makes the largest displacement near
        the tunnel 8 % of the lining outer radius.
    """
    x, y = ds["node_x"].values, ds["node_y"].values
    ux, uy = ds["displacement_x"].values, ds["displacement_y"].values
    tri = ds["face_nodes"].values.astype(np.int64)
    body = ds["body"].values
    lining_nodes = ds["lining_node"].values.astype(np.int64)
    cx = 0.0
    cy = float(np.mean(ds["interface_y"].values[[0, -1]]))
    radius = float(np.max(np.hypot(ds["interface_x"].values - cx, ds["interface_y"].values - cy)))
    view = 2.2 * radius
    near = np.hypot(x - cx, y - cy) < view
    umax = float(np.max(np.hypot(ux[near], uy[near]))) if near.any() else 0.0
    if scale is None:
        scale = 0.08 * radius / umax if umax > 0 else 1.0
    xd, yd = x + scale * ux, y + scale * uy

    fig = Figure(figsize=(6, 7), layout="constrained")
    ax = fig.add_subplot()
    ax.triplot(Triangulation(x, y, tri), color="0.85", lw=0.3)
    ax.triplot(Triangulation(xd, yd, tri[body == 0]), color="tab:brown", lw=0.3, alpha=0.6)
    lining = tri[body == 1]
    ax.add_collection(PolyCollection(np.stack([xd[lining], yd[lining]], axis=-1), facecolors="0.75",
                                     edgecolors="0.35", linewidths=0.3, label="lining"))
    on = ds["in_contact"].values.astype(bool)
    pts = np.column_stack([xd[lining_nodes], yd[lining_nodes]])
    segs = [pts[i:i + 2] for i in range(len(pts) - 1) if on[i] and on[i + 1]]
    ax.add_collection(LineCollection(segs, colors=_CONTACT_COLOR, linewidths=3, label="in contact"))
    ax.plot(pts[on, 0], pts[on, 1], "o", color=_CONTACT_COLOR, ms=2)
    ax.set_xlim(cx - 0.05 * view, cx + view)
    ax.set_ylim(cy - view, cy + view)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper right", fontsize="small")
    ax.set_title(f"Deformed mesh ×{scale:.3g} (grey: undeformed), {_title(ds)}", fontsize="medium")
    return fig


def plot_comparison(combined: xr.Dataset, variable: str = "contact_pressure") -> Figure:
    """``variable`` against theta for every case of a combined result (one line each)."""
    if variable not in combined or "theta" not in combined[variable].dims:
        raise ValueError(f"{variable!r} is not an interface quantity of the combined results")
    da = combined[variable]
    params = [n for n in combined.coords if combined[n].dims == ("case",) and n != "case_id"]
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    for i in range(combined.sizes["case"]):
        label = ", ".join(f"{p}={combined[p].values[i]:.4g}" if np.issubdtype(combined[p].dtype, np.number)
                          else f"{p}={combined[p].values[i]}" for p in params)
        ax.plot(combined["theta"], da.isel(case=i), lw=1.3,
                label=label or str(combined["case_id"].values[i]))
    ax.set_ylabel(f"{da.attrs.get('long_name', variable)} ({da.attrs.get('units', '')})")
    _theta_axis(ax)
    ax.legend(fontsize="small")
    ax.set_title(f"{variable}: {combined.sizes['case']} cases", fontsize="medium")
    return fig


#: Plots of one case, by name (used by the CLI and the REST service).
PLOTS: dict[str, Callable[[xr.Dataset], Figure]] = {
    "contact_pressure": plot_contact_pressure,
    "lining_forces": plot_lining_forces,
    "deformed_mesh": plot_deformed_mesh,
}
