"""A reliability study (SPEC §9.6): random variables on case paths, a limit state on one
result scalar, a method and a budget of FE calls.

Failure is ``output > limit``; the limit state is ``g = limit - output`` (g < 0 fails), the
convention of OpenTURNS and of the reliability literature.
"""
from __future__ import annotations

import hashlib
import json
from typing import Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from solver.results.dataset import SCALARS

from ..parameters import canonical_path, is_parameter, set_parameter
from ..sampling import Distribution

#: Most FE calls one study may spend, and fewest.
MAX_BUDGET = 20_000
MIN_BUDGET = 10
#: Most random variables of one study.
MAX_VARIABLES = 20
METHODS = ("form", "subset", "ak-mcs")
#: The plastic stop test (``solver.plastic_tolerance``) of FORM's cases on yielding ground, unless the
#: base gives one: at the default 0.01 the finite differences did not converge (a Mohr–Coulomb study).
FORM_PLASTIC_TOLERANCE = 2e-3


class ReliabilityStudy(BaseModel):
    """``{"name", "base", "variables", "output", "limit", "method", "budget", "seed"}``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(..., min_length=1, max_length=200)
    base: dict[str, Any] = Field(default_factory=dict, description="the case the variables act on")
    variables: dict[str, Distribution] = Field(
        ..., description="case path -> distribution (SPEC §8: uniform, normal, lognormal, truncated-normal); "
                         "the variables are independent")
    output: str = Field("max_utilization", description="a result scalar (SPEC §3)")
    limit: float = Field(1.0, allow_inf_nan=False, description="failure is output > limit")
    method: Literal["form", "subset", "ak-mcs"] = "form"
    budget: int = Field(300, ge=MIN_BUDGET, le=MAX_BUDGET,
                        description="most FE cases the study uses, checks included (a stored case counts once)")
    seed: int = Field(0, ge=0, le=2**32 - 1, description="seed of every random draw (same seed, same cases)")
    samples_per_level: Optional[int] = Field(
        None, ge=20, le=MAX_BUDGET,
        description="subset: samples per level (default: budget / 4.6, room for five levels)")

    @model_validator(mode="after")
    def _consistent(self) -> "ReliabilityStudy":
        from solver import CaseSpec
        from solver.errors import field_errors

        if self.output not in SCALARS:
            raise ValueError(f"output: {self.output!r} is not a result scalar (one of {', '.join(sorted(SCALARS))})")
        if not self.variables:
            raise ValueError("variables: give at least one random variable")
        if len(self.variables) > MAX_VARIABLES:
            raise ValueError(f"variables: {len(self.variables)} variables, at most {MAX_VARIABLES}")
        try:
            CaseSpec.model_validate(self.base)
        except ValidationError as exc:
            raise ValueError("base.{}: {}".format(*field_errors(exc)[0]).replace("base.: ", "base: ")) from None
        seen: dict[str, str] = {}
        for path in self.variables:
            target = canonical_path(path)
            if not is_parameter(target, self.base):
                raise ValueError(f"variables.{path}: unknown parameter (a numeric case field such as "
                                 "loads.surface_load or ground.layers.0.young)")
            if target in seen:
                raise ValueError(f"variables.{path}: the same parameter as {seen[target]!r}")
            seen[target] = path
        if self.method == "subset" and self.samples_per_level is not None and self.samples_per_level > self.budget:
            raise ValueError(f"samples_per_level: {self.samples_per_level} is over the budget ({self.budget})")
        # the median case must be a case (a variable on a text field, or out of range, fails here)
        try:
            self.case_at({p: float(d.ppf(0.5)) for p, d in self.variables.items()})
        except ValidationError as exc:
            field, reason = field_errors(exc)[0]
            raise ValueError(f"variables: the median case is not valid: {field}: {reason}") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"variables: {exc}") from None
        return self

    @property
    def paths(self) -> list[str]:
        return list(self.variables)

    def case_at(self, values: dict[str, float]):
        """The case with the variables at ``values`` ({path: value})."""
        from solver import CaseSpec

        data = json.loads(json.dumps(self.base))
        for path, value in values.items():
            set_parameter(data, canonical_path(path), float(value))
        spec = CaseSpec.model_validate(data)
        solver = data.get("solver") if isinstance(data.get("solver"), dict) else {}
        if self.method == "form" and spec.plastic and "plastic_tolerance" not in solver:
            # FORM's forward differences need the output's digits: the plastic solve tighter than
            # its default (which leaves them to the iteration; docs/reliability.md)
            data["solver"] = {**solver, "plastic_tolerance": FORM_PLASTIC_TOLERANCE}
            spec = CaseSpec.model_validate(data)
        return spec

    @property
    def study_id(self) -> str:
        """16 hex digits of the study's canonical JSON (the base case's canonical form)."""
        from solver import CaseSpec

        data = self.model_dump(mode="json")
        data["base"] = json.loads(CaseSpec.model_validate(self.base).canonical_json())
        text = json.dumps(data, sort_keys=True, separators=(",", ":"))
        return hashlib.blake2b(text.encode(), digest_size=8).hexdigest()
