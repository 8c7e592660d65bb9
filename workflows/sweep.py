"""Parametric sweeps: a base case, parameters to vary, and their expansion into cases.

A sweep (JSON)::

    {"name": "thickness", "base": {case}, "vary": {"lining.thickness": [0.2, 0.3]},
     "mode": "grid"}

``grid`` takes the cartesian product of the lists, ``zip`` takes them together (equal
lengths). :func:`expand_sweep` checks everything at once and raises one
:class:`SweepError` listing every problem with the dotted path it concerns.
"""
from __future__ import annotations

import itertools
import json
import logging
import math
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from typing import Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from solver.errors import did_you_mean, field_errors
from solver.spec import CaseSpec, canonical_json, content_id
from solver.spec.ground import HOEK_BROWN_DEFAULTS

from .sampling import SAMPLED_MODES, Distribution, sample_errors, sampled_values
from .parameters import PATH_ALIASES, canonical_path, is_parameter, parameter_paths, set_parameter
from .result_store import ResultStore, StoreLike, as_store

logger = logging.getLogger(__name__)

#: Largest number of cases one sweep may expand to.
MAX_SWEEP_CASES = 5000


def _check_unicode(text: str, what: str) -> None:
    """Refuse text that is not valid Unicode (a lone surrogate such as ``"\\ud800"``, which
    JSON can carry but no file or database can store)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise ValueError(f"{what} is not valid Unicode (a lone surrogate, e.g. \\ud800)") from None


class Sweep(BaseModel):
    """A parametric study: ``base`` with the parameters in ``vary`` changed."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(min_length=1, max_length=200, description="label of the study")
    base: CaseSpec = Field(default_factory=CaseSpec, description="the case the variations start from")
    vary: dict[str, Any] = Field(
        default_factory=dict,
        description="dotted parameter path (e.g. 'lining.thickness', 'ground.young') -> list of values "
                    "(grid, zip) or a distribution (sobol, lhs, random)")
    mode: Literal["grid", "zip", "sobol", "lhs", "random"] = Field(
        "grid", description="'grid': cartesian product of the lists; 'zip': equal-length lists taken together; "
                            "'sobol', 'lhs', 'random': samples drawn from each parameter's distribution")
    samples: Optional[int] = Field(None, description="number of sampled cases (sobol: a power of 2)")
    seed: int = Field(0, ge=0, le=2**32 - 1, description="seed of the sample (same seed, same cases)")

    @field_validator("name", mode="before")
    @classmethod
    def _valid_name(cls, name):
        if isinstance(name, str):
            _check_unicode(name, "name")
        return name

    @field_validator("vary", mode="before")
    @classmethod
    def _entries(cls, vary):
        if not isinstance(vary, dict):
            return vary
        out = {}
        for path, entry in vary.items():
            if isinstance(entry, dict):
                try:
                    entry = Distribution.model_validate(entry)
                except ValidationError as exc:
                    err = exc.errors()[0]
                    where = ".".join(str(p) for p in err["loc"])
                    msg = err["msg"].removeprefix("Value error, ")
                    raise ValueError(f"{path}{'.' + where if where else ''}: {msg}") from None
            elif not isinstance(entry, (list, tuple)):
                raise ValueError(f"{path}: expected a list of values or a distribution")
            out[path] = entry if isinstance(entry, Distribution) else list(entry)
        return out

    def canonical_json(self) -> str:
        """Defaults filled, keys sorted, no whitespace (a grid or zip sweep's without the sampling
        settings it ignores, so its id is what it was before sampled sweeps)."""
        data = json.loads(canonical_json(self))
        _without_round4_defaults(data["base"])
        if self.mode not in SAMPLED_MODES:
            data.pop("samples", None)
            data.pop("seed", None)
        return json.dumps(data, sort_keys=True, separators=(",", ":"))

    def definition_json(self) -> str:
        """The sweep as given, as JSON: defaults filled, every key in the order it came (a
        sampled sweep's dimensions follow the order of ``vary``, so a record written in sorted
        order would expand to other cases). What a sweep's record stores; its id is still that
        of :meth:`canonical_json`."""
        return json.dumps(self.model_dump(mode="json"), separators=(",", ":"))

    def table(self) -> dict[str, list[Any]]:
        """The values of each varied parameter: the lists, or a sampled sweep's samples."""
        if self.mode in SAMPLED_MODES and not sample_errors(self.mode, self.samples, self.vary):
            return sampled_values(self.mode, self.samples, self.seed, self.vary)
        return {p: v for p, v in self.vary.items() if not isinstance(v, Distribution)}

    @property
    def sweep_id(self) -> str:
        """Stable 16-hex-digit id of the sweep (sha256 of its canonical JSON)."""
        return content_id(self.canonical_json())


#: Fourth-round fields of a case (SPEC §9) left out of a sweep's id while at their defaults, so every
#: earlier sweep keeps its id (as :class:`solver.spec.CaseSpec` keeps its cases').
_ROUND4_PATHS = (("solver", "mesh_check"), ("solver", "plastic_tolerance"), ("geometry", "section"),
                 ("excavation", "face_distance"),
                 ("excavation", "ldp"), ("design", "crack_width_limit"), ("design", "bar_diameter"),
                 ("settlement", None), ("name", None),
                 *(("ground", f) for f in HOEK_BROWN_DEFAULTS))


def _without_round4_defaults(base: dict) -> None:
    default = json.loads(canonical_json(CaseSpec()))
    for section, field in _ROUND4_PATHS:
        if field is None:
            if section in base and base[section] == default.get(section):
                del base[section]
        elif section in base and field in base[section] and base[section][field] == default[section].get(field):
            del base[section][field]
    for layer in base.get("ground", {}).get("layers", []):  # SPEC §9.1's fields of each layer
        for field, value in HOEK_BROWN_DEFAULTS.items():
            if layer.get(field, value) == value:
                layer.pop(field, None)


class SweepError(ValueError):
    """A sweep that cannot be expanded; ``errors`` lists ``(dotted path, message)``."""

    def __init__(self, errors: list[tuple[str, str]]):
        self.errors = list(errors)
        super().__init__("invalid sweep: " + "; ".join(f"{p}: {m}" for p, m in self.errors))


def sweep_size(sweep: Sweep) -> int:
    """Number of combinations ``sweep`` describes (before validating the cases)."""
    if sweep.mode in SAMPLED_MODES:
        return sweep.samples or 0
    lengths = [len(v) for v in sweep.vary.values() if not isinstance(v, Distribution)]
    if not lengths:
        return 1
    return math.prod(lengths) if sweep.mode == "grid" else max(lengths)


def check_structure(sweep: Sweep) -> None:
    """Raise :class:`SweepError` for the problems of the ``vary`` table itself (paths, empty or
    unequal lists, sample settings, size) without validating a case: cheap, so it runs before an
    expansion is started (a search's grounds are checked so when it is posted)."""
    errors = _structure_errors(sweep, sweep.base.model_dump(mode="json"))
    if errors:
        raise SweepError(errors)


def expand_sweep(sweep: Sweep | dict[str, Any]) -> list[CaseSpec]:
    """The cases of ``sweep``, validated, without duplicates, in expansion order.

    ``sweep`` may also be its JSON-like dict (then a ``pydantic.ValidationError`` is
    raised if it is not a :class:`Sweep` at all).

    Checks, all reported together in one :class:`SweepError`: every varied path is
    a parameter of the case model (aliases: :data:`~workflows.parameters.PATH_ALIASES`),
    no parameter is given twice, every list is non-empty, ``zip`` lists have equal
    lengths, the sweep has at most :data:`MAX_SWEEP_CASES` cases, and every expanded
    case is a valid :class:`CaseSpec`.
    """
    sweep = Sweep.model_validate(sweep)
    base = sweep.base.model_dump(mode="json")
    errors = _structure_errors(sweep, base)
    table = sweep.table()
    # each value on its own first: the errors then name the varied path and value
    for path, values in table.items():
        target = canonical_path(path)
        if not is_parameter(target, base):
            continue
        for value in values:
            try:
                CaseSpec.model_validate(_with_values(base, {target: value}))
            except ValidationError as exc:
                errors.extend((path, f"{value!r}: {msg}") for _, msg in _messages(exc))
    if errors:
        raise SweepError(errors)

    paths = [canonical_path(p) for p in table]
    rows = (itertools.product(*table.values()) if sweep.mode == "grid"
            else zip(*table.values()))
    cases: dict[str, CaseSpec] = {}
    for row in rows:
        try:
            spec = CaseSpec.model_validate(_with_values(base, dict(zip(paths, row))))
        except ValidationError as exc:  # a combination that is invalid only together
            where = ", ".join(f"{p}={v!r}" for p, v in zip(table, row))
            for loc, msg in _messages(exc):
                if (loc, f"{msg} (case {where})") not in errors:
                    errors.append((loc, f"{msg} (case {where})"))
            continue
        cases.setdefault(spec.case_id, spec)
    if errors:
        raise SweepError(errors)
    logger.info("sweep %r: %d cases", sweep.name, len(cases))
    return list(cases.values())


#: Unknown ``vary`` paths given a "did you mean" (the first ones: an error answer lists 50,
#: :data:`service.errors.MAX_ERRORS`; a 0.9 MB body of 36 000 unknown paths took 25 s of them).
SUGGESTED = 50


def _structure_errors(sweep: Sweep, base: dict[str, Any]) -> list[tuple[str, str]]:
    """Problems of the ``vary`` table itself: paths, empty or unequal lists, size."""
    errors: list[tuple[str, str]] = []
    known = parameter_paths()
    seen: dict[str, str] = {}
    unknown = 0
    sampled = sweep.mode in SAMPLED_MODES
    if sampled:
        errors.extend(sample_errors(sweep.mode, sweep.samples, sweep.vary))
        if not sweep.vary:
            errors.append(("vary", f"a {sweep.mode} sweep with nothing varied has no case to sample; give each "
                                   "uncertain parameter a distribution (or use mode 'grid' for the base case alone)"))
    elif sweep.mode == "zip" and not sweep.vary:
        errors.append(("vary", "a zip sweep with nothing varied has no case; vary at least one parameter "
                               "(or use mode 'grid', whose empty vary is the base case alone)"))
    elif any(isinstance(v, Distribution) for v in sweep.vary.values()):
        errors.extend((f"vary.{p}", f"a distribution needs mode 'sobol', 'lhs' or 'random' (mode is {sweep.mode!r})")
                      for p, v in sweep.vary.items() if isinstance(v, Distribution))
    for path, values in sweep.vary.items():
        target = canonical_path(path)
        if sampled and is_parameter(target, base) and not _numeric(target, base):
            errors.append((path, "a sampled parameter must be a number"))
        if not is_parameter(target, base):
            unknown += 1  # a suggestion costs about a millisecond: the first ones only
            hint = did_you_mean(path, [*known, *PATH_ALIASES]) if unknown <= SUGGESTED else ""
            errors.append((path, "unknown parameter; expected '<section>.<field>' of the case "
                                 f"(e.g. {known[0]}, ..., {known[-1]}), or ground.layers.<i>.<field> "
                                 "of a layer the base case has" + hint))
        elif target in seen:
            errors.append((path, f"the same parameter as {seen[target]!r}"))
        else:
            seen[target] = path
        if not isinstance(values, Distribution) and not values:
            errors.append((path, "empty list of values"))
    lengths = [len(v) for v in sweep.vary.values() if not isinstance(v, Distribution)]
    if sweep.mode == "zip" and len(set(lengths)) > 1:
        errors.extend((path, f"has {len(values)} values; in zip mode all lists must be equally "
                             f"long (lengths {lengths})") for path, values in sweep.vary.items())
    size = sweep_size(sweep)
    if size > MAX_SWEEP_CASES:
        errors.append(("vary", f"the sweep has {size:,} cases, over the cap of {MAX_SWEEP_CASES:,}"))
    return errors


def _numeric(path: str, base: dict[str, Any]) -> bool:
    """Whether the case parameter at ``path`` takes a number (its value in the base case)."""
    node: Any = base
    for part in path.split("."):
        node = node[int(part)] if isinstance(node, list) else node.get(part)
    return isinstance(node, (int, float)) and not isinstance(node, bool)


def _with_values(base: dict[str, Any], values: dict[str, Any]) -> dict[str, Any]:
    """A copy of the case dict ``base`` with ``{canonical path: value}`` set."""
    data = json.loads(json.dumps(base))  # a deep copy of plain JSON data
    for path, value in values.items():
        set_parameter(data, path, value)
    return data


def _messages(exc: ValidationError) -> list[tuple[str, str]]:
    """``(dotted location, message)`` of each error of a case validation."""
    return [(path or "case", reason) for path, reason in field_errors(exc)]


def run_sweep(sweep: Sweep | dict[str, Any], root: StoreLike, client=None, *, progress: bool = False,
              force: bool = False, on_result: Callable[[dict], None] | None = None,
              retry_failed: bool = True) -> list[str]:
    """Solve every case of ``sweep`` on dask and store the results; return the case ids.

    The cases go to the scheduler through :func:`workflows.tasks.run_cases` (cheap cases
    several to a task, each stored as its own file and reported on its own). Cases
    already stored are skipped without submitting anything (unless ``force``), except a
    stored file that cannot be read, which is computed again; a failing case records its
    error file and does not stop the others.

    Parameters
    ----------
    sweep : the study (a :class:`Sweep` or its dict).
    root : the result store, or its folder (it must be reachable from the workers).
    client : a ``distributed.Client``; ``None`` starts an embedded LocalCluster
        (2 worker processes, 1 thread each) and closes it afterwards.
    progress : show a tqdm progress bar.
    force : recompute stored cases.
    retry_failed : recompute cases whose earlier failure is recorded in the store (the
        default); False leaves them failed (the command line's default, as for ``run``).
    on_result : called with each case's summary dict as it completes.
    """
    from tqdm import tqdm

    from .tasks import run_cases

    store = as_store(root)
    sweep = Sweep.model_validate(sweep)
    specs = expand_sweep(sweep)
    store.remove_stale_temporaries()
    ids = [s.case_id for s in specs]
    store.write_sweep_record(sweep.sweep_id, sweep.name, sweep.definition_json(), ids)  # the service lists it
    broken = set() if force else set(store.unreadable(ids))  # recomputed, never combined
    todo = [s for s in specs if force or not store.is_stored(s.case_id) or s.case_id in broken]
    if not retry_failed and not force:
        todo = [s for s in todo if s.case_id in broken or store.read_error(s.case_id) is None]
    logger.info("sweep %r: %d cases, %d to compute", sweep.name, len(ids), len(todo))
    if not todo:
        return ids
    store = store if store.url else ResultStore(os.path.abspath(store.root))
    with _client_or_local(client) as c:
        bar = tqdm(total=len(todo), desc=f"sweep {sweep.name}", unit="case") if progress else None
        try:  # a task computes an unreadable file again
            for result in run_cases(c, todo, store, force=force):
                logger.info("case %s %s", result["case_id"], result["status"])
                if on_result is not None:
                    on_result(result)
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
    return ids


@contextmanager
def local_client(n_workers: int = 2) -> Iterator:
    """An embedded LocalCluster client (worker processes, one thread each), closed on exit."""
    from distributed import Client, LocalCluster

    from .workers import worker_config

    # silence_logs=CRITICAL: the embedded cluster's teardown noise (a worker's heartbeat meeting
    # the closed scheduler is logged by distributed at ERROR, with a traceback) is not the user's
    # business; what the user needs, each case's failure and its reason, the sweep reports itself
    with worker_config(), LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.CRITICAL) as cluster, \
            Client(cluster) as client:
        yield client


def _client_or_local(client):
    return nullcontext(client) if client is not None else local_client()


__all__ = ["MAX_SWEEP_CASES", "PATH_ALIASES", "Sweep", "SweepError", "expand_sweep",
           "run_sweep", "sweep_size", "local_client"]
