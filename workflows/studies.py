"""Studies beyond grids (SPEC §8): the sensitivity of a result to a sweep's varied parameters,
the probability that it exceeds a limit, and the search for the smallest design value that
meets a requirement over a set of grounds.

Sensitivity: a sweep's own sample, whatever drew it (Sobol' points, a Latin hypercube, Monte
Carlo, even a grid), is analysed by SALib's HDMR (high-dimensional model representation: a
least-squares fit of first- and second-order component functions, which works on any sample
of at least 300 points, first-order and total indices with bootstrap intervals); a smaller
sample gets the moment-independent *delta* method's first-order (Sobol') index alone, with the
total index NaN. Saltelli's estimator (``SALib.analyze.sobol``) would need its own design
(N·(2d+2) points along radial lines), which is not the sample a sweep has.

Reliability: the fraction of the cases whose result exceeds the limit estimates the
probability, with the exact (Clopper–Pearson) 95 % interval of a binomial proportion and the
reliability index β = -Φ⁻¹(P). It is a probability only if the cases are a random sample of
the uncertain parameters (a ``random``, ``lhs`` or ``sobol`` sweep); with few exceedances the
interval is wide, and the answer says so.

Search: bisection on the design parameter, assuming the requirement, once met, stays met for
larger values (a thicker lining, a stronger concrete). Each trial is a sweep (the ``over``
grounds with the parameter at the trial value), stored like any other, so a search run again
finds its trials' cases done and resumes where it was.
"""
from __future__ import annotations

import contextlib
import copy
import io
import logging
import math
import threading
from typing import Any, Literal, Optional

import numpy as np
import xarray as xr
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from solver.errors import field_errors
from solver.results.variables import SCALARS
from solver.spec import CaseSpec

from .parameters import (canonical_path, flat_name, flat_parameters, is_parameter, parameter_path, set_parameter,
                         varying_parameters)
from .result_store import StoreLike, as_store
from .sweep import Sweep, SweepError, check_structure, expand_sweep, run_sweep

logger = logging.getLogger(__name__)

#: Fewest samples HDMR accepts (SALib); below it the delta method's first-order index only.
HDMR_MIN_SAMPLES = 300
#: Fewest done cases a reliability estimate is made from.
MIN_SAMPLES = 32
#: Fewest done cases a sensitivity estimate is made from: the delta method's first-order index
#: of a parameter that changes nothing (γF for the moment, three parameters, LHS) is 0.12-0.23
#: at 64 cases, 0.07 at 96, 0.013 ± 0.05 from 128 on.
SENSITIVITY_MIN_SAMPLES = 128
#: Exceedances (or non-exceedances) below which a reliability estimate is called small.
FEW = 10
#: A search's tolerance must span at least this many units in the last place of its bounds: the
#: bisection then always has a new value strictly inside its bracket.
RESOLVABLE_ULPS = 8
#: Longest sweep name (:class:`workflows.sweep.Sweep`): a trial's name is the search's, cut to fit.
SWEEP_NAME_CHARS = 200


class StudyError(ValueError):
    """A study's input is wrong: ``errors`` is a list of ``(field, reason)``."""

    def __init__(self, errors: list[tuple[str, str]]):
        self.errors = errors
        super().__init__("; ".join(f"{f}: {r}" for f, r in errors))


def check_output(output: str, field: str = "output") -> str:
    if output not in SCALARS:
        raise StudyError([(field, f"{output!r} is not a result scalar (one of {', '.join(sorted(SCALARS))})")])
    return output


def study_sample(root: StoreLike, case_ids: list[str], output: str, minimum: int = MIN_SAMPLES):
    """The done cases of ``case_ids``: the varied parameters (paths), their values (n, d), the
    output (n,) and how many cases are not done."""
    check_output(output)
    store = as_store(root)
    stored = store.file_keys()
    done = [c for c in case_ids if c in stored]
    if len(done) < minimum:
        raise StudyError([("case_ids", f"{len(done)} of the {len(case_ids)} cases are done; this analysis needs at "
                                       f"least {minimum}")])
    combined = store.open_results(done)
    params = [flat_parameters(str(s)) for s in combined["case_spec"].values]
    names = [n for n in varying_parameters(params)
             if all(isinstance(p[n], (int, float)) and not isinstance(p[n], bool) for p in params)]
    X = np.array([[float(p[n]) for n in names] for p in params]).reshape(len(done), len(names))
    return [parameter_path(n) for n in names], X, combined[output].values.astype(float), len(case_ids) - len(done)


#: one analysis at a time seeds numpy's global generator (:func:`_seeded`)
_GLOBAL_RNG = threading.Lock()


@contextlib.contextmanager
def _seeded(seed: int):
    """numpy's global generator seeded with ``seed`` (0 included), one caller at a time, its
    state put back after. SALib's HDMR and delta estimators draw their bootstrap from the global
    generator and seed it only for a truthy ``seed``: with the default 0 the same sample gave
    other indices each time, and two analyses in one process's threads would share the draws."""
    with _GLOBAL_RNG:
        state = np.random.get_state()
        np.random.seed(seed)
        try:
            yield
        finally:
            np.random.set_state(state)


def sensitivity(root: StoreLike, case_ids: list[str], output: str, *, seed: int = 0) -> xr.Dataset:
    """First-order and total sensitivity indices of the result scalar ``output`` to each
    parameter that varies across the done cases of ``case_ids`` (see the module's notes).
    The attribute ``noise_floor`` is, for the delta method, the index (plus its half-width) of
    a dummy parameter that changes nothing: an index below it cannot be told from zero (0
    for HDMR, whose indices of such a parameter stay below 0.02 from 300 cases)."""
    names, X, Y, missing = study_sample(root, case_ids, output, SENSITIVITY_MIN_SAMPLES)
    if not names:
        raise StudyError([("case_ids", "no numeric parameter varies across these cases")])
    finite = np.isfinite(Y)
    X, Y = X[finite], Y[finite]
    d, n = len(names), len(Y)
    first, first_ci, total, total_ci = (np.full(d, np.nan) for _ in range(4))
    floor = 0.0
    method = "hdmr" if n >= HDMR_MIN_SAMPLES else "delta"  # the estimator the sample suits
    if np.ptp(Y) <= 1e-12 * max(float(np.max(np.abs(Y))), 1e-300):  # a constant output depends on nothing
        first[:], first_ci[:], total[:], total_ci[:] = 0.0, 0.0, 0.0, 0.0
        method = "constant output"
    else:
        problem = {"num_vars": d, "names": names,
                   "bounds": [[float(X[:, i].min()), float(X[:, i].max())] for i in range(d)]}
        si = None
        if method == "hdmr":
            from SALib.analyze import hdmr

            try:
                with _seeded(seed):
                    si = hdmr.analyze(problem, X, Y, maxorder=2 if d > 1 else 1)
            except (RuntimeError, ValueError, np.linalg.LinAlgError) as exc:  # too many terms for the sample
                logger.warning("HDMR failed on %d cases of %d parameters (%s): the delta method instead", n, d, exc)
                method = "delta"
        if si is not None:
            terms = list(si["Term"])
            for i, name in enumerate(names):
                k = terms.index(name)
                first[i], first_ci[i] = si["S"][k], si["S_conf"][k]
                total[i], total_ci[i] = si["ST"][i], si["ST_conf"][i]
        elif method == "delta":
            from SALib.analyze import delta

            # a dummy parameter (independent of everything) measures the estimator's floor on
            # this sample: an index at or below the dummy's cannot be told from zero
            dummy = np.random.default_rng(seed).random(n)
            with_dummy = {"num_vars": d + 1, "names": names + ["dummy"], "bounds": problem["bounds"] + [[0.0, 1.0]]}
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()), \
                    _seeded(seed):  # its notices; its bootstrap
                # method="sobol": the first-order index alone (the moment-independent delta, which
                # is not reported, is its kernel-density part: 25 times the cost)
                si = delta.analyze(with_dummy, np.column_stack([X, dummy]), Y, method="sobol")
            first, first_ci = np.asarray(si["S1"][:d], float), np.asarray(si["S1_conf"][:d], float)
            floor = float(si["S1"][d] + si["S1_conf"][d])
            method = "delta (first order only)"
    ds = xr.Dataset(
        {"first_order": ("parameter", first, {"long_name": "first-order sensitivity index"}),
         "first_order_ci": ("parameter", first_ci, {"long_name": "95 % half-width of the first-order index"}),
         "total_order": ("parameter", total, {"long_name": "total sensitivity index"}),
         "total_order_ci": ("parameter", total_ci, {"long_name": "95 % half-width of the total index"})},
        coords={"parameter": names},
        attrs={"output": output, "samples": n, "method": method, "not_done": missing,
               "noise_floor": floor})
    return ds


def reliability(root: StoreLike, case_ids: list[str], output: str = "max_utilization",
                limit: float = 1.0) -> dict[str, Any]:
    """Probability that ``output`` exceeds ``limit`` over the done cases of ``case_ids``: the
    fraction, its exact 95 % interval, β = -Φ⁻¹(P) (None where P is 0 or 1) and a note when the
    estimate rests on few cases. Cases whose ``output`` is NaN (not defined for them) are left
    out of the sample and counted as ``undefined``; fewer than :data:`MIN_SAMPLES` defined
    values raise :class:`StudyError` naming ``output``."""
    from scipy import stats

    if not math.isfinite(limit):
        raise StudyError([("limit", "must be a finite number")])
    _, _, Y, missing = study_sample(root, case_ids, output)
    # a NaN output is not defined for that case (bolt_theta of a bonded interface): neither safe
    # nor failed, so it is no sample of the event (counting it below the limit made P = 0 of nothing)
    undefined = int(np.count_nonzero(np.isnan(Y)))
    Y = Y[~np.isnan(Y)]
    if Y.size < MIN_SAMPLES:
        raise StudyError([("output", f"{output} is defined (not NaN) in {Y.size} of the {Y.size + undefined} done "
                                     f"cases; a probability needs at least {MIN_SAMPLES}")])
    n = int(Y.size)
    k = int(np.sum(Y > limit))
    p = k / n
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")

    def beta(q: float) -> Optional[float]:
        return None if q <= 0.0 or q >= 1.0 else float(-stats.norm.ppf(q))

    note = None
    if min(k, n - k) < FEW:
        note = (f"{k} of {n} cases exceed {limit:g}: too few {'exceedances' if k < FEW else 'non-exceedances'} "
                "for a tight estimate; the interval is exact but wide (more samples narrow it)")
    if undefined:
        note = " ".join(filter(None, [f"{output} is not defined (NaN) in {undefined} done cases: left out of the "
                                      "sample", note]))
    return {"output": output, "limit": float(limit), "probability": p, "ci_low": float(ci.low),
            "ci_high": float(ci.high), "beta": beta(p), "beta_ci": [beta(float(ci.high)), beta(float(ci.low))],
            "samples": n, "exceedances": k, "not_done": missing, "undefined": undefined, "note": note,
            "values": Y.tolist()}


# -- search -------------------------------------------------------------------------------------


def _first_error(exc: ValidationError) -> str:
    """The first field error of ``exc`` as ``path: reason``."""
    return "{}: {}".format(*field_errors(exc)[0]).lstrip(": ")


class Requirement(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    output: str = Field("max_utilization", description="a result scalar (SPEC §3)")
    at_most: Optional[float] = Field(None, allow_inf_nan=False)
    at_least: Optional[float] = Field(None, allow_inf_nan=False)

    @model_validator(mode="after")
    def _one_bound(self) -> "Requirement":
        check_output(self.output, "output")
        if (self.at_most is None) == (self.at_least is None):
            raise ValueError("at_most: give exactly one of at_most and at_least")
        return self

    def worst(self, values: np.ndarray) -> float:
        return float(np.max(values) if self.at_most is not None else np.min(values))

    def met(self, worst: float) -> bool:
        return worst <= self.at_most if self.at_most is not None else worst >= self.at_least


class Search(BaseModel):
    """The smallest value of ``parameter`` in [low, high] (to ``tolerance``) for which
    ``require`` holds in every case of ``over`` (SPEC §8)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(..., min_length=1, max_length=200)
    base: dict[str, Any] = Field(default_factory=dict)
    parameter: str = Field(..., description="a numeric case field, e.g. geometry.thickness")
    low: float = Field(..., allow_inf_nan=False)
    high: float = Field(..., allow_inf_nan=False)
    tolerance: float = Field(..., gt=0, allow_inf_nan=False)
    require: Requirement = Field(default_factory=lambda: Requirement(at_most=1.0))
    over: dict[str, Any] = Field(default_factory=dict, description="the vary of a sweep (SPEC §5, §8)")
    mode: Literal["grid", "zip", "sobol", "lhs", "random"] = "grid"
    samples: Optional[int] = None
    seed: Optional[int] = None

    @model_validator(mode="after")
    def _consistent(self) -> "Search":
        """What can be checked without expanding the grounds (cheap: a posted search is
        validated before the service answers anything else). The grounds' cases themselves are
        validated when a trial is expanded (:func:`expand_trial`)."""
        if not self.low < self.high:
            raise ValueError(f"high: must exceed low ({self.low} >= {self.high})")
        if not self.tolerance < self.high - self.low:
            raise ValueError(f"tolerance: must be less than high - low ({self.high - self.low:g})")
        finest = RESOLVABLE_ULPS * math.ulp(max(abs(self.low), abs(self.high)))
        if self.tolerance < finest:  # bisection would try the same value again and again
            raise ValueError(f"tolerance: must be at least {finest:.3g} ({RESOLVABLE_ULPS} units in the last place "
                             "of the bounds): no finer step between them can be represented")
        if self.parameter in self.over:
            raise ValueError(f"over: varies {self.parameter}, the parameter searched")
        path = canonical_path(self.parameter)
        try:
            current = flat_parameters(CaseSpec.model_validate(self.base)).get(flat_name(path))
        except ValidationError as exc:
            raise ValueError(f"base: {_first_error(exc)}") from None
        if not is_parameter(path, self.base) or isinstance(current, bool) or not isinstance(current, (int, float)):
            raise ValueError(f"parameter: {self.parameter!r} is not a numeric case field")
        for end in ("low", "high"):  # both ends of the range are cases of their own
            case = copy.deepcopy(self.base)
            set_parameter(case, path, float(getattr(self, end)))
            try:
                CaseSpec.model_validate(case)
            except ValidationError as exc:
                raise ValueError(f"{end}: {getattr(self, end):g} is not a valid {self.parameter}: "
                                 f"{_first_error(exc)}") from None
        try:  # the grounds' table as a sweep checks it before expanding: paths, lists, size
            check_structure(self.trial_sweep(self.low))
        except ValidationError as exc:
            raise ValueError(f"over: {_first_error(exc)}") from None
        except SweepError as exc:
            raise ValueError("over: {}: {}".format(*exc.errors[0])) from None
        return self

    def trial_sweep(self, value: float) -> Sweep:
        """The sweep of one trial: every ``over`` case with the parameter at ``value``."""
        base = copy.deepcopy(self.base)
        set_parameter(base, canonical_path(self.parameter), float(value))
        extra = {k: getattr(self, k) for k in ("samples", "seed") if getattr(self, k) is not None}
        label = f": {self.parameter} = {value:.6g}"
        name = self.name[:SWEEP_NAME_CHARS - len(label) - 1] + "…" if len(self.name) + len(label) > SWEEP_NAME_CHARS \
            else self.name
        return Sweep.model_validate({"name": name + label, "base": base,
                                     "vary": self.over or {self.parameter: [float(value)]}, "mode": self.mode,
                                     **extra})


def expand_trial(sweep: Sweep) -> list[CaseSpec]:
    """The cases of a search's trial sweep (:meth:`Search.trial_sweep`), validated.

    Raises
    ------
    StudyError
        Naming ``over`` when a case of the grounds is invalid.
    """
    try:
        return expand_sweep(sweep)
    except SweepError as exc:
        raise StudyError([("over", f"{path}: {message}") for path, message in exc.errors]) from None


def next_trial(search: Search, trials: list[dict]) -> tuple[Optional[float], Optional[dict]]:
    """The next value to try, or the answer: ``(value, None)`` or ``(None, answer)``.

    The high end first (if it fails, nothing in the range passes), then the low end (if it
    passes, it is the answer), then bisection of the bracket until it is within the tolerance;
    the answer is the smallest value seen to pass."""
    passed = sorted(t["value"] for t in trials if t["satisfied"])
    failed = sorted(t["value"] for t in trials if not t["satisfied"])
    if not trials:
        return search.high, None
    if search.high in failed:
        return None, {"value": None, "satisfied": False}
    if len(trials) == 1:
        return search.low, None
    if search.low in passed:
        return None, {"value": search.low, "satisfied": True}
    hi = min(passed)
    lo = max(v for v in failed if v < hi)
    middle = 0.5 * (lo + hi)
    if hi - lo <= search.tolerance or not lo < middle < hi:  # (no float strictly between them)
        return None, {"value": hi, "satisfied": True}
    return middle, None


def trial_outcome(search: Search, value: float, root: StoreLike, case_ids: list[str]) -> dict:
    """A trial's record from its stored cases: the worst output over the done ones; a trial
    with a failed case does not pass (the requirement must hold in every case)."""
    store = as_store(root)
    stored = store.file_keys()
    done = [c for c in case_ids if c in stored]
    out = search.require.output
    values = store.open_results(done)[out].values.astype(float) if done else np.array([])
    worst = search.require.worst(values) if values.size else float("nan")
    failed = len(case_ids) - len(done)
    return {"value": float(value), "case_ids": list(case_ids), "worst": worst if math.isfinite(worst) else None,
            "failed": failed, "satisfied": bool(failed == 0 and math.isfinite(worst) and search.require.met(worst))}


def run_search(search: Search | dict, root: StoreLike, client=None, *, progress: bool = False) -> dict:
    """Run ``search`` (SPEC §8) on dask and return ``{"value", "satisfied", "trials"}``; each
    trial's cases are stored as any sweep's, so a search run again resumes where it stopped.
    A case of the grounds that is not valid raises :class:`StudyError` naming ``over``."""
    from .sweep import _client_or_local

    search = Search.model_validate(search)
    trials: list[dict] = []
    with _client_or_local(client) as c:
        while True:
            value, answer = next_trial(search, trials)
            if answer is not None:
                return {**answer, "trials": trials, "grid_cases": grid_cases(search, trials)}
            try:
                ids = run_sweep(search.trial_sweep(value), root, c, progress=progress, retry_failed=False)
            except SweepError as exc:  # the grounds are validated as the first trial is expanded
                raise StudyError([("over", f"{path}: {message}") for path, message in exc.errors]) from None
            trials.append(trial_outcome(search, value, root, ids))


def grid_cases(search: Search, trials: list[dict]) -> dict:
    """Cases the search ran against those of a grid over [low, high] at its tolerance."""
    per_trial = len(trials[0]["case_ids"]) if trials else 0
    steps = int(math.ceil((search.high - search.low) / search.tolerance)) + 1
    return {"search": per_trial * len(trials), "grid": per_trial * steps}


__all__ = ["Requirement", "Search", "StudyError", "expand_trial", "next_trial", "reliability", "run_search", "sensitivity"]
