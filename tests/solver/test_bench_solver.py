"""``python -m bench.solver`` runs through the one solver path and its ratios are what its
table says they are (a smoke test at a coarse mesh; timings themselves are not asserted)."""
from __future__ import annotations

import math

import pytest

from bench.solver import bench_size


def test_solver_benchmark_row_is_consistent():
    row = bench_size(0.3, 8.0, repeat=2)
    for key in ("floor_s", "factorization_s", "flexibility_s", "first_contact_s", "next_contact_s",
                "uzawa_contact_s", "run_case_s"):
        assert math.isfinite(row[key]) and row[key] > 0.0, key
    assert row["first_ratio"] == pytest.approx(
        (row["factorization_s"] + row["flexibility_s"] + row["first_contact_s"]) / row["floor_s"])
    assert row["next_ratio"] == pytest.approx((row["factorization_s"] + row["next_contact_s"]) / row["floor_s"])
    for key in ("first_ratio_median", "next_ratio_median"):  # ratios within a repeat, median
        assert math.isfinite(row[key]) and row[key] > 0.0, key
    assert row["dof"] > 0 and row["interface_nodes"] > 0 and row["active_set_iterations"] >= 1
    assert 0.0 < row["max_abs_moment_kNm"] < 1e4


def test_ordering_benchmark_rows(capsys):
    """``python -m bench.ordering`` runs its three orderings through CHOLMOD; ordering the
    interface last never shrinks the factor."""
    import json

    from bench.ordering import main

    main(["--size", "0.3:8", "--repeat", "1", "--json"])
    rows = json.loads(capsys.readouterr().out)
    assert [r["ordering"] for r in rows] == ["vertex-nd", "node-nd", "amd"]
    for r in rows:
        assert r["last_nnz_L"] >= r["free_nnz_L"] > r["dof"]
        assert r["free_total_s"] == pytest.approx(r["order_s"] + r["free_symbolic_s"] + r["free_numeric_s"])
