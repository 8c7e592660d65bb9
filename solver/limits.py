"""A time limit for one case, checked by the solver's own loops (contact iterations, friction
steps, plastic iterations), so no case ties up a process: a case over its limit fails with
the reason, like any case that does not converge.

``with time_limit(seconds): ...`` sets the limit for the code run inside (per thread and
task: a :mod:`contextvars` variable); :func:`check_time` raises once it has passed. The
default, :func:`case_time_limit` seconds, is ``TUNNEL_CONTACT_CASE_TIME_LIMIT`` (600: the
finest mesh the sizing cap allows solves in about a minute on one core), read when a case starts.
"""
from __future__ import annotations

import contextvars
import os
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass

from .errors import SolverError


def case_time_limit() -> float:
    """``TUNNEL_CONTACT_CASE_TIME_LIMIT`` seconds (600 unset), read at each call: a dask worker
    forked from a process that imported the solver earlier has its own environment by then."""
    return float(os.environ.get("TUNNEL_CONTACT_CASE_TIME_LIMIT", "600") or 600)


#: Seconds between two calls of a block's ``stop`` callable (it may look at a file).
STOP_POLL = 0.5


@dataclass
class _Limit:
    deadline: float  # time.monotonic() past which the case stops
    seconds: float
    stop: Callable[[], bool] | None
    next_poll: float  # when ``stop`` is asked next


_LIMIT: contextvars.ContextVar[_Limit | None] = contextvars.ContextVar("limit", default=None)


class TimeLimitExceeded(SolverError):
    """A case that ran past its time limit."""


class CaseCancelled(SolverError):
    """A case whose ``stop`` callable asked it to give up (cancelled while running)."""


@contextmanager
def time_limit(seconds: float | None = None, stop: Callable[[], bool] | None = None):
    """Run the block under a limit of ``seconds`` (default :func:`case_time_limit`); ``stop``,
    if given, is asked every :data:`STOP_POLL` seconds whether to give the case up (a
    cancellation), which :func:`check_time` then raises as :class:`CaseCancelled`."""
    seconds = case_time_limit() if seconds is None else float(seconds)
    now = time.monotonic()
    token = _LIMIT.set(_Limit(now + seconds, seconds, stop, now + STOP_POLL))
    try:
        yield
    finally:
        _LIMIT.reset(token)


def check_time(where: str, iteration: int | None = None) -> None:
    """Raise :class:`TimeLimitExceeded` naming ``where`` if the current limit has passed, or
    :class:`CaseCancelled` if the block's ``stop`` says so."""
    limit = _LIMIT.get()
    if limit is None:
        return
    now = time.monotonic()
    if limit.stop is not None and now > limit.next_poll:
        limit.next_poll = now + STOP_POLL
        if limit.stop():
            raise CaseCancelled(f"cancelled while running ({where}); submit the case again to compute it")
    if now > limit.deadline:
        at = f" after {iteration:,} iterations" if iteration is not None else ""
        raise TimeLimitExceeded(
            f"time limit: the case ran past its limit of {limit.seconds:g} s in the {where}{at} and was stopped "
            "(a very fine tolerance, a huge solver.max_iterations or a very fine mesh; the service's limit is "
            "TUNNEL_CONTACT_CASE_TIME_LIMIT)")
