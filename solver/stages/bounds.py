"""Where the unsupported ground's limit load lies when its flow is not associated: what proves a collapse that the
staged solve could not follow to its end (SPEC §9.1: a collapse is a result, named with what the ground held).

For Mohr–Coulomb ground with dilatancy ψ < φ the limit load (here the share λ of the excavation load that the
unsupported ground holds, its in-situ state a dead load) is bracketed by two limit loads of associated ground
(ψ = φ), whose paths the staged solve follows readily (Radenkovic 1961, 1962; Drescher & Detournay 1993):

- it is at most that of the same ground with ψ = φ (normality gives the largest limit load);
- it is at least that of associated ground of the reduced strength ``tan φ* = sin φ cos ψ / (1 - sin φ sin ψ)``,
  ``c* = c cos φ cos ψ / (1 - sin φ sin ψ)`` (``c* cot φ* = c cot φ``: the same apex, so the tension cut-off
  stays admissible).

So where stage 1 stalls short of a named collapse and the same ground with ψ = φ collapses below the asked λd, the
ground cannot stand there: :func:`judge` says so, with both bounds (the lower one: what the ground holds for
certain); a collapse the path names itself is checked against them. Hoek–Brown strata have a constant ψ, not a
potential equal to their surface: no bound is drawn there.
"""
from __future__ import annotations

import math

from ..errors import GroundCollapseError, SolverError
from ..limits import CaseCancelled, TimeLimitExceeded
from .path import ADVICE


def twins(spec):
    """The case with every Mohr–Coulomb stratum's flow associated: ``(upper, lower)``, the same strength with
    ψ = φ and Radenkovic's reduced strength with ψ = φ* (``lower`` None where that case is not admissible: the
    in-situ state outside the reduced surface); None where no stratum's flow is non-associated or one is
    Hoek–Brown."""
    from ..spec.case import CaseSpec

    ground = spec.ground
    strata = ground.layers or (ground,)
    if any(s.model == "hoek-brown" for s in strata) or \
            not any(s.model == "mohr-coulomb" and s.dilatancy < s.friction_angle for s in strata):
        return None

    def case(reduced: bool):
        data = spec.model_dump(mode="json")

        def associated(stratum: dict) -> dict:
            if stratum.get("model") != "mohr-coulomb":
                return stratum
            phi, psi = math.radians(stratum["friction_angle"]), math.radians(stratum["dilatancy"])
            if not reduced:
                return stratum | {"dilatancy": stratum["friction_angle"]}
            factor = math.cos(psi) / (1.0 - math.sin(phi) * math.sin(psi))
            phi_star = math.degrees(math.atan(math.sin(phi) * factor))
            return stratum | {"cohesion": stratum["cohesion"] * math.cos(phi) * factor,
                              "friction_angle": phi_star, "dilatancy": phi_star}

        data["ground"] = associated(data["ground"]) | {"layers": [associated(s) for s in data["ground"]["layers"]]}
        try:
            return CaseSpec.model_validate(data)
        except ValueError:
            return None

    upper = case(False)
    return None if upper is None else (upper, case(True))


def _limit(release, twin) -> float | None:
    """The λ at which ``twin``'s unsupported ground collapses on its way to its λd (``release(twin)``: its stage 1);
    infinity where it stands there, None where its solve fails short of a named collapse."""
    try:
        release(twin)
    except GroundCollapseError as collapse:
        return collapse.peak
    except (TimeLimitExceeded, CaseCancelled):
        raise  # the clock's or the user's, not the twin's
    except SolverError:
        return None
    return math.inf


def _bound(value: float, ld: float, which: str) -> str:
    kind = ("associated ground of Radenkovic's reduced strength" if which == "lower"
            else "the same ground with ψ = φ")
    if math.isinf(value):
        return f"{'at least' if which == 'lower' else 'beyond'} λd {ld:.4g}, which {kind} holds"
    return f"{'at least' if which == 'lower' else 'at most'} λ {value:.4g}, where {kind} collapses"


def judge(spec, failure: SolverError, release) -> str | None:
    """Judge ``spec``'s stage-1 ``failure`` by Radenkovic's bounds (``release(twin)`` runs a twin case's stage 1
    to its λd; the twins' outcomes are what the caller keeps):

    - a stall: where the same ground with ψ = φ collapses below λd, the ground cannot stand there either: raise
      that :class:`~solver.errors.GroundCollapseError`, with both bounds; else return what the bounds say (the
      lower one: what the ground holds for certain), the stall's to be solved again;
    - a named collapse: raise it, with the bounds it lies within, unless it lies below what the ground holds for
      certain (the lower bound, or λd where that twin stands, less half an increment: the resolution of the path's
      own collapse tests), where it was a stall of the path, not a collapse: return a note that says so.

    Ground with no twins (associated flow, Hoek–Brown) is judged by nothing: a collapse is raised as it is."""
    pair = twins(spec)
    collapsed = isinstance(failure, GroundCollapseError)
    if pair is None:
        if collapsed:
            raise failure
        return None
    ld = spec.excavation.deconfinement
    upper = _limit(release, pair[0])
    lower = None if pair[1] is None else _limit(release, pair[1])
    if not collapsed and (upper is None or upper >= ld):  # nothing proved: what is known of the limit, said
        known = [_bound(v, ld, which) for v, which in ((lower, "lower"), (upper, "upper")) if v is not None]
        return f"its limit load is {', '.join(known)}: Radenkovic's bounds" if known else None
    if collapsed and lower is not None and failure.peak is not None \
            and failure.peak < min(lower, ld) - 0.5 * ld / spec.solver.load_steps:
        return f"not a collapse: the ground holds {_bound(lower, ld, 'lower')}"
    bracket = ", ".join([_bound(v, ld, which) for v, which in ((lower, "lower"), (upper, "upper")) if v is not None])
    if collapsed:
        raise GroundCollapseError(f"{failure} (with its flow not associated its limit load is {bracket}: "
                                  "Radenkovic's bounds)", failure.peak)
    raise GroundCollapseError(
        f"excavation.deconfinement: the unsupported ground cannot stand at λd {ld:.4g}: with its flow not associated "
        f"its limit load is {bracket} (Radenkovic's bounds; {ADVICE}). The staged solve had stopped short of it: "
        f"{failure}", lower if lower is not None and math.isfinite(lower) else None)
