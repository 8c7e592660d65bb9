"""A study's figure: the estimate against FE calls (β and its 95 % interval) and the
importance factors α²."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from scipy import stats


def _beta(p):
    p = np.asarray(p, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((p > 0) & (p < 1), -stats.norm.ppf(np.clip(p, 1e-300, 1 - 1e-16)), np.nan)


def plot_study(record) -> Figure:
    """Convergence (left) and importance (right) of a :class:`~.records.ReliabilityRecord`."""
    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    left, right = fig.subplots(1, 2, width_ratios=[2.2, 1])
    history = record.history
    iterates = [h for h in history if "beta" in h and "probability" not in h]
    if iterates:
        left.plot([h["calls"] for h in iterates], [h["beta"] for h in iterates], "o-", color="C1",
                  label="design point distance |u| (FORM)")
    estimates = [h for h in history if h.get("probability") is not None]
    if estimates:
        calls = np.array([h["calls"] for h in estimates])
        left.plot(calls, _beta([h["probability"] for h in estimates]), ".-", color="C0", label="β = −Φ⁻¹(P)")
        if all("ci_low" in h for h in estimates):
            low = _beta([h["ci_high"] for h in estimates])
            high = _beta([h["ci_low"] for h in estimates])
            left.fill_between(calls, low, high, color="C0", alpha=0.2, label="95 % interval")
    if record.beta is not None:
        left.axhline(record.beta, color="k", lw=0.8, ls="--", label=f"β = {record.beta:.3f}")
    left.set_xlabel("FE calls")
    left.set_ylabel("reliability index β")
    left.set_title(f"{record.study.get('method', '')}: {record.calls} of {record.budget} calls", fontsize=10)
    if left.get_legend_handles_labels()[0]:
        left.legend(fontsize=8, loc="best")
    left.grid(alpha=0.3)
    if record.importance:
        names = list(record.importance)
        y = np.arange(len(names))
        right.barh(y, [record.importance[n] for n in names], color="C2")
        right.set_yticks(y, names, fontsize=8)
        right.set_xlim(0, 1)
        right.invert_yaxis()
    else:
        right.text(0.5, 0.5, "no design point yet", ha="center", va="center", transform=right.transAxes)
        right.set_yticks([])
    right.set_xlabel("importance α²")
    return fig
