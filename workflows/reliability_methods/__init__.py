"""Small probabilities (SPEC §9.6): FORM, subset simulation and AK-MCS on the FE model.

- :mod:`.study`: the study (variables on case paths, output and limit, method, budget, seed);
- :mod:`.space`: the standard normal space of the variables;
- :mod:`.limit_state`: g(u) with a budget of calls; the FE one makes each point a case;
- :mod:`.form`, :mod:`.subset`, :mod:`.akmcs`: the algorithms (they know only a limit state);
- :mod:`.driver`: the algorithm on stored cases (dask or the service's queue), restart-safe;
- :mod:`.records`: the study's record in the results store; :mod:`.plots`: its figures.
"""
from __future__ import annotations

from .akmcs import ak_mcs
from .driver import StoreRunner, reliability_study, run_study
from .form import form
from .limit_state import BudgetExhausted, CaseFailed, CaseLimitState, FunctionLimitState, LimitState
from .records import ReliabilityRecord, all_records, read_record
from .result import ReliabilityResult
from .study import ReliabilityStudy
from .subset import subset_simulation

__all__ = ["BudgetExhausted", "CaseFailed", "CaseLimitState", "FunctionLimitState", "LimitState",
           "ReliabilityRecord", "ReliabilityResult", "ReliabilityStudy", "StoreRunner", "ak_mcs", "all_records",
           "form", "read_record", "reliability_study", "run_study", "subset_simulation"]
