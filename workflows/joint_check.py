"""The design statement at the joints of a segmental lining (SPEC §1.6, issue 26).

At a joint the lining's section is the joint's contact strip, of height a: the EN 1992 check of
the full section (``utilization``) is made away from the joints, and at each joint two questions
are asked. Does the strip carry the thrust within its height, |M| ≤ N·a/2
(``joint_eccentricity`` ≤ 1; the contact solution keeps it so, and an open joint bears on its
strip's edge, at 1)? And does the strip hold, EN 1992-1-1 (12.10) on it as a plain section at the
joint's design thrust (``joint_utilization`` ≤ 1, :func:`solver.lining.design.joint_utilization`): a
hinging joint needs a stress block at its edge, so it passes only if the strip leaves room for it.
A joint opens where |M|/N exceeds about a/6 (``joint_eccentricity`` > 1/3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from solver.results.variables import ECCENTRICITY_LIMIT

from .joint_plots import contact_height, has_joints


@dataclass(frozen=True)
class JointCheck:
    """The joints of one result: how many, how many open, the largest |M|/(N a/2) and the
    joint's θ (deg) where it is, the strip height a (m), the largest EN 1992 utilization of a
    strip and the θ of that joint, and whether every joint passes both."""

    count: int
    open: int
    worst: float
    theta: float
    height: float
    utilization: float = 0.0
    utilization_theta: float = 0.0

    @property
    def passes(self) -> bool:
        return bool(self.worst <= ECCENTRICITY_LIMIT and self.utilization <= 1.0)


def _largest(values: np.ndarray) -> int:
    return int(np.argmax(np.where(np.isnan(values), np.inf, values)))  # a NaN fails


def joint_check(ds: xr.Dataset) -> JointCheck | None:
    """The joints' check of a result (None for a monolithic lining)."""
    if not has_joints(ds):
        return None
    ratio = ds["joint_eccentricity"].values
    k = _largest(ratio)
    theta = ds["joint_theta"].values
    eta = ds["joint_utilization"].values if "joint_utilization" in ds else np.zeros_like(ratio)
    u = _largest(eta)
    return JointCheck(count=int(ratio.size), open=int(np.count_nonzero(ds["joint_open"].values)),
                      worst=float(ratio[k]) if not np.isnan(ratio[k]) else math.inf,
                      theta=float(theta[k]), height=contact_height(ds),
                      utilization=float(eta[u]) if not np.isnan(eta[u]) else math.inf,
                      utilization_theta=float(theta[u]))


def statement(passes: bool, worst: float, count: int | None = None, utilization: float | None = None) -> str:
    """The one-line statement of the joints' check, from its largest |M|/(N a/2) and, when
    given, its largest EN 1992 (12.10) utilization of a strip."""
    where = f"at all {count} joints" if count else "at every joint"
    inside = worst <= ECCENTRICITY_LIMIT
    if inside:
        text = f"the thrust acts within the contact strip {where}: |M| ≤ N·a/2 (largest |M|/(N·a/2) = {worst:.3g})"
    else:
        text = f"the thrust leaves the contact strip: |M|/(N·a/2) = {worst:.3g} > 1 at a joint"
    if utilization is not None:
        holds = utilization <= 1.0
        text += (f"; EN 1992-1-1 (12.10) on the strip: η = {utilization:.3g} "
                 + ("≤ 1" if holds else "> 1, the strip's edge is overloaded (a wider strip, or joints away from "
                    "the moment's peaks)"))
    return text


def joint_report(ds: xr.Dataset) -> str:
    """The joints' check in words (empty for a monolithic lining): the statement, then where
    the largest eccentricity and utilization are and how many joints opened."""
    check = joint_check(ds)
    if check is None:
        return ""
    verdict = "passes" if check.passes else "fails"
    return (f"joints ({verdict}; contact strip a = {check.height:g} m): "
            f"{statement(check.passes, check.worst, check.count, check.utilization)}\n"
            f"  largest |M|/(N·a/2) at θ = {check.theta:.1f}°, largest η at θ = {check.utilization_theta:.1f}°; "
            f"{check.open} of {check.count} joints open")
