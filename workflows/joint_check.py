"""The design statement at the joints of a segmental lining (SPEC §1.6, issue 26).

At a joint the lining's section is the joint's contact strip, of height a: the EN 1992 check of
the full section (``utilization``) is made away from the joints, and at each joint the question
is whether the strip carries the thrust within its height, |M| ≤ N·a/2 (``joint_eccentricity``
≤ 1). A joint opens where |M|/N exceeds about a/6 (``joint_eccentricity`` > 1/3); at 1 the thrust
sits on the strip's edge and the joint turns as a hinge about it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from solver.dataset import ECCENTRICITY_LIMIT

from .joint_plots import contact_height, has_joints


@dataclass(frozen=True)
class JointCheck:
    """The joints of one result: how many, how many open, the largest |M|/(N a/2) and the
    joint's θ (deg) where it is, the strip height a (m), and whether every joint passes."""

    count: int
    open: int
    worst: float
    theta: float
    height: float

    @property
    def passes(self) -> bool:
        return bool(self.worst <= ECCENTRICITY_LIMIT)


def joint_check(ds: xr.Dataset) -> JointCheck | None:
    """The joints' check of a result (None for a monolithic lining)."""
    if not has_joints(ds):
        return None
    ratio = ds["joint_eccentricity"].values
    k = int(np.argmax(np.where(np.isnan(ratio), np.inf, ratio)))  # a NaN ratio fails
    return JointCheck(count=int(ratio.size), open=int(np.count_nonzero(ds["joint_open"].values)),
                      worst=float(ratio[k]) if not np.isnan(ratio[k]) else math.inf,
                      theta=float(ds["joint_theta"].values[k]), height=contact_height(ds))


def statement(passes: bool, worst: float, count: int | None = None) -> str:
    """The one-line statement of the joints' check, from its largest |M|/(N a/2)."""
    where = f"at all {count} joints" if count else "at every joint"
    if passes:
        return f"the thrust acts within the contact strip {where}: |M| ≤ N·a/2 (largest |M|/(N·a/2) = {worst:.3g})"
    return f"the thrust leaves the contact strip: |M|/(N·a/2) = {worst:.3g} > 1 at a joint"


def joint_report(ds: xr.Dataset) -> str:
    """The joints' check in words (empty for a monolithic lining): the statement, then where
    the largest eccentricity is and how many joints opened."""
    check = joint_check(ds)
    if check is None:
        return ""
    verdict = "passes" if check.passes else "fails"
    return (f"joints ({verdict}; contact strip a = {check.height:g} m): "
            f"{statement(check.passes, check.worst, check.count)}\n"
            f"  largest at θ = {check.theta:.1f}°; {check.open} of {check.count} joints open")
