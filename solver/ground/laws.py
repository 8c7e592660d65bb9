"""The yield laws of a set of points (SPEC §1.5, §9.1): Mohr–Coulomb and Hoek–Brown side by side.

A layered ground may mix laws; the staged driver (:mod:`solver.stages.plastic`) returns every
trial stress through :meth:`PointLaws.return_stress`, which hands each law its own points (the
laws share one signature: trial (4, n) and per-point material in, stress, plastic strain
increment and at-yield flags out).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import hoek_brown, mohr_coulomb

#: The laws that yield, by the name ``ground.model`` gives them.
LAWS = {"mohr-coulomb": mohr_coulomb, "hoek-brown": hoek_brown}


@dataclass(frozen=True)
class PointLaws:
    """Per law (its module), the positions of its points among the set's and their material."""

    groups: tuple[tuple[object, np.ndarray, object], ...]

    @classmethod
    def of(cls, law: np.ndarray, lam: np.ndarray, mu: np.ndarray, field) -> "PointLaws":
        """From each point's law name ``law`` (n,), Lamé's λ, μ (n,) and ``field(name)``: a
        strength field's values at the points (n,)."""
        groups = []
        for name, module in LAWS.items():
            at = np.flatnonzero(law == name)
            if at.size == 0:
                continue
            if module is mohr_coulomb:
                material = mohr_coulomb.Material.of(at.size, lam[at], mu[at], *(
                    field(k)[at] for k in ("cohesion", "friction_angle", "dilatancy", "tensile_strength")))
            else:
                material = hoek_brown.HBMaterial.of(at.size, lam[at], mu[at], *(
                    field(k)[at] for k in ("ucs", "gsi", "mi", "disturbance", "dilatancy", "tensile_strength")))
            groups.append((module, at, material))
        return cls(tuple(groups))

    def at(self, index: np.ndarray) -> "PointLaws":
        """The laws of the points ``index`` (positions among this set's, ascending)."""
        index = np.asarray(index)
        groups = []
        for module, at, material in self.groups:
            keep = np.isin(at, index)
            if keep.any():
                groups.append((module, np.searchsorted(index, at[keep]), material.at(np.flatnonzero(keep))))
        return PointLaws(tuple(groups))

    def return_stress(self, trial: np.ndarray, flag_tolerance: float):
        """``(stress (4, n), plastic strain increment (3, n), at_yield (n,))`` of trial stresses
        (4, n) at the set's points, each by its own law."""
        if len(self.groups) == 1 and self.groups[0][1].size == trial.shape[1]:
            module, _, material = self.groups[0]
            return module.return_stress(trial, material, flag_tolerance)
        stress, dep = trial.copy(), np.zeros((3, trial.shape[1]))
        flags = np.zeros(trial.shape[1], bool)
        for module, at, material in self.groups:
            stress[:, at], dep[:, at], flags[at] = module.return_stress(trial[:, at], material, flag_tolerance)
        return stress, dep, flags
