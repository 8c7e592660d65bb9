"""Figures of a sweep's analyses (SPEC §8): sensitivity bars and the reliability histogram."""
from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from solver.results.variables import SCALARS

from .units import display_unit


def png(figure: Figure, dpi: int = 110) -> bytes:
    """A figure as PNG bytes (what the service answers with)."""
    import io

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def _output_label(name: str) -> tuple[str, float]:
    unit, factor = display_unit(SCALARS[name][0], name)[:2] if name in SCALARS else ("", 1.0)
    long_name = SCALARS.get(name, ("", name))[1]
    return (f"{long_name} ({unit})" if unit and unit != "1" else long_name), factor


def plot_sensitivity(ds: xr.Dataset) -> Figure:
    """Horizontal bars: first-order and total index of each varied parameter, with their 95 %
    intervals; the largest total index at the top."""
    names = [str(p) for p in ds["parameter"].values]
    first, total = ds["first_order"].values, ds["total_order"].values
    order = np.argsort(np.nan_to_num(total, nan=-1) + 1e-6 * np.nan_to_num(first))
    fig = Figure(figsize=(7.5, 1.2 + 0.55 * len(names)), layout="constrained")
    ax = fig.add_subplot()
    y = np.arange(len(names))
    ax.barh(y + 0.18, first[order], 0.36, xerr=ds["first_order_ci"].values[order], color="#4C72B0",
            label="first order", capsize=3, gid="first_order")
    if np.isfinite(total).any():
        ax.barh(y - 0.18, total[order], 0.36, xerr=ds["total_order_ci"].values[order], color="#DD8452",
                label="total", capsize=3, gid="total_order")
    floor = float(ds.attrs.get("noise_floor", 0.0))
    if floor > 0:
        ax.axvspan(0, floor, color="0.85", zorder=0, label=f"noise floor ({floor:.2f}: a dummy parameter)",
                   gid="noise_floor")
    ax.set_yticks(y, [names[i] for i in order])
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlim(min(-0.05, float(np.nanmin(first)) - 0.05), 1.05)
    ax.set_xlabel("sensitivity index (share of the output's variance)")
    ax.set_title(f"Sensitivity of {_output_label(ds.attrs['output'])[0]}\n"
                 f"{ds.attrs['samples']} cases, {ds.attrs['method']}; bars: 95 % intervals", fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(axis="x", alpha=0.3)
    return fig


def plot_reliability(r: dict) -> Figure:
    """The distribution of the output over the cases (histogram and empirical exceedance
    curve), the limit, and the probability of exceeding it with its interval and β."""
    label, factor = _output_label(r["output"])
    values = np.asarray(r["values"], float) * factor
    limit = r["limit"] * factor
    fig = Figure(figsize=(7.5, 4.2), layout="constrained")
    ax = fig.add_subplot()
    ax.hist(values, bins=min(40, max(8, int(np.sqrt(values.size)))), color="#4C72B0", alpha=0.8,
            edgecolor="white", gid="histogram")
    ax.axvline(limit, color="#C44E52", lw=2, gid="limit", label=f"limit {r['limit']:g}")
    ax.set_xlabel(label)
    ax.set_ylabel("cases")
    twin = ax.twinx()
    xs = np.sort(values)
    twin.step(xs, 1.0 - np.arange(1, xs.size + 1) / xs.size, where="post", color="k", lw=1, gid="exceedance")
    twin.set_ylabel("fraction of cases above")
    twin.set_ylim(0, 1.02)
    beta = "β = —" if r["beta"] is None else f"β = {r['beta']:.2f}"
    fig.suptitle(f"P({r['output']} > {r['limit']:g}) = {r['probability']:.3g} "
                 f"[{r['ci_low']:.3g}, {r['ci_high']:.3g}] (95 %), {beta}; {r['samples']} cases", fontsize=10)
    if r.get("note"):
        import textwrap

        ax.set_title("\n".join(textwrap.wrap(r["note"], 110)), fontsize=7, color="#8B0000")
    ax.legend(loc="upper left", fontsize=8)
    return fig


def plot_search(search: dict, trials: list[dict], value) -> Figure:
    """A search converging: the value tried at each trial (passing or not) with the bracket
    that remains, and the worst output of each trial against the requirement."""
    need = search["require"]
    fig = Figure(figsize=(7.5, 4.6), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    k = np.arange(1, len(trials) + 1)
    values = np.array([t["value"] for t in trials], float)
    ok = np.array([t["satisfied"] for t in trials], bool)
    lo, hi = [], []
    for i in range(len(trials)):
        seen = trials[: i + 1]
        passed = [t["value"] for t in seen if t["satisfied"]]
        below = [t["value"] for t in seen if not t["satisfied"] and (not passed or t["value"] < min(passed))]
        hi.append(min(passed) if passed else search["high"])
        lo.append(max(below) if below else search["low"])
    top.fill_between(k, lo, hi, step="mid", color="#4C72B0", alpha=0.15, label="bracket left")
    top.plot(k[ok], values[ok], "o", color="#55A868", label="meets", gid="passing")
    top.plot(k[~ok], values[~ok], "x", color="#C44E52", ms=8, label="fails", gid="failing")
    if value is not None:
        top.axhline(value, color="k", lw=0.8, ls="--", label=f"answer {value:.4g}")
    top.set_ylabel(search["parameter"])
    top.legend(fontsize=8, loc="best")
    top.set_title(f"{search['name']}: smallest {search['parameter']} with {need['output']} "
                  + (f"≤ {need['at_most']:g}" if need.get("at_most") is not None else f"≥ {need['at_least']:g}"),
                  fontsize=10)
    worst = np.array([np.nan if t["worst"] is None else t["worst"] for t in trials], float)
    bottom.plot(k, worst, "o-", color="#4C72B0", gid="worst")
    bound = need.get("at_most") if need.get("at_most") is not None else need.get("at_least")
    bottom.axhline(bound, color="#C44E52", lw=1.5, label="requirement")
    bottom.set_ylabel(f"worst {need['output']}")
    bottom.set_xlabel("trial")
    bottom.set_xticks(k)
    bottom.legend(fontsize=8)
    return fig
