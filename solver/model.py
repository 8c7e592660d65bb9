"""Build once, solve many: what a geometry, its mesh settings and materials fix.

A :class:`TunnelModel` holds the mesh, both bodies' stiffness and factorizations, the dense
interface flexibility and the unit loads a case combines (SPEC §1.1-§1.3). Any case that shares
those (:func:`model_key`) solves on it, varying only loads, construction stages, the interface
model, solver options or design inputs; the staged solve of one case is :mod:`solver.stages`::

    model = TunnelModel(spec)            # mesh, assembly, factorization: once
    for case in cases:                   # same model_key(case)
        solution = model.solve(case)     # forward solves, the contact solve, backward solves

Each body's factorization has the interface unknowns last, so a case's solve splits around the
contact problem: a forward solve of its load gives the interface jumps ``B K⁺ f``, and one
backward solve with the contact tractions the displacements (:meth:`FactoredBody.forward`,
:meth:`~FactoredBody.backward`).
"""
from __future__ import annotations

import dataclasses
import os
import threading
from collections import OrderedDict

from .build import BuiltModel, model_key
from .errors import SolverError
from .ground.loads import LOAD_TERMS
from .spec import CaseSpec
from .spec.canonical import canonical_json
from .stages.loads import load_coefficients
from .stages.solve import solve_case
from .stages.state import CONTACT_GAP_TOL, KKT_ACCEPT, Forward, Solution, StageLoads, accepted_residual

__all__ = ["TunnelModel", "Solution", "model_key", "shared_model", "load_coefficients", "LOAD_TERMS",
           "CONTACT_GAP_TOL", "KKT_ACCEPT", "accepted_residual", "Forward", "StageLoads"]


class TunnelModel(BuiltModel):
    """A :class:`~solver.build.BuiltModel` that solves cases: build once, solve many."""

    def solve(self, spec: CaseSpec) -> Solution:
        """Solve ``spec`` (which must share this model's :func:`model_key`): :func:`solver.stages.solve.solve_case`.

        The mechanics are kept on the model (:class:`~solver.build.Kept`) by :func:`mechanics_key`:
        a case that differs from one solved here only in its design checks, its settlement trough or its
        name (a design sweep, a search for the least reinforcement) takes them as they are, and only its
        results are worked out again (:func:`solver.results.dataset.to_dataset`); a case whose solve failed
        fails so again (not one stopped by its time limit or cancelled)."""
        if not self.accepts(spec):
            return solve_case(self, spec)  # which says why
        kept = self.kept.get("solution", mechanics_key(spec), lambda: solve_case(self, spec), failures=(SolverError,))
        # the solved case as solve_case leaves it (a face distance's λd found), with this one's checks, trough and name
        solved = kept.spec.model_copy(update={part: getattr(spec, part) for part in _RESULTS_ONLY})
        return dataclasses.replace(kept, spec=solved, timings=dict(kept.timings))


#: What a case's mechanics do not depend on: what its results make of them (:func:`mechanics_key`).
_RESULTS_ONLY = ("design", "settlement", "name")


def mechanics_key(spec: CaseSpec) -> str:
    """The case less its design checks (SPEC §1.6), settlement trough (§9.3) and name: what
    :func:`solver.stages.solve.solve_case` depends on beyond the model."""
    return canonical_json(spec, exclude=set(_RESULTS_ONLY))


_SHARED: "OrderedDict[str, TunnelModel]" = OrderedDict()
_SHARED_LOCK = threading.Lock()


def shared_models() -> int:
    """Models a process keeps for reuse (a worker running a sweep over one geometry needs one):
    ``TUNNEL_CONTACT_SHARED_MODELS`` (2 unset; 0 turns reuse off, every case built from nothing),
    read at each call (a forked worker's own)."""
    return int(os.environ.get("TUNNEL_CONTACT_SHARED_MODELS", "2"))


def shared_model(spec: CaseSpec) -> TunnelModel:
    """The process's :class:`TunnelModel` for ``spec``'s :func:`model_key`, built on first use.

    Cases of a sweep that share geometry, mesh, boundaries and materials (loads, K0,
    deconfinement, interface, solver and design varying) then pay mesh, assembly and
    factorization once per worker process. Least recently used models are dropped
    beyond :func:`shared_models`. Solving on a shared model gives the same result as on
    a fresh one: what a model builds on first use (unit load vectors, the factorization and
    flexibility an interface model needs, stress bases) depends on the model alone.
    """
    keep = shared_models()
    if keep <= 0:
        return TunnelModel(spec)
    key = model_key(spec)
    with _SHARED_LOCK:
        if key in _SHARED:
            _SHARED.move_to_end(key)
            return _SHARED[key]
        model = TunnelModel(spec)
        _SHARED[key] = model
        while len(_SHARED) > keep:
            _SHARED.popitem(last=False)
        return model
