"""open_results over many stored cases: every case file read (the old path) against the index.

``python -m bench.index [--cases 1000 10000] [--json]``

Cases are generated cheaply: three coarse cases (mesh.interface_size 0.2, far_size 8;
lining thickness 0.25, 0.3, 0.35) are solved once; every further case is a copy of one of
their files under a new case id (the same case with another ``loads.surface_load``, so
``case_spec`` and the id change) whose contact pressure, thrust and their maxima are
scaled by the load ratio, edited in place with netCDF4, followed by the index entry the
store writes when a case lands (``ResultIndex.add``, what ``ResultStore.write_case``
does). The files are as large as a coarse case (the old path's cost per case hardly
depends on the mesh: it is the opening and the per-variable reads).

For each size, in one run and on one store (the larger size extends the smaller):

- ``old``: :func:`workflows.combine.combine_files`, every case file opened (today's path),
  timed last (it takes minutes), over the first ``n`` ids of the full store;
- ``first``: :func:`workflows.open_results` right after the cases landed (every entry still
  pending: it merges them and writes ``index/results.nc``);
- ``index``: :func:`workflows.open_results` again, index up to date (best of 3);
- ``subset``: six cases out of the whole store through the index (best of 3);

and the two answers are checked with ``xarray.testing.assert_identical``.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time

SCALED = ("contact_pressure", "thrust", "max_contact_pressure", "max_thrust")


def solve_bases():
    """The three coarse cases every generated case is a copy of."""
    import solver

    return [solver.run_case(solver.CaseSpec.model_validate(
        {"mesh": {"interface_size": 0.2, "far_size": 8.0}, "geometry": {"thickness": t}}))
        for t in (0.25, 0.3, 0.35)]


def add_copies(store, bases, start: int, stop: int) -> float:
    """Store copies ``start .. stop-1`` of the (stored) ``bases``; return the mean seconds of
    their index entries (``ResultIndex.add``)."""
    import netCDF4

    from solver import CaseSpec
    from workflows.result_store import file_key

    sources = [store.case_path(ds.attrs["case_id"]) for ds in bases]
    entry_seconds = 0.0
    for i in range(start, stop):
        base = bases[i % len(bases)]
        data = CaseSpec.model_validate_json(base.attrs["case_spec"]).model_dump(mode="json")
        data["loads"]["surface_load"] = 1e5 + 10.0 * (i + 1)
        spec = CaseSpec.model_validate(data)
        ratio = data["loads"]["surface_load"] / 1e5
        copy = base.copy(deep=False)
        copy.attrs = {**base.attrs, "case_id": spec.case_id, "case_spec": spec.canonical_json()}
        for name in SCALED:
            copy[name] = base[name].copy(data=base[name].values * ratio)
        target = store.case_path(spec.case_id)
        shutil.copyfile(sources[i % len(bases)], target)
        with netCDF4.Dataset(target, "a") as nc:
            nc.setncattr("case_id", spec.case_id)
            nc.setncattr("case_spec", spec.canonical_json())
            for name in SCALED:
                nc.variables[name].set_auto_maskandscale(False)
                nc.variables[name][...] = copy[name].values
        start_entry = time.perf_counter()
        store.index.add(copy, file_key(target.stat()))
        entry_seconds += time.perf_counter() - start_entry
    return entry_seconds / max(1, stop - start)


def best(fn, repeat: int = 3) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return min(times), out


def measure_index(store, n: int) -> dict:
    """Index figures over the ``n`` cases of the store, right after they landed."""
    from workflows import open_results

    ids = store.case_ids()
    assert len(ids) == n, (len(ids), n)
    start = time.perf_counter()
    open_results(store)
    first_seconds = time.perf_counter() - start
    index_seconds, _ = best(lambda: open_results(store))
    subset = ids[:: max(1, n // 6)][:6]
    subset_seconds, _ = best(lambda: open_results(store, subset))
    return {"cases": n, "first_seconds": first_seconds, "index_seconds": index_seconds,
            "subset_seconds": subset_seconds,
            "index_file_mb": store.index.path.stat().st_size / 1e6 if store.index.path.is_file() else 0.0}


def measure_old(store, ids: list[str]) -> float:
    """Seconds of the old path over ``ids``; its answer must equal the index's."""
    import xarray as xr

    from workflows import open_results
    from workflows.combine import combine_files

    start = time.perf_counter()
    old = combine_files(store, ids)
    seconds = time.perf_counter() - start
    xr.testing.assert_identical(open_results(store, ids), old)
    return seconds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.index", description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, nargs="+", default=[1000, 10000], help="store sizes, ascending")
    parser.add_argument("--skip-old-above", type=int, default=10**9,
                        help="do not time the old path (every file read) above this many cases")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    from workflows import ResultStore
    from workflows.commands import configure_logging

    configure_logging()
    load_before = os.getloadavg()
    bases = solve_bases()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-index-") as root:
        store = ResultStore(root)
        for ds in bases:
            store.write_case(ds)
        for n in sorted(args.cases):  # the index first: the old path takes minutes
            before = len(store.case_ids())
            entry = add_copies(store, bases, before - len(bases), n - len(bases))
            rows.append({**measure_index(store, n), "entry_write_seconds": entry, "new_cases": n - before})
            if not args.json:
                row = rows[-1]
                print(f"{n:>6} cases: index {row['index_seconds']:.3f} s (first read, merging the "
                      f"{n - before} new entries: {row['first_seconds']:.2f} s); 6 of them {row['subset_seconds']:.3f} s; "
                      f"index file {row['index_file_mb']:.0f} MB; entry write {1e3 * entry:.1f} ms a case",
                      flush=True)
        ids = store.case_ids()  # sorted ids: the first n are as good a sample as any
        for row in rows:
            if row["cases"] <= args.skip_old_above:
                row["old_seconds"] = measure_old(store, ids[: row["cases"]])
                row["identical"] = True
                if not args.json:
                    print(f"{row['cases']:>6} cases: old path (every case file read) {row['old_seconds']:.2f} s, "
                          f"{row['old_seconds'] / row['index_seconds']:.0f}x the index; answers identical",
                          flush=True)
    report = {"cpu_count": os.cpu_count(), "load_average_before": load_before,
              "load_average_after": os.getloadavg(), "sizes": rows}
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"load average before {load_before[0]:.2f}, after {report['load_average_after'][0]:.2f} "
              f"on {report['cpu_count']} CPUs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
