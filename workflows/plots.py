"""Figures of one result or of combined results (matplotlib, Agg: no display needed).

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot, so
nothing is kept in a global figure registry; save it with ``fig.savefig(path)``.
The figures of one case live in :mod:`workflows.case_plots`; this module holds the
figures of many cases and the registries :data:`PLOTS` and :data:`SWEEP_PLOTS`.
"""
from __future__ import annotations

import textwrap
from collections.abc import Callable
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from .case_plots import (
    draw_envelope,
    load_factor,
    plot_contact_pressure,
    plot_ground_reaction,
    plot_lining_forces,
    plot_surface_settlement,
    theta_axis,
)
from .case_plots import plot_interaction as plot_case_interaction
from .field_plots import plot_contours, plot_deformed_mesh
from .model_plot import plot_model
from .parameters import shown_parameter_unit
from .store_files import data_variables
from .units import DIAGNOSTICS, display_unit, shown_value


def plot_comparison(combined: xr.Dataset, variable: str = "contact_pressure") -> Figure:
    """``variable`` against theta for every case of a combined result (one line each)."""
    if variable not in combined or "theta" not in combined[variable].dims:
        raise ValueError(f"{variable!r} is not an interface quantity of the combined results")
    da = combined[variable]
    params = [n for n in combined.coords if combined[n].dims == ("case",) and n not in ("case_id", "case")]
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    for i in range(combined.sizes["case"]):
        label = ", ".join(f"{p}={combined[p].values[i]:.4g}" if np.issubdtype(combined[p].dtype, np.number)
                          else f"{p}={combined[p].values[i]}" for p in params)
        ax.plot(combined["theta"], da.isel(case=i), lw=1.3,
                label=label or str(combined["case_id"].values[i]))
    ax.set_ylabel(f"{da.attrs.get('long_name', variable)} ({da.attrs.get('units', '')})")
    theta_axis(ax)
    ax.legend(fontsize="small")
    ax.set_title(f"{variable}: {combined.sizes['case']} cases", fontsize="medium")
    return fig


#: Plots of one case, by name (used by the CLI and the REST service).
PLOTS: dict[str, Callable[[xr.Dataset], Figure]] = {
    "contact_pressure": plot_contact_pressure,
    "lining_forces": plot_lining_forces,
    "interaction": plot_case_interaction,
    "surface_settlement": plot_surface_settlement,
    "deformed_mesh": plot_deformed_mesh,
    "contours": plot_contours,
    "ground_reaction": plot_ground_reaction,
    "model": plot_model,
}
#: Plots that show one construction stage at a time (``stage``: "total", "1", "2").
STAGED_PLOTS = ("deformed_mesh",)


# -- figures of a sweep (many cases) ------------------------------------------------------

#: Most cases for which a figure still gets a legend (more: colour only).
_LEGEND_CASES = 10


def case_parameters(combined: xr.Dataset) -> list[str]:
    """Names of the varied parameters of combined results (coordinates along ``case``)."""
    return [str(n) for n in combined.coords if combined[n].dims == ("case",) and n not in ("case_id", "case")]


def case_labels(combined: xr.Dataset) -> list[str]:
    """One label per case: its varied parameters in engineering units (``ground_young = 50 MPa,
    ...``), else its id."""
    params = case_parameters(combined)
    values = {p: combined[p].values.tolist() for p in params}
    return [", ".join(parameter_text(p, values[p][i]) for p in params) or str(combined["case_id"].values[i])
            for i in range(combined.sizes["case"])]


def parameter_text(param: str, value) -> str:
    """``param = value unit`` with a number in its engineering unit (``ground_young = 20 MPa``)."""
    if isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
        unit, factor = shown_parameter_unit(param)
        return f"{param} = {_format_value(float(value) * factor)}" + (f" {unit}" if unit not in ("", "1") else "")
    return f"{param} = {value}"


def parameter_label(param: str) -> str:
    """An axis or colour bar label of a parameter: its name and engineering unit."""
    unit = shown_parameter_unit(param)[0]
    return f"{param} ({unit})" if unit not in ("", "1") else param


def lines_per(param: str, others: list[str], sep: str = ": ") -> str:
    """What a panel against ``param`` draws when cases sharing the ``others`` are joined by a line."""
    if not others:
        return f"against {param}{sep}one line through the cases"
    return f"against {param}{sep}one line per " + (others[0] if len(others) == 1 else
                                                   "combination of " + ", ".join(others))


def _case_colors(n: int) -> list:
    from matplotlib import colormaps

    if n <= 10:
        return [colormaps["tab10"](i) for i in range(n)]
    return [colormaps["viridis"](i / (n - 1)) for i in range(n)]


def _value_colours(values) -> tuple[list, Any]:
    """Viridis colours of numbers (on a log scale when all are positive and span a factor
    over 5) and the ``ScalarMappable`` their colour bar is drawn from."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LogNorm, Normalize

    v = np.asarray(values, dtype=float)
    log = bool(np.all(v > 0) and v.max() > 5 * v.min())
    mappable = ScalarMappable(norm=(LogNorm if log else Normalize)(v.min(), v.max()), cmap=colormaps["viridis"])
    return [mappable.to_rgba(x) for x in v], mappable


class CaseColours:
    """How a sweep's figures tell cases apart: coloured by one varied parameter (a colour bar in its
    engineering unit when it is a number, a legend when it is a choice) and faceted by a second one with at
    most :data:`MAX_FACETS` values; by case (legend up to :data:`_LEGEND_CASES`) when no
    parameter varies."""

    def __init__(self, combined: xr.Dataset):
        from matplotlib import colormaps

        n = combined.sizes["case"]
        varied = [p for p in case_parameters(combined) if len(set(combined[p].values.tolist())) > 1]
        numeric = [p for p in varied if np.issubdtype(combined[p].dtype, np.number)]
        self.param = max(numeric, key=lambda p: np.unique(combined[p].values).size) if numeric else \
            (varied[0] if varied else None)
        self.facet = next((p for p in varied if p != self.param
                           and len(set(combined[p].values.tolist())) <= MAX_FACETS), None)
        self.labels = case_labels(combined)
        self.mappable = None  # of the colour bar, when coloured by a number
        if self.param is not None and self.param in numeric:
            shown = combined[self.param].values * shown_parameter_unit(self.param)[1]
            self.colors, self.mappable = _value_colours(shown)
            self.legend = False
        elif self.param is not None:
            categories = list(dict.fromkeys(combined[self.param].values.tolist()))
            self.colors = [colormaps["tab10"](categories.index(x) % 10) for x in combined[self.param].values.tolist()]
            self.labels = [f"{self.param}={x}" for x in combined[self.param].values.tolist()]
            self.legend = True
        else:
            self.colors = _case_colors(n)
            self.legend = n <= _LEGEND_CASES
        self.facets: list[tuple[str | None, list[int]]] = [(None, list(range(n)))]
        if self.facet is not None:
            values = combined[self.facet].values.tolist()
            self.facets = [(parameter_text(self.facet, v), [i for i in range(n) if values[i] == v])
                           for v in dict.fromkeys(values)]

    def finish(self, fig: Figure, axes) -> None:
        """The colour bar (numeric colouring) or one legend of unique labels (otherwise)."""
        if self.mappable is not None:
            bar = fig.colorbar(self.mappable, ax=axes, shrink=0.9)
            bar.set_label(parameter_label(self.param), fontsize="small")
        elif self.legend:
            handles, labels = axes.flat[0].get_legend_handles_labels()
            unique = dict(zip(labels, handles))
            axes.flat[0].legend(unique.values(), unique.keys(), fontsize="x-small")


#: Most values of a parameter that still facets a sweep's figures (one panel column each).
MAX_FACETS = 4


def _curves(combined: xr.Dataset, rows: tuple[tuple[str, str, float], ...], title: str) -> Figure:
    """``rows`` of (variable, axis label, factor) against theta, one column per facet."""
    colours = CaseColours(combined)
    ncols = len(colours.facets)
    fig = Figure(figsize=(5.2 * ncols + 1.8, 3.4 * len(rows) + 0.6), layout="constrained")
    axes = fig.subplots(len(rows), ncols, sharex=True, sharey="row", squeeze=False)
    for col, (facet, members) in enumerate(colours.facets):
        for row, (name, label, factor) in enumerate(rows):
            ax = axes[row, col]
            for i in members:
                ax.plot(combined["theta"], combined[name].isel(case=i) * factor, lw=1.1, color=colours.colors[i],
                        label=colours.labels[i])
            ax.axhline(0.0, color="0.5", lw=0.8)
            theta_axis(ax)
            if row < len(rows) - 1:
                ax.set_xlabel("")
            if col == 0:
                ax.set_ylabel(label)
            if facet and row == 0:
                ax.set_title(facet, fontsize="small")
    colours.finish(fig, axes)
    by = f", colour: {colours.param}" if colours.param else ""
    by += f", one column per {colours.facet}" if colours.facet else ""
    fig.suptitle(f"{title}: {combined.sizes['case']} cases{by}", fontsize="medium")
    return fig


def plot_contact_pressure_comparison(combined: xr.Dataset) -> Figure:
    """Contact pressure (kPa) against theta for every case of a combined result, coloured by a
    varied parameter (colour bar) and faceted by a second (:class:`CaseColours`)."""
    return _curves(combined, (("contact_pressure", "contact pressure λ (kPa)", 1e-3),), "Contact pressure")


def plot_lining_forces_comparison(combined: xr.Dataset) -> Figure:
    """Thrust and moment against theta for every case of a combined result, coloured and
    faceted as :func:`plot_contact_pressure_comparison`."""
    return _curves(combined, (("thrust", "thrust N (kN/m)", 1e-3),
                              ("moment", "moment M (kN·m/m),\n+ = inner fibre compressed", 1e-3)), "Lining forces")


def plot_interaction(cases: list[xr.Dataset], labels: list[str] | None = None, *,
                     combined: xr.Dataset | None = None) -> Figure:
    """N–M diagram of a set of cases and, given ``combined``, max utilization against each parameter.

    Where a case carries its design envelope (``capacity_thrust``, ``capacity_moment``
    on ``envelope``, SPEC §1.3), the envelope is drawn and the stations are the design
    actions (N_Ed, γF·M, with γF = ``design.load_factor`` of the case and N_Ed the governing of γF·N
    and 1.0·N, ``design_thrust``); otherwise the
    stations are the computed (N, M). Up to :data:`_LEGEND_CASES` cases, a colour and a legend entry
    per case (``labels``); more cases of ``combined`` are coloured by a varied parameter (colour
    bar) and the legend names the envelopes and the stations. With ``combined`` results holding
    ``max_utilization`` and varied parameters, one panel per parameter shows ``max_utilization``
    against it (cases sharing the other parameters joined, a legend of them, a title saying so),
    with the limit η = 1: the table a reader uses to pick the thinnest section that passes.
    """
    params = case_parameters(combined) if combined is not None and "max_utilization" in combined else []
    fig = Figure(figsize=(7 + 4 * bool(params), 6 + 0.6 * max(len(params) - 2, 0)), layout="constrained")
    if params:
        grid = fig.add_gridspec(len(params), 2, width_ratios=(7, 4))
        ax = fig.add_subplot(grid[:, 0])
        for row, param in enumerate(params):
            panel = fig.add_subplot(grid[row, 1])
            _scalar_panel(panel, combined, "max_utilization", param, legend=True,
                          title="max utilization η " + lines_per(param, [o for o in params if o != param], "\n"))
            panel.axhline(1.0, color="tab:red", lw=1.0, ls="--")
            panel.set_ylabel("max utilization η (≤ 1 passes)", fontsize="small")
    else:
        ax = fig.add_subplot()
    labels = labels or [str(ds.attrs.get("case_id", i)) for i, ds in enumerate(cases)]
    colors, colour_by = _station_colours(fig, ax, cases, combined)
    with_envelope = [all(v in ds for v in ("capacity_thrust", "capacity_moment")) for ds in cases]
    worst = None
    drawn: list[np.ndarray] = []
    for ds, label, color, design in zip(cases, labels, colors, with_envelope):
        factor = 1.0
        if design:
            factor = load_factor(ds)
            envelope = ds["capacity_thrust"].values
            if not any(e.shape == envelope.shape and np.array_equal(e, envelope) for e in drawn):
                drawn.append(envelope)  # cases sharing a section share one envelope
                draw_envelope(ax, ds, color=color, label=None)
                _label_section(ax, ds, color)
        thrust = ds["design_thrust"].values if design and "design_thrust" in ds else factor * ds["thrust"].values
        ax.plot(factor * ds["moment"].values / 1e3, thrust / 1e3, "o", ms=2.5, color=color,
                label=None if colour_by else label)
        if "utilization" in ds and not np.isnan(ds["utilization"].values).all():
            eta = float(np.nanmax(ds["utilization"].values))
            worst = eta if worst is None else max(worst, eta)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.axvline(0.0, color="0.5", lw=0.8)
    ax.grid(True, alpha=0.3)
    if any(with_envelope):
        ax.set_xlabel("design moment M_Ed (kN·m/m), + = inner fibre compressed")
        ax.set_ylabel("design thrust N_Ed (kN/m), compression up")
        title = (f"N–M interaction of {len(cases)} cases: design envelopes (lines), "
                 "design actions at every station (dots)")
        if worst is not None:
            title += f"\nlargest utilization η = {worst:.3g}" + (" (fails)" if worst > 1 else " (passes)")
    else:
        ax.set_xlabel("moment M (kN·m/m)")
        ax.set_ylabel("thrust N (kN/m, compression +)")
        title = f"Thrust and moment at every station of {len(cases)} cases (no design envelope in these results)"
    _station_legend(ax, len(cases), any(with_envelope), colour_by)
    ax.set_title("\n".join(textwrap.fill(line, 80) for line in title.split("\n")), fontsize="medium")
    return fig


def _station_colours(fig: Figure, ax, cases: list[xr.Dataset], combined: xr.Dataset | None) -> tuple[list, str | None]:
    """The colour of each case's stations and envelope, and the parameter they are coloured by
    (None: a colour per case). Over :data:`_LEGEND_CASES` cases of a sweep, by the numeric varied
    parameter with the most values (a section's envelope then has its thickness' colour), with a
    colour bar in engineering units."""
    varied = [] if combined is None or len(cases) <= _LEGEND_CASES else [
        p for p in case_parameters(combined)
        if np.issubdtype(combined[p].dtype, np.number) and np.unique(combined[p].values).size > 1]
    if not varied:
        return _case_colors(len(cases)), None
    param = max(varied, key=lambda p: np.unique(combined[p].values).size)
    colors, mappable = _value_colours(combined[param].values.astype(float) * shown_parameter_unit(param)[1])
    fig.colorbar(mappable, ax=ax, shrink=0.8, pad=0.01).set_label(parameter_label(param), fontsize="small")
    return colors, param


def _station_legend(ax, count: int, envelopes: bool, colour_by: str | None) -> None:
    """The N–M legend: each case (up to :data:`_LEGEND_CASES`), or what the colours mean, and
    what the lines and dots are."""
    from matplotlib.lines import Line2D

    handles, _ = ax.get_legend_handles_labels()  # the cases' stations, when a colour is a case
    if colour_by or count > _LEGEND_CASES:
        by = f", colour: {colour_by}" if colour_by else f", one colour per case ({count})"
        handles = [Line2D([], [], ls="", marker="o", ms=2.5, color="0.35", label="design actions at the stations" + by
                          if envelopes else "(M, N) at the stations" + by)]
    if envelopes:
        handles.append(Line2D([], [], color="0.35", lw=1.2, label="design envelope N_Rd–M_Rd of a section"))
    ax.legend(handles=handles, fontsize="x-small", markerscale=2)


def _label_section(ax, ds: xr.Dataset, color) -> None:
    """Name the section (thickness, reinforcement) at the top of its envelope."""
    import json

    spec = json.loads(ds.attrs.get("case_spec", "{}"))
    if "thickness" not in spec.get("geometry", {}):
        return
    area = spec.get("design", {}).get("reinforcement_area", 0.0)
    text = f"h = {spec['geometry']['thickness']:g} m" + (f", As = {area * 1e4:g} cm²/m" if area > 0 else ", plain")
    k = int(np.argmax(ds["capacity_thrust"].values))
    ax.annotate(text, (ds["capacity_moment"].values[k] / 1e3, ds["capacity_thrust"].values[k] / 1e3),
                xytext=(0, 2), textcoords="offset points", ha="center", va="bottom", fontsize="x-small",
                color=color)


def _format_value(value) -> str:
    return f"{value:.4g}" if isinstance(value, (int, float, np.number)) else str(value)


def _parameter_axis(values: np.ndarray) -> tuple[np.ndarray, list[str] | None]:
    """Positions for parameter ``values``: themselves if numeric, else category indices and labels."""
    if np.issubdtype(values.dtype, np.number):
        return values.astype(float), None
    categories = list(dict.fromkeys(values.tolist()))
    return np.array([categories.index(v) for v in values.tolist()], dtype=float), categories


#: Most lines of a panel that still get a legend (more: a colour bar when they differ by one number).
_LEGEND_LINES = 10


def _scalar_panel(ax, combined: xr.Dataset, scalar: str, param: str, *, legend: bool,
                  title: str | None = None, facet: str | None = None) -> None:
    """``scalar`` against ``param``, both in engineering units; cases sharing the other varied
    parameters (but ``facet``, the same in all of ``combined``: one panel's) joined by a line
    labelled with their values (a legend of up to :data:`_LEGEND_LINES` lines when ``legend``; many
    lines of one other number: coloured by it, with a colour bar)."""
    unit, factor = display_unit(combined[scalar].attrs.get("units", ""), scalar)
    y = combined[scalar].values.astype(float) * factor
    x, categories = _parameter_axis(combined[param].values)
    if categories is None:
        x = x * shown_parameter_unit(param)[1]
    others = [p for p in case_parameters(combined) if p not in (param, facet)]
    groups = _groups(combined, others)
    colors = _case_colors(len(groups))
    by_value = len(groups) > 6 and len(others) == 1 and np.issubdtype(combined[others[0]].dtype, np.number)
    if by_value:  # many lines of one other number: coloured by it, with a colour bar
        colors, mappable = _value_colours([float(key[0]) * shown_parameter_unit(others[0])[1] for key in groups])
        bar = ax.figure.colorbar(mappable, ax=ax, pad=0.01)
        bar.set_label(parameter_label(others[0]), fontsize="xx-small")
        bar.ax.tick_params(labelsize="xx-small")
    if _points_only(groups):  # one collection (a line object a case made an 84-panel figure 14 s)
        first = [members[0] for members in groups.values()]
        ax.scatter(x[first], y[first], s=9, c=list(colors), linewidths=0)
    else:
        for color, (key, members) in zip(colors, groups.items()):
            members = sorted(members, key=lambda i: x[i])
            ax.plot(x[members], y[members], "o-", ms=3, lw=1, color=color,
                    label=", ".join(parameter_text(o, v) for o, v in zip(others, key)))
    if legend and others and len(groups) <= _LEGEND_LINES:
        ax.legend(fontsize="xx-small", ncol=1 if len(groups) <= 5 else 2)
    if categories is not None:
        ax.set_xticks(range(len(categories)), categories, fontsize="x-small")
    else:
        if np.all(x > 0) and x.max() > 5 * x.min():  # e.g. ground stiffness: a factor per step
            ax.set_xscale("log")
            ax.minorticks_off()
        if np.unique(x).size <= 8:  # the values swept, not matplotlib's round numbers
            ax.set_xticks(np.unique(x), [f"{v:.3g}" for v in np.unique(x)], fontsize="x-small")
    if title:
        ax.set_title(title, fontsize="x-small")
    ax.set_xlabel(parameter_label(param), fontsize="small")
    ax.set_ylabel(f"{scalar}" + (f" ({unit})" if unit else ""), fontsize="small")
    ax.tick_params(labelsize="x-small")
    ax.grid(True, alpha=0.3)


#: Most values of a third varied parameter that get a panel each (more: one line per combination).
_FACETS = 4


def facet_parameter(params: list[str], param: str, combined: xr.Dataset) -> str | None:
    """With three or more varied parameters, the one whose values get a panel each in the panels
    against ``param`` ("η against t, one line per E, one panel per K0"): of the others, the one with
    the fewest values (the last of equals), if it has at most :data:`_FACETS`; else None."""
    others = [p for p in params if p != param]
    if len(others) < 2:
        return None
    counts = {o: len(dict.fromkeys(combined[o].values.tolist())) for o in others}
    best = min(reversed(others), key=counts.get)
    return best if counts[best] <= _FACETS else None


def _rows(combined: xr.Dataset, scalars: list[str], params: list[str],
          facets: dict[str, str | None]) -> dict[tuple[str, str], list[tuple]]:
    """Per (scalar, parameter) its panels' ``(facet, value)``: one per value of the parameter's facet
    (:func:`facet_parameter`), else the one ``(None, None)``."""
    rows = {}
    for scalar in scalars:
        for param in params:
            facet = facets[param]
            values = [None] if facet is None else list(dict.fromkeys(combined[facet].values.tolist()))
            rows[(scalar, param)] = [(facet, v) for v in values]
    return rows


def plot_scalars(combined: xr.Dataset, scalars: list[str] | None = None) -> Figure:
    """Each summary scalar against each varied parameter (one panel per pair).

    Cases that share the values of the other varied parameters are joined by a line
    (one colour per combination of those values, a legend on the first panel against each
    parameter), so in a grid sweep each line shows the effect of one parameter alone; with three
    or more varied parameters, the one with the fewest values (up to four) gets a panel per value
    instead ("η against t, one line per E, one panel per K0"). The title says what the lines and
    panels are. Parameters and results are in engineering units. Scalars with the same value in
    every case are listed in the title instead of plotted.

    Parameters
    ----------
    combined : combined results (:func:`workflows.open_results`).
    scalars : names of the scalars to show; default every numeric scalar along ``case``,
        the solver's diagnostics (bolt, iterations, residual, time) last.
    """
    params = case_parameters(combined)
    if scalars is None:
        scalars = [n for n, v in data_variables(combined) if v.dims == ("case",) and v.dtype.kind in "biuf"]
        scalars.sort(key=lambda name: name in DIAGNOSTICS)
    constant = [s for s in scalars if np.allclose(combined[s].values.astype(float),
                                                  float(combined[s].values[0]), rtol=1e-9, atol=0)]
    facets = {p: facet_parameter(params, p, combined) for p in params}
    rows = _rows(combined, [s for s in scalars if s not in constant], params, facets)
    if not rows:
        fig = Figure(figsize=(6, 2), layout="constrained")
        fig.text(0.5, 0.5, "no varied parameter, or no scalar that changes: nothing to plot",
                 ha="center", va="center")
        return fig
    faceted = any(f is not None for f in facets.values())
    if faceted:  # a row per scalar and parameter, its facets side by side
        ncols, nrows = max(map(len, rows.values())), len(rows)
    else:  # whole rows of scalars: 4 panels a row for one or two parameters, 3 for three
        ncols = len(params) if len(params) == 3 else 4
        nrows = -(-len(rows) // ncols)
    drawn = "; ".join(_drawn_against(combined, p, [o for o in params if o not in (p, facets[p])])
                      + (f", one panel per {facets[p]}" if facets[p] else "") for p in params)
    title = f"Each result against each varied parameter, {combined.sizes['case']} cases: {drawn}"
    title = "\n".join(textwrap.wrap(title + (" (legend)" if len(params) > 1 else ""), 36 * ncols))
    if constant:
        shown = ", ".join(f"{s} = {shown_value(combined[s].values[0], combined[s].attrs.get('units'), s)}"
                          for s in constant)
        title += "\nthe same in every case: " + "\n".join(textwrap.wrap(shown, 30 * ncols))
    fig = _panel_grid(ncols, nrows, title_lines=title.count("\n") + 1)
    placed = _place(rows, fig.subplots(nrows, ncols, squeeze=False), faceted)
    first = {}
    plotted = combined[list(dict.fromkeys(scalar for scalar, _ in placed))]  # a facet's cases: a cheap isel
    for (scalar, param), members in placed.items():
        for ax, (facet, value) in members:
            sub = plotted if facet is None else plotted.isel(case=np.flatnonzero(
                np.asarray(plotted[facet].values.tolist(), dtype=object) == value))
            shown = None if facet is None else parameter_text(facet, value)
            _scalar_panel(ax, sub, scalar, param, legend=first.setdefault(param, ax) is ax, title=shown,
                          facet=facet)
        if len(members) > 1:  # a row's facets on one scale: the panels compare at a glance
            axes = [ax for ax, _ in members]
            low, high = min(ax.get_ylim()[0] for ax in axes), max(ax.get_ylim()[1] for ax in axes)
            for ax in axes:
                ax.set_ylim(low, high)
    fig.suptitle(title, fontsize="small", y=1.0 - 0.08 / fig.get_figheight(), va="top")
    return fig


#: The scalars figure's panel cell (inches): the axes and, around them, room for the tick labels,
#: the axis labels and a facet's title (fixed, not a layout engine's: with ~100 panels
#: constrained layout was half of the figure's time, 7 of 13 s)
_CELL = (3.4, 2.4)
_MARGINS = {"left": 0.78, "right": 0.12, "bottom": 0.62, "top": 0.26}  # of each cell
_TITLE_LINE = 0.16  # inches a line of the figure's title takes (small type)


def _panel_grid(ncols: int, nrows: int, *, title_lines: int) -> Figure:
    """A figure of ``nrows`` × ``ncols`` panel cells (:data:`_CELL`) under a title of ``title_lines``
    lines, its subplot grid placed in inches: every cell keeps :data:`_MARGINS` around its axes."""
    title = 0.15 + _TITLE_LINE * title_lines
    width, height = _CELL[0] * ncols, _CELL[1] * nrows + title
    fig = Figure(figsize=(width, height))
    m = _MARGINS
    inner_w, inner_h = _CELL[0] - m["left"] - m["right"], _CELL[1] - m["bottom"] - m["top"]
    fig.subplots_adjust(left=m["left"] / width, right=1.0 - m["right"] / width,
                        bottom=m["bottom"] / height, top=1.0 - (title + m["top"]) / height,
                        wspace=(m["left"] + m["right"]) / inner_w, hspace=(m["bottom"] + m["top"]) / inner_h)
    return fig


def _groups(combined: xr.Dataset, others: list[str]) -> dict[tuple, list[int]]:
    """The cases (indices) by their values of the parameters ``others``: a panel's lines."""
    values = [combined[o].values.tolist() for o in others]
    groups: dict[tuple, list[int]] = {}
    for i in range(combined.sizes["case"]):
        groups.setdefault(tuple(v[i] for v in values), []).append(i)
    return groups


def _points_only(groups: dict[tuple, list[int]]) -> bool:
    """A sampled sweep's panel: more cases than a legend takes and no two sharing the other
    parameters, so there are no lines to draw, only points."""
    return len(groups) > _LEGEND_LINES and all(len(members) == 1 for members in groups.values())


def _drawn_against(combined: xr.Dataset, param: str, others: list[str]) -> str:
    """What the panels against ``param`` draw (:func:`_scalar_panel`): one line per combination
    of the ``others``, or one point per case."""
    if others and _points_only(_groups(combined, others)):
        return f"against {param}: one point per case"
    return lines_per(param, others)


def _place(rows: dict[tuple, list[tuple]], axes: np.ndarray, faceted: bool) -> dict[tuple, list[tuple]]:
    """Each row's panels with their axes: a faceted figure gives each (scalar, parameter) a row of
    its own (its facets side by side, the rest of the row hidden); otherwise the panels fill the
    rows in order."""
    flat = axes.ravel()
    if not faceted:
        for ax in flat[len(rows):]:
            ax.set_visible(False)
        return {key: [(ax, members[0])] for ax, (key, members) in zip(flat, rows.items())}
    for r, members in enumerate(rows.values()):
        for ax in axes[r, len(members):]:
            ax.set_visible(False)
    return {key: list(zip(axes[r, :len(members)], members)) for r, (key, members) in enumerate(rows.items())}


#: Plots of a sweep (combined results of its finished cases), by name. ``interaction``
#: needs the cases themselves (their envelopes are not combined): see
#: :func:`workflows.artifacts.render_sweep_plot`.
SWEEP_PLOTS: dict[str, Callable[[xr.Dataset], Figure]] = {
    "contact_pressure": plot_contact_pressure_comparison,
    "lining_forces": plot_lining_forces_comparison,
    "scalars": plot_scalars,
}
SWEEP_PLOT_NAMES = ("contact_pressure", "lining_forces", "interaction", "scalars")
