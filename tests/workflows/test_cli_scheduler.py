"""`tunnel-contact sweep --scheduler ADDR` against a separate dask scheduler and worker."""
from __future__ import annotations

import json
import subprocess
import sys

from service.process import running_cluster
from solver import CaseSpec
from workflows import open_case

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


def test_cli_sweep_on_an_external_scheduler(tmp_path):
    (tmp_path / "sweep.json").write_text(json.dumps(
        {"name": "ext", "base": COARSE, "vary": {"ground.young": [3e7, 6e7]}}))
    ids = [CaseSpec.model_validate({**COARSE, "ground": {"young": e}}).case_id for e in (3e7, 6e7)]
    with running_cluster(1, logs=tmp_path) as address:
        run = subprocess.run([sys.executable, "-m", "service.cli", "sweep", "sweep.json",
                              "--scheduler", address, "--results", "out"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    for case_id in ids:
        assert case_id in run.stdout
        ds = open_case(tmp_path / "out", case_id)
        assert int(ds.converged) == 1
