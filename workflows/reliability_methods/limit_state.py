"""Limit states: g(u) on points of the standard normal space, g < 0 failing.

An algorithm sees only :class:`LimitState`: a batched function ``g(U)`` that counts its calls
against a budget (a point seen before counts once and is not computed again). :class:`CaseLimitState`
makes each point a case of the FE model and has a *runner* solve the new ones (on dask, or
through the service's job queue); :class:`FunctionLimitState` wraps a plain function (tests,
benchmarks).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

#: A runner solves cases and returns, per case, ``{"case_id", "status", "summary", "error"}``.
Runner = Callable[[Sequence[Any]], Sequence[dict]]


class BudgetExhausted(RuntimeError):
    """A batch of new points would take the study over its budget of calls."""


class CaseFailed(RuntimeError):
    """An FE case the study needs failed (the study cannot tell whether it is a failure)."""


class LimitState:
    """A function g(U) of (n, d) standard normal points with a budget of distinct calls."""

    def __init__(self, dimension: int, budget: int):
        self.dimension = dimension
        self.budget = budget
        self._values: dict[Any, float] = {}
        self.keys: list[Any] = []  # the distinct points, in the order first asked

    @property
    def calls(self) -> int:
        return len(self.keys)

    @property
    def remaining(self) -> int:
        return self.budget - self.calls

    def key(self, u: np.ndarray) -> Any:
        return tuple(float(v) for v in u)

    def __call__(self, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(np.asarray(U, float))
        keys = [self.key(u) for u in U]
        new: dict[Any, np.ndarray] = {}
        for k, u in zip(keys, U):
            if k not in self._values and k not in new:
                new[k] = u
        if len(new) > self.remaining:
            raise BudgetExhausted(f"{len(new)} new calls asked, {self.remaining} left of {self.budget}")
        if new:
            values = self._evaluate(list(new), np.array(list(new.values())))
            for k, v in zip(new, values):
                self._values[k] = float(v)
                self.keys.append(k)
        return np.array([self._values[k] for k in keys])

    def key_of(self, u: np.ndarray) -> Any:
        """The key of a point already evaluated (its case id for an FE limit state)."""
        return self.key(np.asarray(u, float))

    def _evaluate(self, keys: list, U: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class FunctionLimitState(LimitState):
    """g = ``function(U)`` (batched, (n, d) -> (n,))."""

    def __init__(self, function: Callable[[np.ndarray], np.ndarray], dimension: int, budget: int):
        super().__init__(dimension, budget)
        self.function = function

    def _evaluate(self, keys: list, U: np.ndarray) -> np.ndarray:
        return np.asarray(self.function(U), float).reshape(len(U))


class CaseLimitState(LimitState):
    """g(u) = limit − output of the case at x(u): every point is a case, keyed by its id, so
    two points giving the same case (and a case stored before) count once."""

    def __init__(self, study, runner: Runner):
        from .space import StandardSpace

        super().__init__(len(study.variables), study.budget)
        self.study = study
        self.space = StandardSpace(list(study.variables.values()))
        self.runner = runner
        self.outputs: dict[str, float] = {}

    def spec(self, u: np.ndarray):
        from pydantic import ValidationError

        from solver.errors import field_errors, format_errors

        values = self.values(u)
        try:
            return self.study.case_at(values)
        except ValidationError as exc:  # the distributions reach values the case model refuses
            where = ", ".join(f"{p} = {v:.6g}" for p, v in values.items())
            raise CaseFailed(f"the variables at {where} give no valid case: "
                             f"{format_errors(field_errors(exc))}") from None

    def key(self, u: np.ndarray) -> str:
        return self.spec(u).case_id

    def values(self, u: np.ndarray) -> dict[str, float]:
        """{path: value} of the variables at ``u``."""
        return dict(zip(self.study.paths, (float(v) for v in self.space.to_physical(np.atleast_2d(u))[0])))

    def _evaluate(self, keys: list, U: np.ndarray) -> np.ndarray:
        specs = [self.spec(u) for u in U]
        by_id = {o["case_id"]: o for o in self.runner(specs)}
        out = []
        for u, spec in zip(U, specs):
            o = by_id.get(spec.case_id) or {"status": "failed", "error": "no outcome"}
            value = (o.get("summary") or {}).get(self.study.output) if o.get("status") == "done" else None
            if value is None or not np.isfinite(value):
                where = ", ".join(f"{p} = {v:.6g}" for p, v in self.values(u).items())
                raise CaseFailed(f"case {spec.case_id} ({where}) {o.get('status')}: "
                                 f"{o.get('error') or f'no finite {self.study.output}'}")
            self.outputs[spec.case_id] = float(value)
            out.append(self.study.limit - float(value))
        return np.array(out)
