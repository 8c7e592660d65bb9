"""Before and after, in one run: the P1 solver (the last P1 commit) against today's P2 solver.

The cos 2θ moment of a ring in a 30-radii medium (external loading, full slip, K = 0.5)
against the exact annulus, for a thick (t/a = 0.12) and a thin (t/a = 0.025) lining, at
each solver's default interface_size and two refinements: DOF, seconds, moment error.
First, each tree's default case (`run_case(CaseSpec())`, median of five after a warm-up),
twice, alternating: the P1 commit's one-stage default against today's staged default.
The P1 code is checked out of this repository's history into a temporary git worktree
and run in a subprocess with the same Python environment.

    python -m bench.p1_vs_p2 [--json] [--p1-commit a076fe8] [--default-only]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from bench import print_rows
from solver.analytic import exact_ring

P1_COMMIT = "a076fe8"  # last commit with linear triangles
ROOT = Path(__file__).resolve().parents[1]

_PROBE = r"""
import json, sys, time, logging
import numpy as np
logging.disable(logging.WARNING)
from solver import run_case
from solver.analytic import ring_in_medium_case
out = []
for t, h in json.loads(sys.argv[1]):
    t0 = time.perf_counter()
    ds = run_case(ring_in_medium_case(radii=30, K=0.5, thickness=t, h=h))
    sec = time.perf_counter() - t0
    w, c = ds.weight.values, np.cos(2 * np.radians(ds.theta.values))
    out.append({"t": t, "h": h, "dof": 2 * ds.sizes["node"], "seconds": sec,
                "M2": float(np.sum(w * ds.moment.values * c) / np.sum(w * c * c))})
print(json.dumps(out))
"""

_DEFAULT = r"""
import json, logging, statistics, time
logging.disable(logging.WARNING)
from solver import CaseSpec, run_case
run_case(CaseSpec())
seconds = []
for _ in range(5):
    t0 = time.perf_counter()
    ds = run_case(CaseSpec())
    seconds.append(time.perf_counter() - t0)
print(json.dumps({"median_s": statistics.median(seconds), "dof": 2 * ds.sizes["node"],
                  "max_abs_moment": float(ds.max_abs_moment)}))
"""

GRID = {"P1": [0.05, 0.035, 0.025], "P2": [0.1, 0.05, 0.025]}
THICKNESS = [0.3, 0.0625]


def _run(tree: Path, cases, probe: str = _PROBE) -> list[dict] | dict:
    done = subprocess.run([sys.executable, "-c", probe, json.dumps(cases)], cwd=tree,
                          capture_output=True, text=True, env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"})
    if done.returncode:
        raise RuntimeError(f"{tree}: {done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--p1-commit", default=P1_COMMIT)
    ap.add_argument("--default-only", action="store_true",
                    help="only the default case's run_case time, each tree twice, alternating")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "p1"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(old), args.p1_commit],
                       check=True, capture_output=True)
        try:
            for _ in range(2):  # alternating, so drift of the machine's speed hits both
                for label, tree in (("P1 default case (one stage)", old), ("P2 default case (two stages)", ROOT)):
                    rows.append({"elements": label, **_run(tree, [], _DEFAULT)})
            for label, tree in (() if args.default_only else (("P1", old), ("P2", ROOT))):
                cases = [(t, h) for t in THICKNESS for h in GRID[label]]
                if label == "P1":  # the P1 element cap stops the thin lining's finest mesh
                    cases = [(t, h) for t, h in cases if not (t < 0.1 and h < 0.035)]
                for r in _run(tree, cases):
                    ex = exact_ring(1e5, 0.5, 5e7, 0.3, 3e10, 0.2, 2.5, 2.5 + r["t"], loading="external",
                                    interface="slip")
                    rows.append({"elements": label, "t_over_a": r["t"] / 2.5, "interface_size": r["h"],
                                 "dof": r["dof"], "seconds": r["seconds"], "M2_error": r["M2"] / ex.M2 - 1})
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(old)], capture_output=True)
    print_rows(rows, as_json=args.json)


if __name__ == "__main__":
    main()
