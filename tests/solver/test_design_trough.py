"""The design settlement trough (SPEC §9.3) against the closed forms of the Gaussian, and the case
name outside the id."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from solver import CaseSpec
from solver.results.settlement import design_trough
from solver.run import run_case

COARSE = {"interface_size": 0.25, "far_size": 8.0}


@pytest.mark.parametrize("volume_loss, K, depth, R", [(0.01, 0.5, 15.0, 2.8), (0.005, 0.3, 25.0, 4.0)])
def test_design_trough_closed_forms(volume_loss, K, depth, R):
    """S(x) = S_max exp(-x²/2i²), i = K z0, √(2π) i S_max = V_L π R².
    dS/dx = -(x/i²) S: d²S/dx² = 0 at x = i, so max |dS/dx| = (S_max/i) e^(-1/2)
    = V_L π R² e^(-1/2) / (√(2π) i²) = 0.2420 V_L π R² / i².
    Horizontal displacement towards the axis u = x S / z0, strain ε = -du/dx = -(S/z0)(1 - x²/i²)
    (tension positive); dε/dx = 0 at x = 0 and x = √3 i, where ε = (S_max/z0) 2 e^(-3/2) = 0.4463 S_max/z0."""
    i = K * depth
    x = np.linspace(0.0, 6 * i, 600001)
    out = design_trough(x, 0.123, R, depth, SimpleNamespace(volume_loss=volume_loss, trough_width_factor=K))
    volume = volume_loss * math.pi * R ** 2
    s_max = volume / (math.sqrt(2 * math.pi) * i)
    assert out["max_settlement"] == pytest.approx(s_max, rel=1e-12)
    assert 2 * np.trapezoid(out["settlement"], x) == pytest.approx(volume, rel=1e-6)   # both halves
    assert out["max_slope"] == pytest.approx(0.24197 * volume / i ** 2, rel=1e-4)
    slope = np.gradient(out["settlement"], x)
    assert out["max_slope"] == pytest.approx(np.abs(slope).max(), rel=1e-6)
    assert x[np.argmax(np.abs(slope))] == pytest.approx(i, rel=1e-3)
    strain = -np.gradient(x * out["settlement"] / depth, x)
    assert out["max_horizontal_strain"] == pytest.approx(strain.max(), rel=1e-6)
    assert out["max_horizontal_strain"] == pytest.approx(0.44626 * s_max / depth, rel=1e-4)
    assert x[np.argmax(strain)] == pytest.approx(math.sqrt(3) * i, rel=1e-3)
    assert strain[0] == pytest.approx(-s_max / depth, rel=1e-9)   # compressive above the axis


def test_design_trough_defaults_to_the_ground_loss():
    x = np.linspace(0, 30, 7)
    out = design_trough(x, 0.004, 2.8, 15.0, SimpleNamespace(volume_loss=None, trough_width_factor=0.5))
    assert out["volume_loss"] == 0.004
    assert out["max_settlement"] == pytest.approx(0.004 * math.pi * 2.8 ** 2 / (math.sqrt(2 * math.pi) * 7.5))


def test_case_design_trough_name_and_id():
    """On a solved case: the design trough of the given volume loss and width factor; the name in the
    attrs, not in the canonical JSON or the id."""
    spec = CaseSpec.model_validate({"mesh": COARSE, "name": "Contract 4, km 12+300",
                                    "settlement": {"volume_loss": 0.01, "trough_width_factor": 0.4}})
    ds = run_case(spec)
    R, z0 = spec.geometry.hole_radius, spec.geometry.depth
    i = 0.4 * z0
    s_max = 0.01 * math.pi * R ** 2 / (math.sqrt(2 * math.pi) * i)
    assert float(ds.design_max_settlement) == pytest.approx(s_max, rel=1e-12)
    x = ds.surface_x.values
    np.testing.assert_allclose(ds.design_settlement.values, s_max * np.exp(-x ** 2 / (2 * i * i)), rtol=1e-12)
    assert float(ds.max_slope) == pytest.approx(s_max * math.exp(-0.5) / i, rel=1e-12)
    assert float(ds.max_horizontal_strain) == pytest.approx(2 * math.exp(-1.5) * s_max / z0, rel=1e-12)
    assert ds.attrs["case_name"] == "Contract 4, km 12+300"
    assert "Contract" not in ds.attrs["case_spec"]
    unnamed = CaseSpec.model_validate({"mesh": COARSE, "settlement": {"volume_loss": 0.01,
                                                                      "trough_width_factor": 0.4}})
    assert unnamed.case_id == spec.case_id == ds.attrs["case_id"]
    assert unnamed.case_id != CaseSpec.model_validate({"mesh": COARSE}).case_id   # the trough is an input
    # the default trough is the Gaussian holding the case's own ground loss
    plain = run_case(CaseSpec.model_validate({"mesh": COARSE}))
    assert float(plain.design_max_settlement) == float(plain.gaussian_max_settlement)
    assert "case_name" not in plain.attrs


def test_round4_defaults_keep_ids():
    base = CaseSpec()
    same = CaseSpec.model_validate({"design": {"crack_width_limit": 0.3e-3, "bar_diameter": 0.014},
                                    "settlement": {"volume_loss": None, "trough_width_factor": 0.5},
                                    "name": "anything"})
    assert same.case_id == base.case_id
    assert "settlement" not in json.loads(base.canonical_json())
    assert "crack_width_limit" not in json.loads(base.canonical_json())["design"]
    assert CaseSpec.model_validate({"design": {"crack_width_limit": 0.2e-3}}).case_id != base.case_id


@pytest.mark.parametrize("name", ["x" * 121, "two\nlines", 42])
def test_bad_names_refused(name):
    with pytest.raises(ValidationError, match="name"):
        CaseSpec.model_validate({"name": name})
    assert CaseSpec.model_validate({"name": "x" * 120}).name == "x" * 120
