"""``tunnel-contact reliability STUDY.json``: run a study and print its answer."""
from __future__ import annotations

import sys
from typing import TextIO

from pydantic import ValidationError

from ..commands import InputError, _one_line, _read_json, _scheduler_client
from ..result_store import ResultStore
from .limit_state import CaseFailed
from .study import ReliabilityStudy


def reliability_command(study_file: str, results: str, *, scheduler: str | None = None, progress: bool = True,
                        out: TextIO | None = None) -> int:
    """Run the study (SPEC §9.6) and print β, P with its interval, the design point and the
    importance factors; 1 if the study did not converge or a case it needed failed."""
    from .driver import reliability_study

    out = out or sys.stdout
    try:
        study = ReliabilityStudy.model_validate(_read_json(study_file))
    except ValidationError as exc:
        raise InputError(f"{study_file}: {_one_line(exc)}") from None
    client = _scheduler_client(scheduler)
    try:
        r = reliability_study(study, ResultStore(results), client, progress=progress)
    except CaseFailed as exc:
        print(f"tunnel-contact: reliability {study.name}: {exc}", file=sys.stderr)
        return 1
    finally:
        if client is not None:
            client.close()

    def g(x) -> str:
        return "-" if x is None else f"{x:.4g}"

    print(f"reliability {study.name} ({r['id']}): {study.method}, P({study.output} > {study.limit:g})", file=out)
    ci = r["beta_ci"] or [None, None]
    print(f"  beta = {g(r['beta'])} (95 % {g(ci[0])} to {g(ci[1])}); P = {g(r['probability'])}, "
          f"95 % [{g(r['ci_low'])}, {g(r['ci_high'])}]; {r['calls']} of {r['budget']} FE calls", file=out)
    if r["design_point"]:
        print(f"  design point (case {r['design_case'] or '-'}):", file=out)
        for path, value in r["design_point"].items():
            alpha2 = (r["importance"] or {}).get(path)
            print(f"    {path:<32} {value:>14.6g}   alpha^2 = {g(alpha2)}", file=out)
    if r["note"]:
        print(f"  note: {r['note']}", file=out)
    return 0 if r["converged"] else 1
