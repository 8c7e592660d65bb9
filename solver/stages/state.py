"""What passes between the stages of one case: its loads, their forward halves, the solution."""
from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np

from ..contact.bolt import BoltTrial
from ..lining.joints import JointResults
from ..spec import CaseSpec


#: Relative gap (to the largest displacement) below which a node counts as closed.
CONTACT_GAP_TOL = 1e-6
#: KKT residual every answer meets whatever its inner tolerance (exact active sets reach
#: 1e-10 or less; the field measured over the test suite's cases stays below 1e-7).
KKT_ACCEPT = 1e-6


def accepted_residual(tolerance: float) -> float:
    """The largest discrete KKT residual (:func:`solver.contact.kkt.kkt_residual`) of an answer given
    as a result: the case's ``solver.tolerance`` or :data:`KKT_ACCEPT`, whichever is larger."""
    return max(tolerance, KKT_ACCEPT)


@dataclass(frozen=True)
class StageLoads:
    """Free-DOF loads (N/m) of one case: the contact stage's ground and lining loads, and
    the full excavation load ``release`` (None for ``wished-in-place``; stage 1 releases
    λd of it, the contact stage the rest)."""

    ground: np.ndarray
    lining: np.ndarray
    release: np.ndarray | None
    #: the seepage force of a drained lining's stage 2 (already in ``ground``), or None
    seepage: np.ndarray | None = None


@dataclass(frozen=True)
class Forward:
    """A case's loads solved forward (:meth:`FactoredBody.forward`): the contact stage's
    ground and lining loads and, for a staged excavation, the whole release r and λd."""

    ground: np.ndarray
    lining: np.ndarray
    release: np.ndarray | None = None
    deconfinement: float = 0.0


@dataclass(frozen=True)
class Installation:
    """How a face-distance case's λd was found (:mod:`solver.stages.face`): the profile's u*,
    the radius R (m) and R* it used, and, for ground that can yield, the full-release wall
    convergence u_max (m; NaN for elastic ground, where only the ratio matters) and the
    full-release ground reaction curve [(released, convergence)]."""

    deconfinement: float
    ldp_ratio: float
    radius: float
    plastic_ratio: float
    full_release_convergence: float = float("nan")
    full_release_curve: tuple = ()


@dataclass
class Solution:
    """The solved contact stage of one case, in SI units.

    u_ground : (2, Ng) m, ground displacement since excavation (stages 1 + 2), or since the
        stress-free start for ``wished-in-place``; u_stage1 : (2, Ng) m, stage 1 alone.
    u_lining : (2, Nl) m, lining displacement since placement.
    lam, shear : (m,) Pa, contact pressure and shear traction on the lining.
    normal_jump, tangential_jump : (m,) m, [u]ν and [u]τ of the contact stage.
    in_contact, slipping : (m,) bool, closed nodes (all of them for ``bonded``) and those of
        them that slip (a tangential jump, which the bond forbids).
    """

    spec: CaseSpec
    u_ground: np.ndarray
    u_stage1: np.ndarray
    u_lining: np.ndarray
    lam: np.ndarray
    shear: np.ndarray
    normal_jump: np.ndarray
    tangential_jump: np.ndarray
    in_contact: np.ndarray
    slipping: np.ndarray
    a: float | np.ndarray
    bolt: int | None
    trials: list["BoltTrial"]
    iterations: int
    admissible: bool
    F2: float
    kkt_residual: float
    timings: dict = field(default_factory=dict)
    #: N/m: the (half) lining's weight, and the upward resultant of the water on its extrados
    lining_weight: float = 0.0
    water_uplift: float = 0.0
    #: water: (N,) pore pressure at the ground's nodes after stage 2 (Pa; hydrostatic unless
    #: drained), (m,) water pressure on the lining's extrados (Pa), inflow (m³/s per metre)
    pore: np.ndarray | None = None
    water_pressure: np.ndarray | None = None
    water_inflow: float = 0.0
    #: a drained case's hydraulic head at the ground's nodes (m; the unconfined seepage's), else None
    water_head: np.ndarray | None = None
    #: yielding ground (:func:`solver.stages.plastic.solve_staged`): effective stress, yield flags and
    #: equivalent plastic strain at the sub-triangle centroids, iterations, ground reaction curve
    plastic: dict | None = None
    #: a segmental lining's joints (:class:`solver.lining.joints.JointResults`) and its bolt set
    joints: "JointResults | None" = None
    #: a face-distance case: how its λd was found (:class:`solver.stages.face.Installation`)
    installation: Installation | None = None

    @property
    def gap(self) -> np.ndarray:
        return self.spec.geometry.gap - self.normal_jump
