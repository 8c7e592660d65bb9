"""Figures of one result or of combined results (matplotlib, Agg: no display needed).

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot, so
nothing is kept in a global figure registry; save it with ``fig.savefig(path)``.
"""
from __future__ import annotations

import textwrap
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


# -- figures of a sweep (many cases) ------------------------------------------------------

#: CF units of the results -> (unit shown to people, factor from SI).
DISPLAY_UNITS: dict[str, tuple[str, float]] = {
    "Pa": ("kPa", 1e-3), "N m-1": ("kN/m", 1e-3), "N m m-1": ("kN·m/m", 1e-3),
    "m": ("mm", 1e3), "degree": ("°", 1.0), "s": ("s", 1.0), "1": ("", 1.0),
}
#: Scalars that describe the solve rather than the tunnel.
_DIAGNOSTICS = ("bolt_theta", "bolt_trials", "iterations", "converged", "kkt_residual", "solve_seconds")
#: Most cases for which a figure still gets a legend (more: colour only).
_LEGEND_CASES = 10


def display_unit(units: str) -> tuple[str, float]:
    """``(unit label, factor)`` to show a quantity stored in CF ``units`` (e.g. Pa -> kPa, 1e-3)."""
    return DISPLAY_UNITS.get(units, (units, 1.0))


def case_parameters(combined: xr.Dataset) -> list[str]:
    """Names of the varied parameters of combined results (coordinates along ``case``)."""
    return [str(n) for n in combined.coords if combined[n].dims == ("case",) and n != "case_id"]


def case_labels(combined: xr.Dataset) -> list[str]:
    """One label per case: its varied parameters (``ground_young=5e+07, ...``), else its id."""
    params = case_parameters(combined)
    labels = []
    for i in range(combined.sizes["case"]):
        parts = [f"{p}={combined[p].values[i]:.4g}" if np.issubdtype(combined[p].dtype, np.number)
                 else f"{p}={combined[p].values[i]}" for p in params]
        labels.append(", ".join(parts) or str(combined["case_id"].values[i]))
    return labels


def _case_colors(n: int) -> list:
    from matplotlib import colormaps

    if n <= 10:
        return [colormaps["tab10"](i) for i in range(n)]
    return [colormaps["viridis"](i / (n - 1)) for i in range(n)]


def plot_contact_pressure_comparison(combined: xr.Dataset) -> Figure:
    """Contact pressure (kPa) against theta for every case of a combined result."""
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    labels, colors = case_labels(combined), _case_colors(combined.sizes["case"])
    for i in range(combined.sizes["case"]):
        ax.plot(combined["theta"], combined["contact_pressure"].isel(case=i) / 1e3, lw=1.2, color=colors[i],
                label=labels[i])
    ax.set_ylabel("contact pressure λ (kPa)")
    _theta_axis(ax)
    if combined.sizes["case"] <= _LEGEND_CASES:
        ax.legend(fontsize="x-small")
    ax.set_title(f"Contact pressure: {combined.sizes['case']} cases", fontsize="medium")
    return fig


def plot_lining_forces_comparison(combined: xr.Dataset) -> Figure:
    """Thrust and moment against theta for every case of a combined result."""
    fig = Figure(figsize=(7, 6), layout="constrained")
    ax_n, ax_m = fig.subplots(2, 1, sharex=True)
    labels, colors = case_labels(combined), _case_colors(combined.sizes["case"])
    for ax, name, label in ((ax_n, "thrust", "thrust N (kN/m)"),
                            (ax_m, "moment", "moment M (kN·m/m),\n+ = inner fibre compressed")):
        for i in range(combined.sizes["case"]):
            ax.plot(combined["theta"], combined[name].isel(case=i) / 1e3, lw=1.2, color=colors[i], label=labels[i])
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(label)
        _theta_axis(ax)
    ax_n.set_xlabel("")
    if combined.sizes["case"] <= _LEGEND_CASES:
        ax_n.legend(fontsize="x-small")
    ax_n.set_title(f"Lining forces: {combined.sizes['case']} cases", fontsize="medium")
    return fig


def plot_interaction(cases: list[xr.Dataset], labels: list[str] | None = None) -> Figure:
    """N–M diagram of a set of cases: each case's thrust and moment at every station.

    Where a case carries its design envelope (``capacity_thrust``, ``capacity_moment``
    on ``envelope``, SPEC §1.3), the envelope is drawn and the stations are the design
    actions (γF·N, γF·M, with γF = ``design.load_factor`` of the case); otherwise the
    stations are the computed (N, M).
    """
    import json

    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot()
    labels = labels or [str(ds.attrs.get("case_id", i)) for i, ds in enumerate(cases)]
    colors = _case_colors(len(cases))
    with_envelope = [all(v in ds for v in ("capacity_thrust", "capacity_moment")) for ds in cases]
    worst = None
    for ds, label, color, design in zip(cases, labels, colors, with_envelope):
        factor = 1.0
        if design:
            factor = float(json.loads(ds.attrs.get("case_spec", "{}")).get("design", {}).get("load_factor", 1.0))
            n_env, m_env = ds["capacity_thrust"].values / 1e3, ds["capacity_moment"].values / 1e3
            ax.plot(np.append(m_env, m_env[:1]), np.append(n_env, n_env[:1]), color=color, lw=1.0)
        ax.plot(factor * ds["moment"].values / 1e3, factor * ds["thrust"].values / 1e3, "o", ms=2.5,
                color=color, label=label)
        if "utilization" in ds:
            eta = float(np.nanmax(ds["utilization"].values))
            worst = eta if worst is None else max(worst, eta)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.axvline(0.0, color="0.5", lw=0.8)
    ax.grid(True, alpha=0.3)
    if any(with_envelope):
        ax.set_xlabel("design moment M_Ed (kN·m/m)")
        ax.set_ylabel("design thrust N_Ed (kN/m, compression +)")
        title = "N–M interaction: design envelopes (lines) and actions at every station (dots)"
        if worst is not None:
            title += f"\nlargest utilization η = {worst:.3g}" + (" (fails)" if worst > 1 else "")
    else:
        ax.set_xlabel("moment M (kN·m/m)")
        ax.set_ylabel("thrust N (kN/m, compression +)")
        title = "Thrust and moment at every station (no design envelope in these results)"
    if len(cases) <= _LEGEND_CASES:
        ax.legend(fontsize="x-small", markerscale=2)
    ax.set_title(title, fontsize="medium")
    return fig


def _format_value(value) -> str:
    return f"{value:.4g}" if isinstance(value, (int, float, np.number)) else str(value)


def _parameter_axis(values: np.ndarray) -> tuple[np.ndarray, list[str] | None]:
    """Positions for parameter ``values``: themselves if numeric, else category indices and labels."""
    if np.issubdtype(values.dtype, np.number):
        return values.astype(float), None
    categories = list(dict.fromkeys(values.tolist()))
    return np.array([categories.index(v) for v in values.tolist()], dtype=float), categories


def plot_scalars(combined: xr.Dataset, scalars: list[str] | None = None) -> Figure:
    """Each summary scalar against each varied parameter (one panel per pair).

    Cases that share the values of the other varied parameters are joined by a line
    (one colour per combination of those values, legend in the first row), so in a
    grid sweep each line shows the effect of one parameter alone. Scalars with the
    same value in every case are listed in the title instead of plotted.

    Parameters
    ----------
    combined : combined results (:func:`workflows.open_results`).
    scalars : names of the scalars to show; default every numeric scalar along ``case``,
        the solver's diagnostics (bolt, iterations, residual, time) last.
    """
    params = case_parameters(combined)
    if scalars is None:
        scalars = [str(n) for n, v in combined.data_vars.items()
                   if v.dims == ("case",) and v.dtype.kind in "biuf"]
        scalars.sort(key=lambda name: name in _DIAGNOSTICS)
    constant = [s for s in scalars if np.allclose(combined[s].values.astype(float),
                                                  float(combined[s].values[0]), rtol=1e-9, atol=0)]
    panels = [(s, p) for s in scalars if s not in constant for p in params]
    if not panels:
        fig = Figure(figsize=(6, 2), layout="constrained")
        fig.text(0.5, 0.5, "no varied parameter, or no scalar that changes: nothing to plot",
                 ha="center", va="center")
        return fig
    # whole rows of scalars: 4 panels a row for one or two parameters, 3 for three, then 4
    ncols = len(params) if len(params) == 3 else 4
    nrows = -(-len(panels) // ncols)
    fig = Figure(figsize=(3.4 * ncols, 2.4 * nrows + 0.4), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    for k, (ax, (scalar, param)) in enumerate(zip(axes, panels)):
        unit, factor = display_unit(combined[scalar].attrs.get("units", ""))
        y = combined[scalar].values.astype(float) * factor
        x, categories = _parameter_axis(combined[param].values)
        others = [p for p in params if p != param]
        groups: dict[tuple, list[int]] = {}
        for i in range(combined.sizes["case"]):
            groups.setdefault(tuple(_format_value(combined[o].values[i]) for o in others), []).append(i)
        colors = _case_colors(len(groups))
        for color, (key, members) in zip(colors, groups.items()):
            members = sorted(members, key=lambda i: x[i])
            ax.plot(x[members], y[members], "o-", ms=3, lw=1, color=color,
                    label=", ".join(f"{o}={v}" for o, v in zip(others, key)))
        if k < ncols and others and len(groups) <= 6:
            ax.legend(fontsize="xx-small")
        if categories is not None:
            ax.set_xticks(range(len(categories)), categories, fontsize="x-small")
        ax.set_xlabel(param, fontsize="small")
        ax.set_ylabel(f"{scalar}" + (f" ({unit})" if unit else ""), fontsize="small")
        ax.tick_params(labelsize="x-small")
        ax.grid(True, alpha=0.3)
    title = f"Summary scalars against the varied parameters: {combined.sizes['case']} cases"
    if constant:
        shown = ", ".join(f"{s} = {float(combined[s].values[0]):.4g}" for s in constant)
        title += "\nthe same in every case: " + "\n".join(textwrap.wrap(shown, 30 * ncols))
    fig.suptitle(title, fontsize="small")
    return fig


#: Plots of a sweep (combined results of its finished cases), by name. ``interaction``
#: needs the cases themselves (their envelopes are not combined): see
#: :func:`workflows.artifacts.render_sweep_plot`.
SWEEP_PLOTS: dict[str, Callable[[xr.Dataset], Figure]] = {
    "contact_pressure": plot_contact_pressure_comparison,
    "lining_forces": plot_lining_forces_comparison,
    "scalars": plot_scalars,
}
SWEEP_PLOT_NAMES = ("contact_pressure", "lining_forces", "interaction", "scalars")
