"""The joints of a segmental lining (SPEC §1.6) on the figures of one case.

A result with joints has the dim ``joint`` (``joint_theta``, ``joint_open``, ...); one without
draws nothing here. Closed joints are drawn dashed in dark grey, open ones solid in orange,
wherever they appear: ticks across the ring diagrams, lines along θ, the joint faces across the
lining on the mesh, the joint stations on the N–M diagram. Every artist carries the gid
``joint-closed`` or ``joint-open`` (one per joint and panel), so a test or a reader of an SVG can
find them.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

#: (colour, line style) of a closed and of an open joint.
CLOSED_STYLE = ("0.2", (0, (4, 2)))
OPEN_STYLE = ("darkorange", "-")


def has_joints(ds: xr.Dataset) -> bool:
    """Whether ``ds`` is the result of a segmental lining."""
    return "joint_theta" in ds.variables and ds.sizes.get("joint", 0) > 0


def joints(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """``(theta in deg, open as bool)`` of the joints, crown to invert (empty without joints)."""
    if not has_joints(ds):
        return np.zeros(0), np.zeros(0, bool)
    return ds["joint_theta"].values.astype(float), ds["joint_open"].values.astype(bool)


def style(is_open: bool) -> dict:
    """Matplotlib keywords of a joint's line: colour, style and gid (``joint-open``/``joint-closed``)."""
    color, ls = OPEN_STYLE if is_open else CLOSED_STYLE
    return {"color": color, "ls": ls, "gid": "joint-open" if is_open else "joint-closed"}


def legend_label(is_open: bool, first: bool) -> str | None:
    """The legend entry of a joint's line: the first of each kind only."""
    return ("joint, open" if is_open else "joint, closed") if first else None


def draw_on_theta(ax, ds: xr.Dataset, *, labels: bool = True) -> None:
    """A vertical line at each joint on an axis of θ (deg), with a legend entry per kind
    (``labels``)."""
    seen: set[bool] = set()
    for theta, is_open in zip(*joints(ds)):
        label = legend_label(is_open, is_open not in seen) if labels else None
        ax.axvline(theta, lw=1.1, zorder=2.5, label=label, **style(is_open))
        seen.add(is_open)


def draw_on_ring(ax, ds: xr.Dataset, radius: float, *, reach: float = 0.42) -> None:
    """A radial tick through the ring diagram of mid-surface ``radius`` at each joint, from
    (1 − reach) to (1 + reach) radii (the diagrams' offsets reach 0.35 radius), with the
    joint's θ at its outer end."""
    for theta, is_open in zip(*joints(ds)):
        t = np.radians(theta)
        r = radius * np.array([1 - reach, 1 + reach])
        ax.plot(r * np.sin(t), r * np.cos(t), lw=1.2, zorder=1.5, **style(is_open))
        ax.plot(radius * np.sin(t), radius * np.cos(t), "o", ms=4.5, mfc="white", mec=style(is_open)["color"],
                zorder=3.5, gid=style(is_open)["gid"])


def ring_legend_handles(ds: xr.Dataset) -> list:
    """Legend handles of the joint kinds present (for a figure-level legend)."""
    from matplotlib.lines import Line2D

    kinds = sorted(set(joints(ds)[1].tolist()))
    return [Line2D([], [], lw=1.2, marker="o", mfc="white", mec=style(k)["color"], label=legend_label(k, True),
                   **{key: v for key, v in style(k).items() if key != "gid"}) for k in kinds]


def joint_faces(ds: xr.Dataset) -> list[tuple[float, bool, list[np.ndarray]]]:
    """Per joint ``(theta, open, faces)``: the lining nodes of each of its faces (the crown-side
    face first; one face for a joint on the symmetry line), ordered from the intrados out.

    Found from the mesh alone: the lining's nodes on the joint's cut (the lining's normal through
    the joint's interface station: a radial line on a circle), split by the side of the cut their
    triangles lie on (the two faces' nodes are distinct copies at one place).
    """
    if not has_joints(ds):
        return []
    x, y = ds["node_x"].values, ds["node_y"].values
    center = np.array([0.0, float(np.mean(ds["interface_y"].values[[0, -1]]))])
    tri = ds["face_nodes"].values.astype(np.int64)[:, :3][ds["body"].values == 1]
    xy = np.stack([x, y])
    station = np.stack([ds["interface_x"].values, ds["interface_y"].values])
    normal = np.stack([ds["normal_x"].values, ds["normal_y"].values])
    theta_i = ds["theta"].values
    reach = np.hypot(*(station - center[:, None]))
    scale, near = float(reach.max()), 0.5 * float(reach.min())  # the lining lies within ``near`` of a station
    out = []
    for theta, is_open in zip(*joints(ds)):
        k = int(np.argmin(np.abs(theta_i - theta)))
        n = normal[:, k] * np.sign(normal[:, k] @ (station[:, k] - center))  # outward
        t = np.array([n[1], -n[0]])  # towards increasing θ (clockwise on the right half)
        rel = xy - station[:, k:k + 1]
        along, across = t @ rel, n @ rel
        # (F, 3) corners on the cut (the line also crosses the lining's far side: not that piece)
        at = (np.abs(along) < 1e-7 * scale)[tri] & (np.abs(across) < near)[tri]
        centroid = t @ (xy[:, tri].mean(axis=2) - station[:, k:k + 1])
        touching = at.any(axis=1)
        faces = []
        for side in (centroid < 0.0, centroid > 0.0):
            nodes = np.unique(tri[touching & side][at[touching & side]])
            if nodes.size > 1:
                faces.append(nodes[np.argsort(across[nodes])])
        out.append((float(theta), bool(is_open), faces))
    return out


def contact_height(ds: xr.Dataset) -> float:
    """The joints' contact strip height a (m)."""
    return float(ds["joint_eccentricity"].attrs.get("contact_height_m", ds.attrs.get("joint_contact_height_m",
                                                                                       np.nan)))


def draw_on_interaction(ax, ds: xr.Dataset, gamma: float, top: float) -> None:
    """The joints on an N–M diagram of design actions (kN·m/m across, kN/m up, factor ``gamma``):
    each joint's (γM, γN) as a diamond, and the strip's limits |M| = N·a/2 as two rays from
    the origin up to thrust ``top`` (kN/m): a joint carries its thrust within its strip while
    its diamond lies between them. The section's envelope does not apply at a joint."""
    if not has_joints(ds):
        return
    half = 0.5 * contact_height(ds)
    ax.plot([-half * top, 0.0, half * top], [top, 0.0, top], color=OPEN_STYLE[0], lw=1.0, ls=":", zorder=2,
            gid="joint-limit", label=f"joints' strip limit |M| = N·a/2 (a = {2 * half:g} m; not the envelope)")
    n = gamma * ds["joint_thrust"].values / 1e3
    m = gamma * ds["joint_moment"].values / 1e3
    seen: set[bool] = set()
    for mj, nj, is_open in zip(m, n, joints(ds)[1]):
        label = None if is_open in seen else ("joints, open" if is_open else "joints, closed")
        ax.plot(mj, nj, "D", ms=7, mfc="white", mec=style(is_open)["color"], mew=1.5, zorder=4,
                gid=style(is_open)["gid"], label=label)
        seen.add(is_open)


def summary(ds: xr.Dataset) -> str:
    """``"4 joints, 2 open"`` (empty without joints)."""
    theta, is_open = joints(ds)
    return f"{theta.size} joint{'s' * (theta.size != 1)}, {int(is_open.sum())} open" if theta.size else ""


def draw_on_mesh(ax, ds: xr.Dataset, *, scale: float = 0.0, displacement=None) -> None:
    """Each joint's faces as lines across the lining, at the nodes displaced by ``scale`` times
    their displacement (0: undeformed; ``displacement`` (ux, uy) in the figure's reference, else
    the stored one), so a magnified open joint shows its wedge."""
    x, y = ds["node_x"].values, ds["node_y"].values
    if scale:
        ux, uy = displacement if displacement is not None else (ds["displacement_x"].values,
                                                                ds["displacement_y"].values)
        x, y = x + scale * ux, y + scale * uy
    seen: set[bool] = set()
    for _, is_open, faces in joint_faces(ds):
        for face in faces:
            ax.plot(x[face], y[face], lw=2.2, zorder=4, solid_capstyle="butt",  # solid: too short to dash
                    label=legend_label(is_open, is_open not in seen), **{**style(is_open), "ls": "-"})
            seen.add(is_open)
