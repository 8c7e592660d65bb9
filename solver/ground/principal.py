"""Principal stresses of plane strain and back: what every isotropic yield law and its tangent share."""
from __future__ import annotations

import numpy as np
from numba import njit


def principal(stress: np.ndarray):
    """Principal values of plane-strain stresses (4, ...) = (xx, yy, xy, zz): the in-plane pair
    (major, minor), the major direction as ``(cos 2θ, sin 2θ)`` (θ from x; (1, 0) where the in-plane
    stress is isotropic) and σzz. No angle is formed: :func:`from_principal` needs only these."""
    sxx, syy, sxy, szz = stress
    c = 0.5 * (sxx + syy)
    d = 0.5 * (sxx - syy)
    r = np.hypot(d, sxy)
    some = r > 0.0
    c2 = np.divide(d, r, out=np.ones_like(r), where=some)
    s2 = np.divide(sxy, r, out=np.zeros_like(r), where=some)
    return c + r, c - r, (c2, s2), szz


def from_principal(major, minor, direction, szz) -> np.ndarray:
    """Plane-strain stress components (4, ...) from in-plane principal values along ``direction``
    (``(cos 2θ, sin 2θ)`` of the major one, as :func:`principal` gives it)."""
    c2, s2 = direction
    mid = 0.5 * (major + minor)
    rad = 0.5 * (major - minor)
    return np.stack(np.broadcast_arrays(mid + rad * c2, mid - rad * c2, rad * s2, szz))


def descending(major, minor, szz):
    """The principal values sorted σ1 ≥ σ2 ≥ σ3, (3, m), and the permutation ``(top, mid)``: where σzz
    is the largest, where it is the intermediate (``major ≥ minor`` always; ties keep the order major,
    minor, zz, as a stable sort would). Three cases, so a few selections instead of a sort."""
    top = szz > major
    mid = (szz > minor) & ~top
    return np.stack([np.where(top, szz, major), np.where(top, major, np.where(mid, szz, minor)),
                     np.where(top | mid, minor, szz)]), (top, mid)


def unsorted(x: np.ndarray, perm) -> np.ndarray:
    """Rows (3, m) in :func:`descending`'s order back in the slots (major, minor, zz)."""
    top, mid = perm
    return np.stack([np.where(top, x[1], x[0]), np.where(top | mid, x[2], x[1]),
                     np.where(top, x[0], np.where(mid, x[1], x[2]))])


def order_of(perm) -> np.ndarray:
    """:func:`descending`'s permutation as indices (3, m): the slot (0 major, 1 minor, 2 zz) of each sorted row."""
    top, mid = perm
    return np.stack([np.where(top, 2, 0), np.where(top, 0, np.where(mid, 2, 1)), np.where(top | mid, 1, 2)])


# The same at one point, compiled: what the yield laws' compiled returns share (solver.ground.mohr_coulomb,
# solver.ground.hoek_brown), one pass over the points with no temporaries.

@njit(cache=True)
def extremes(trial, i):
    """The largest and least principal stresses (σ1, σ3) of point ``i`` of ``trial`` (4, n), without sorting."""
    mid, d = 0.5 * (trial[0, i] + trial[1, i]), 0.5 * (trial[0, i] - trial[1, i])
    rad = np.sqrt(d * d + trial[2, i] * trial[2, i])
    return max(mid + rad, trial[3, i]), min(mid - rad, trial[3, i])


@njit(cache=True)
def sorted_at(trial, i, st):
    """Point ``i``'s principal stresses sorted σ1 ≥ σ2 ≥ σ3 into ``st`` (3,) as :func:`descending` sorts them;
    returns its permutation ``(top, mid)`` and its major in-plane direction ``(cos 2θ, sin 2θ)`` (:func:`principal`'s):
    what :func:`put_back` takes."""
    mid, d = 0.5 * (trial[0, i] + trial[1, i]), 0.5 * (trial[0, i] - trial[1, i])
    rad = np.sqrt(d * d + trial[2, i] * trial[2, i])
    major, minor, szz = mid + rad, mid - rad, trial[3, i]
    top = szz > major
    middle = szz > minor and not top
    st[0] = szz if top else major
    st[1] = major if top else (szz if middle else minor)
    st[2] = minor if (top or middle) else szz
    c2, s2 = (d / rad, trial[2, i] / rad) if rad > 0.0 else (1.0, 0.0)
    return top, middle, c2, s2


@njit(cache=True)
def put_back(i, top, middle, c2, s2, res, ep, stress, dep):
    """Sorted principal stresses ``res`` and plastic strain increments ``ep`` (3,) of point ``i`` back in the
    slots (major, minor, zz) (:func:`unsorted`) and along its trial's in-plane directions (:func:`from_principal`;
    the permutation and direction :func:`sorted_at` gave): ``stress[:, i]`` (4, n) and ``dep[:, i]`` (3, n)."""
    if top:
        a, b, z, ea, eb, ez = res[1], res[2], res[0], ep[1], ep[2], ep[0]
    elif middle:
        a, b, z, ea, eb, ez = res[0], res[2], res[1], ep[0], ep[2], ep[1]
    else:
        a, b, z, ea, eb, ez = res[0], res[1], res[2], ep[0], ep[1], ep[2]
    m2, r2 = 0.5 * (a + b), 0.5 * (a - b)
    stress[0, i], stress[1, i], stress[2, i], stress[3, i] = m2 + r2 * c2, m2 - r2 * c2, r2 * s2, z
    dep[0, i], dep[1, i], dep[2, i] = ea, eb, ez
