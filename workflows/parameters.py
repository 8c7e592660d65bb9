"""Case parameters as dotted paths and as flat names.

A parameter of a case is addressed by its dotted path ``<section>.<field>``
(``ground.young``, ``geometry.gap``). In combined results and tables it appears
under its flat name ``<section>_<field>`` (``ground_young``, ``geometry_gap``),
with one exception that follows the contract's wording (SPEC §3, §4): the lining
thickness lives in ``geometry.thickness`` but is named ``lining_thickness``, and
the dotted path ``lining.thickness`` is accepted as an alias of
``geometry.thickness``.
"""
from __future__ import annotations

import json
from functools import lru_cache
from typing import Any

from pydantic import BaseModel

from solver.spec import CaseSpec

#: Alternative dotted paths accepted in sweeps -> canonical path in :class:`CaseSpec`.
PATH_ALIASES: dict[str, str] = {"lining.thickness": "geometry.thickness"}
#: Canonical paths whose flat name is not ``<section>_<field>``.
FLAT_NAME_OVERRIDES: dict[str, str] = {"geometry.thickness": "lining_thickness"}


def canonical_path(path: str) -> str:
    """The :class:`CaseSpec` path ``path`` stands for (resolving aliases)."""
    return PATH_ALIASES.get(path, path)


@lru_cache(maxsize=None)  # called for every parameter of every case combined
def flat_name(path: str) -> str:
    """Flat name of a dotted parameter path: ``ground.young`` -> ``ground_young``."""
    path = canonical_path(path)
    return FLAT_NAME_OVERRIDES.get(path, path.replace(".", "_"))


def parameter_paths() -> list[str]:
    """Every leaf path ``<section>.<field>`` of :class:`CaseSpec`."""
    paths = []
    for section, info in CaseSpec.model_fields.items():
        model = info.annotation
        if isinstance(model, type) and issubclass(model, BaseModel):
            paths.extend(f"{section}.{field}" for field in model.model_fields)
    return paths


def flat_parameters(spec: CaseSpec | dict[str, Any] | str) -> dict[str, Any]:
    """All parameters of a case as ``{flat name: value}``.

    ``spec`` may be a :class:`CaseSpec`, its ``model_dump(mode="json")`` or its
    canonical JSON text (the ``case_spec`` attribute of a result).
    """
    if isinstance(spec, CaseSpec):
        data = spec.model_dump(mode="json")
    elif isinstance(spec, str):
        data = json.loads(spec)
    else:
        data = spec
    return {flat_name(f"{section}.{field}"): value
            for section, fields in data.items() for field, value in fields.items()}


def varying_parameters(cases: list[dict[str, Any]]) -> list[str]:
    """Flat names whose value is not the same in all ``cases`` (flat dicts), in path order."""
    if not cases:
        return []
    names = list(cases[0])
    return [n for n in names if any(c.get(n) != cases[0].get(n) for c in cases[1:])]
