"""Small probabilities (SPEC §9.6): FORM, subset simulation and AK-MCS on the FE model.

- :mod:`.study`: the study (variables on case paths, output and limit, method, budget, seed);
- :mod:`.space`: the standard normal space of the variables;
- :mod:`.limit_state`: g(u) with a budget of calls; the FE one makes each point a case;
- :mod:`.form`, :mod:`.subset`, :mod:`.akmcs`: the algorithms (they know only a limit state);
- :mod:`.driver`: the algorithm on stored cases (dask or the service's queue), restart-safe;
- :mod:`.records`: the study's record in the results store; :mod:`.plots`: its figures.
"""
from __future__ import annotations

from solver.lazy import lazy_exports

from .form import form  # (eager: the submodule of the same name would shadow a lazy one)

#: Where each name of the package lives, imported on first use (PEP 562): AK-MCS's scikit-learn
#: only when a study asks for it.
_HOME = {
    "ak_mcs": ".akmcs", "StoreRunner": ".driver", "reliability_study": ".driver", "run_study": ".driver",
    "BudgetExhausted": ".limit_state", "CaseFailed": ".limit_state",
    "CaseLimitState": ".limit_state", "FunctionLimitState": ".limit_state", "LimitState": ".limit_state",
    "ReliabilityRecord": ".records", "all_records": ".records", "read_record": ".records",
    "ReliabilityResult": ".result", "ReliabilityStudy": ".study", "subset_simulation": ".subset",
}

__all__ = sorted([*_HOME, "form"])
__getattr__, __dir__ = lazy_exports(__name__, _HOME)
