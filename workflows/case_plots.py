"""Figures of one case result (matplotlib, no pyplot: nothing kept in a global registry).

Units shown: kPa (tractions), kN/m (thrust, shear force), kN·m/m (moment), mm
(settlements and gaps), θ in degrees from the crown (0) through the springline (90)
to the invert (180). Each function returns a :class:`matplotlib.figure.Figure`.
"""
from __future__ import annotations

import json

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from . import joint_plots
from .joint_check import joint_check

_CONTACT_COLOR = "tab:red"
_SLIP_COLOR = "tab:orange"
#: Lining stations named on the figures (θ in degrees).
STATIONS = {"crown": 0.0, "springline": 90.0, "invert": 180.0}


_WATER_COLOR = "tab:cyan"


def _spans(ax, theta: np.ndarray, on: np.ndarray, *, color: str, label: str, alpha: float = 0.12,
           hatch: str | None = None) -> None:
    """Shade the theta ranges where ``on`` holds (one legend entry)."""
    labelled = False
    for run in np.split(np.arange(theta.size), np.flatnonzero(np.diff(on.astype(int))) + 1):
        if run.size and on[run[0]]:
            ax.axvspan(theta[run[0]], theta[run[-1]], color=color, alpha=alpha, lw=0, hatch=hatch,
                       label=None if labelled else label)
            labelled = True


def _contact_spans(ax, ds: xr.Dataset) -> None:
    """Shade the theta ranges where the interface is in contact."""
    _spans(ax, ds["theta"].values, ds["in_contact"].values.astype(bool), color=_CONTACT_COLOR, label="in contact")


def theta_axis(ax, ds: xr.Dataset | None = None) -> None:
    """θ from crown to invert; for a section that is not a circle (SPEC §9.4), the stations' arc
    length along the extrados on a second axis above (θ alone hides how long each arc is)."""
    ax.set_xlim(0, 180)
    ax.set_xticks(np.arange(0, 181, 30))
    ax.set_xlabel("θ (deg from crown; 90 springline, 180 invert)")
    ax.grid(True, alpha=0.3)
    if ds is not None and "arc_length" in ds.coords and mid_surface(ds) is not None:
        theta, s = ds["theta"].values, ds["arc_length"].values
        top = ax.secondary_xaxis("top", functions=(lambda t: np.interp(t, theta, s), lambda a: np.interp(a, s, theta)))
        top.set_xlabel("arc length along the extrados from the crown (m)", fontsize="small")


def _title(ds: xr.Dataset) -> str:
    return f"case {ds.attrs.get('case_id', '?')}"


def case_spec(ds: xr.Dataset) -> dict:
    """The case specification stored with a result (``{}`` if absent)."""
    return json.loads(ds.attrs.get("case_spec", "{}"))


def load_factor(ds: xr.Dataset) -> float:
    """γF of the case (``design.load_factor``), 1 if the result has none."""
    return float(case_spec(ds).get("design", {}).get("load_factor", 1.0))


def station_name(theta: float) -> str:
    """The named station nearest ``theta`` (deg): crown, springline or invert."""
    return min(STATIONS, key=lambda name: abs(STATIONS[name] - theta))


def plot_contact_pressure(ds: xr.Dataset) -> Figure:
    """Contact pressure λ and gap (top), shear traction s (bottom) along the interface (kPa, mm).

    Contact zones are shaded in both panels, slipping zones (Coulomb) hatched in the
    shear panel; for ``coulomb`` the cone ±μλ is drawn dashed.
    """
    theta = ds["theta"].values
    model = ds.attrs.get("interface_model", case_spec(ds).get("interface", {}).get("model", "?"))
    fig = Figure(figsize=(7.5, 6.5), layout="constrained")
    ax, ax_s = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    _contact_spans(ax, ds)
    ax.plot(theta, ds["contact_pressure"] / 1e3, color="k", lw=1.5, label="contact pressure λ (effective)")
    top = float(np.nanmax(ds["contact_pressure"].values))
    water = ds["water_pressure"].values if "water_pressure" in ds else np.zeros_like(theta)
    if np.any(water > 0):  # a watertight lining below the table: the water acts beside λ
        ax.plot(theta, water / 1e3, color=_WATER_COLOR, lw=1.2, label="water pressure u")
        total = ds["contact_pressure"].values + water
        ax.plot(theta, total / 1e3, color=_WATER_COLOR, lw=1.2, ls=":", label="total λ + u")
        top = max(top, float(np.nanmax(total)))
    joint_plots.draw_on_theta(ax, ds)
    ax.set_ylabel("pressure on the extrados (kPa)")
    ax.set_ylim(bottom=0.0, top=1.15 * max(top / 1e3, 1e-3))
    theta_axis(ax, ds)
    ax.set_xlabel("")
    gap_ax = ax.twinx()
    gap_ax.plot(theta, ds["gap"] * 1e3, color="tab:blue", lw=1, ls="--", label="gap g0 − [u]ν")
    gap_ax.set_ylabel("gap (mm)", color="tab:blue")
    gap_ax.set_ylim(bottom=0.0, top=max(1.0, 1.1 * float(np.nanmax(ds["gap"].values)) * 1e3))
    lines, gap_lines = ax.get_legend_handles_labels(), gap_ax.get_legend_handles_labels()
    ax.legend(lines[0] + gap_lines[0], lines[1] + gap_lines[1], loc="lower right", fontsize="small")

    _contact_spans(ax_s, ds)
    if "slipping" in ds and model == "coulomb":  # frictionless slips everywhere, bonded nowhere
        slipping = ds["slipping"].values.astype(bool) & ds["in_contact"].values.astype(bool)
        _spans(ax_s, theta, slipping, color=_SLIP_COLOR, label="slipping", alpha=0.3, hatch="//")
    shear = ds["shear_traction"].values / 1e3 if "shear_traction" in ds else np.zeros_like(theta)
    ax_s.plot(theta, shear, color="tab:purple", lw=1.5, label="shear traction s (on lining, + towards θ↑)")
    friction = float(case_spec(ds).get("interface", {}).get("friction", 0.0))
    if model == "coulomb" and friction > 0:
        cone = friction * ds["contact_pressure"].values / 1e3
        ax_s.plot(theta, cone, color="0.4", lw=0.8, ls="--", label=f"Coulomb bound ±μλ, μ = {friction:g}")
        ax_s.plot(theta, -cone, color="0.4", lw=0.8, ls="--")
    ax_s.axhline(0.0, color="0.5", lw=0.8)
    joint_plots.draw_on_theta(ax_s, ds, labels=False)
    if model == "frictionless":
        ax_s.text(0.5, 0.5, "frictionless interface: no shear traction", transform=ax_s.transAxes,
                  ha="center", va="center", color="0.4", fontsize="small")
    ax_s.set_ylabel("shear traction s (kPa)")
    reach = max(float(np.max(np.abs(shear))), 1.0)
    if model == "coulomb" and friction > 0:
        reach = max(reach, float(np.max(cone)))
    ax_s.set_ylim(-1.1 * reach, 1.9 * reach)  # room for the legend above the curves
    theta_axis(ax_s)
    ax_s.legend(loc="upper center", ncols=2, fontsize="x-small")
    joints = joint_plots.summary(ds)
    ax.set_title(f"Interface tractions ({model}), {_title(ds)}: max λ "
                 f"{float(ds['max_contact_pressure']) / 1e3:.4g} kPa, contact over "
                 f"{float(ds['contact_extent']):.4g}°" + (f"\nsegmental lining: {joints} (vertical lines)"
                                                         if joints else ""), fontsize="medium")
    return fig


def _mid_radius(ds: xr.Dataset) -> float:
    """Mid-surface radius of the lining (m)."""
    geometry = case_spec(ds).get("geometry", {})
    if "inner_radius" in geometry and "thickness" in geometry:
        return geometry["inner_radius"] + 0.5 * geometry["thickness"]
    cy = float(np.mean(ds["interface_y"].values[[0, -1]]))
    return float(np.max(np.hypot(ds["interface_x"].values, ds["interface_y"].values - cy)))


def mid_surface(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray] | None:
    """The lining's mid-surface points (m, 2) relative to the section's centre and their outward
    normals (m, 2), for a section that is not a circle (SPEC §9.4); None for a circle."""
    spec = case_spec(ds)
    geometry = spec.get("geometry", {})
    if geometry.get("section", {"shape": "circle"}).get("shape", "circle") == "circle":
        return None
    from solver.spec import CaseSpec

    g = CaseSpec.model_validate(spec).geometry
    outward = -np.column_stack([ds["normal_x"].values, ds["normal_y"].values])
    hole = np.column_stack([ds["interface_x"].values, ds["interface_y"].values + g.depth])
    return hole - (g.gap + 0.5 * g.thickness) * outward, outward


def _force_diagram(ax, theta_deg: np.ndarray, values: np.ndarray, radius: float, *, symbol: str, unit: str,
                   title: str, outward: str, joints: xr.Dataset | None = None, shape=None) -> None:
    """``values`` drawn as offsets from the half ring, scaled so the largest is 0.35 radius;
    the joints of ``joints`` (a segmental lining's result) as radial ticks. ``shape``: the
    mid-surface and its normals (:func:`mid_surface`) of a section that is not a circle."""
    theta = np.radians(theta_deg)
    nx, ny = np.sin(theta), np.cos(theta)
    peak = float(np.max(np.abs(values))) if values.size else 0.0
    values = np.where(np.abs(values) < 1e-6 * peak, 0.0, values)  # round-off at the symmetry axis
    scale = 0.35 * radius / peak if peak > 0 else 0.0
    ring = np.column_stack([radius * nx, radius * ny])
    if shape is not None:
        ring, (nx, ny) = shape[0], shape[1].T
    ax.plot(ring[:, 0], ring[:, 1], color="0.3", lw=2.0, solid_capstyle="butt")
    for part, color in ((np.maximum(values, 0.0), "tab:blue"), (np.minimum(values, 0.0), "tab:red")):
        curve = ring + (scale * part)[:, None] * np.column_stack([nx, ny])
        ax.fill(np.concatenate([ring[:, 0], curve[::-1, 0]]), np.concatenate([ring[:, 1], curve[::-1, 1]]),
                color=color, alpha=0.3, lw=0)
    curve = ring + (scale * values)[:, None] * np.column_stack([nx, ny])
    ax.plot(curve[:, 0], curve[:, 1], color="k", lw=1.2, gid="forces")
    if joints is not None:
        joint_plots.draw_on_ring(ax, joints, radius)
    ax.axvline(0.0, color="0.6", lw=0.8, ls="-.")
    for name, where in STATIONS.items():
        i = int(np.argmin(np.abs(theta_deg - where)))
        x, y = ring[i] + (max(scale * values[i], 0.0) + 0.06 * radius) * np.array([nx[i], ny[i]])
        align = {"crown": ("left", "bottom"), "springline": ("left", "center"), "invert": ("left", "top")}[name]
        ax.annotate(f"{name}\n{values[i]:.1f} {unit}", (x, y), ha=align[0], va=align[1], fontsize="small",
                    xytext=(3 if name != "springline" else 0, 0), textcoords="offset points")
    k = int(np.argmax(np.abs(values)))
    ax.plot(*curve[k], "o", color="k", ms=4)
    ax.set_title(f"{title}\nlargest |{symbol}| = {abs(values[k]):.1f} {unit} at θ = {theta_deg[k]:.0f}° (dot)\n"
                 f"blue +, red −; {outward}", fontsize="small")
    reach = 1.75 * radius  # the offsets (0.35 radius) and the station labels beyond them
    if peak > 0:  # a scale bar of a round value, as on a drawing
        step = 10.0 ** np.floor(np.log10(peak))
        bar = max(m * step for m in (1, 2, 5) if m * step <= peak)
        y0 = -0.93 * reach
        x0 = 0.9 * radius
        ax.plot([x0, x0 + scale * bar], [y0, y0], color="k", lw=2.5, solid_capstyle="butt", gid="scale")
        ax.annotate(f"scale: {bar:g} {unit}", (x0, y0), xytext=(0, 4), textcoords="offset points",
                    fontsize="small", va="bottom")
    ax.set_xlim(-0.15 * radius, 1.9 * radius)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    ax.set_axis_off()


def plot_lining_forces(ds: xr.Dataset) -> Figure:
    """Thrust, moment and shear drawn around the half ring (the PLAXIS / RS2 picture).

    Each quantity is an offset from the lining's mid-surface, scaled so its largest
    magnitude is 35 % of the radius and filled between ring and curve (blue positive,
    red negative), with its value at crown, springline and invert. A segmental lining's joints
    are radial ticks through the diagrams (closed dashed, open orange; :mod:`workflows.joint_plots`).
    """
    radius = _mid_radius(ds)
    shape = mid_surface(ds)
    if shape is not None:  # the scale and the frame of the section's largest reach
        radius = float(np.max(np.hypot(*shape[0].T)))
    theta = ds["theta"].values
    fig = Figure(figsize=(12, 5.4), layout="constrained")
    axes = fig.subplots(1, 3)
    panels = (("thrust", "N", "thrust N (kN/m), compression +", "kN/m", "+ drawn outward"),
              ("moment", "M", "bending moment M (kN·m/m), + inner fibre compressed", "kN·m/m",
               "drawn on the tension side"),
              ("shear", "V", "shear force V (kN/m)", "kN/m", "+ drawn outward"))
    for ax, (name, symbol, title, unit, outward) in zip(axes, panels):
        _force_diagram(ax, theta, ds[name].values / 1e3, radius, symbol=symbol, unit=unit, title=title,
                       outward=outward, joints=ds, shape=shape)
    joints = joint_plots.summary(ds)
    if joints:
        fig.legend(handles=joint_plots.ring_legend_handles(ds), loc="outside lower center", ncols=2,
                   fontsize="small", title=f"segmental lining: {joints} (ticks across the ring)",
                   title_fontsize="small")
    where = f"mid-surface radius {radius:.3g} m" if shape is None else \
        f"{case_spec(ds)['geometry']['section']['shape']} section, largest mid-surface reach {radius:.3g} m"
    fig.suptitle(f"Lining forces, {_title(ds)} (half ring, symmetry axis dash-dotted; {where})", fontsize="medium")
    return fig


def draw_envelope(ax, ds: xr.Dataset, *, color="k", label: str | None = "design envelope N_Rd–M_Rd",
                  fill: bool = False) -> None:
    """The closed design N–M envelope of ``ds`` (kN/m up, kN·m/m across)."""
    n_env, m_env = ds["capacity_thrust"].values / 1e3, ds["capacity_moment"].values / 1e3
    ax.plot(np.append(m_env, m_env[:1]), np.append(n_env, n_env[:1]), color=color, lw=1.2, label=label)
    if fill:
        ax.fill(m_env, n_env, color=color, alpha=0.06, lw=0)


def _interaction_axes(ax) -> None:
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.axvline(0.0, color="0.5", lw=0.8)
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("design moment M_Ed (kN·m/m), + = inner fibre compressed")
    ax.set_ylabel("design thrust N_Ed (kN/m), compression up")


def plot_interaction(ds: xr.Dataset) -> Figure:
    """The N–M diagram of one case: design envelope and the design actions at every station.

    Stations are (γF·M, N_Ed), N_Ed the governing of γF·N and 1.0·N (SPEC §9.3), coloured by θ; the
    most utilized one is starred with
    the ray from the origin to the envelope that defines its utilization (SPEC §1.3). A
    segmental lining's joints are diamonds between the rays |M| = N·a/2 of their contact strip
    (:func:`workflows.joint_plots.draw_on_interaction`), not stations of the section check.
    """
    gamma = load_factor(ds)
    theta = ds["theta"].values
    # N_Ed of the governing combination (γF N, or 1.0 N where the lower thrust is unfavourable)
    thrust = ds["design_thrust"].values if "design_thrust" in ds else gamma * ds["thrust"].values
    n_ed, m_ed = thrust / 1e3, gamma * ds["moment"].values / 1e3
    fig = Figure(figsize=(7.5, 6.5), layout="constrained")
    ax = fig.add_subplot()
    draw_envelope(ax, ds, fill=True)
    eta = ds["utilization"].values
    checked = ~np.isnan(eta)  # a segmental lining's joints: their strips, not the section
    points = ax.scatter(m_ed[checked], n_ed[checked], c=theta[checked], cmap="viridis", vmin=0, vmax=180, s=12,
                        zorder=3, label=f"stations (γF = {gamma:g} on M; N_Ed = γF N or 1.0 N, the worse)")
    bar = fig.colorbar(points, ax=ax, ticks=np.arange(0, 181, 30))
    bar.set_label("θ of the station (deg from crown)")
    if joint_plots.has_joints(ds):  # the strip's rays a little beyond the joints, within the envelope's height
        top = min(float(np.max(ds["capacity_thrust"].values)) / 1e3,
                  2.0 * gamma * float(np.max(ds["joint_thrust"].values)) / 1e3)
        joint_plots.draw_on_interaction(ax, ds, gamma, top=top)
    spec = case_spec(ds)
    title = f"N–M interaction (EN 1992-1-1), {_title(ds)}"
    failing = eta > 1.0
    if failing.any():
        ax.scatter(m_ed[failing], n_ed[failing], s=40, facecolors="none", edgecolors="tab:red", lw=0.8, zorder=3,
                   label=f"η > 1 ({int(failing.sum())} of {int(checked.sum())} stations)")
    if not np.isnan(eta).all():
        k = int(np.nanargmax(eta))
        worst = float(eta[k])
        ax.plot(m_ed[k], n_ed[k], "*", color="tab:red", ms=14, mec="k", zorder=4,
                label=f"max η at θ = {theta[k]:.0f}° ({station_name(theta[k])}): "
                      f"N_Ed = {n_ed[k]:.0f} kN/m, M_Ed = {m_ed[k]:.0f} kN·m/m")
        if np.isfinite(worst) and worst > 0:
            ax.plot([0, m_ed[k] / worst], [0, n_ed[k] / worst], color="tab:red", lw=0.8, ls="--",
                    label="ray O→S→E: η = |OS| / |OE| (E on the envelope)")
        if np.isinf(worst):
            title += "\nmax utilization η = inf: fails at any load level (tension, or |M|/N ≥ h/2 in plain concrete)"
        else:
            title += f"\nmax utilization η = {worst:.3g} ({'passes' if worst <= 1 else 'fails'})"
    check = joint_check(ds)
    if check is not None:
        inside = check.worst <= 1 + 1e-6
        title += (f" away from the joints\njoints: |M|/(N·a/2) ≤ {check.worst:.3g} (the thrust "
                  f"{'within' if inside else 'outside'} the strip), strip η ≤ {check.utilization:.3g} "
                  f"({'passes' if check.passes else 'fails'}), {check.open} of {check.count} open")
    design = spec.get("design", {})
    geometry = spec.get("geometry", {})
    if design:
        area = design.get("reinforcement_area", 0.0)
        section = (f"h = {geometry.get('thickness', float('nan')):g} m, fck = {design['concrete_strength'] / 1e6:g} MPa, "
                   + (f"As = {area * 1e4:g} cm²/m per face, fyk = {design['steel_strength'] / 1e6:g} MPa"
                      if area > 0 else "plain concrete (§12)"))
        ax.text(0.02, 0.02, section, transform=ax.transAxes, va="bottom", fontsize="x-small",
                bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    _interaction_axes(ax)
    ax.legend(loc="upper right", fontsize="x-small", framealpha=0.9)
    ax.set_title(title, fontsize="medium")
    return fig


def plot_surface_settlement(ds: xr.Dataset) -> Figure:
    """Settlement trough of the ground surface (mm, downward), mirrored about the tunnel axis:
    first the Gaussian trough of practice holding the ground loss (what to assess settlement
    on), then the FE surface, labelled for what it is (its far field depends on the model's size)."""
    x, s = ds["surface_x"].values, ds["surface_settlement"].values * 1e3
    fig = Figure(figsize=(7.5, 4.3), layout="constrained")
    ax = fig.add_subplot()
    xx = np.concatenate([-x[::-1], x])
    if "gaussian_settlement" in ds:
        gs = ds["gaussian_settlement"].values * 1e3
        K = ds["gaussian_settlement"].attrs.get("trough_width_factor", float("nan"))
        ax.plot(xx, np.concatenate([gs[::-1], gs]), color="tab:red", lw=2.0,
                label=f"Gaussian trough from the ground loss (K = {K:g})")
        ax.fill_between(xx, np.concatenate([gs[::-1], gs]), color="tab:red", alpha=0.10)
    if "design_settlement" in ds and not np.allclose(ds["design_settlement"].values, ds["gaussian_settlement"].values):
        design = ds["design_settlement"].values * 1e3
        volume = float(ds["design_volume_loss"]) if "design_volume_loss" in ds else float("nan")
        factor = json.loads(ds.attrs.get("case_spec", "{}")).get("settlement", {}).get("trough_width_factor",
                                                                                        float("nan"))
        ax.plot(xx, np.concatenate([design[::-1], design]), color="tab:blue", lw=1.6, ls="--",
                label=f"design trough (V_L = {100 * volume:.3g} %, K = {factor:g})")
    ax.plot(x, s, color="k", lw=1.2, marker="o", ms=2, label="FE surface (depends on the model's size)")
    ax.plot(-x, s, color="k", lw=0.8, ls="--")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.axvline(0.0, color="0.6", lw=0.8, ls="-.")
    ax.invert_yaxis()
    ax.set_xlabel("x, distance from the tunnel axis (m)")
    ax.set_ylabel("surface settlement (mm, downward)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize="small")
    since = "since excavation" if ds.attrs.get("excavation_method", "deconfinement") != "wished-in-place" \
        else "since the stress-free start"
    lead = ""
    if "ground_loss" in ds:
        lead = (f"ground loss {100 * float(ds['ground_loss']):.3g} %, trough max "
                f"{1e3 * float(ds['gaussian_max_settlement']):.3g} mm; ")
    fe = f"FE surface at the axis {s[0]:.3g} mm"
    if "max_surface_heave" in ds and float(ds["max_surface_heave"]) > 0:
        fe += f", heave up to {1e3 * float(ds['max_surface_heave']):.3g} mm"
    ax.set_title(f"Surface settlement ({since}), {_title(ds)}\n{lead}{fe}", fontsize="medium")
    return fig


def _ground_lines(ax, ds: xr.Dataset) -> None:
    """The lines between layers (brown, dash-dotted) and the water table (blue, dashed) on
    undeformed axes, where the case has them."""
    spec = case_spec(ds)
    depth = 0.0
    for i, layer in enumerate(spec.get("ground", {}).get("layers", [])[:-1]):
        depth += float(layer.get("thickness", 0.0))
        ax.axhline(-depth, color="tab:brown", lw=1.0, ls="-.", label="layer line" if i == 0 else None)
    table = (spec.get("water") or {}).get("table")
    if table is None:
        return
    drawdown = float(ds["phreatic_drawdown"]) if "phreatic_drawdown" in ds else 0.0
    if "phreatic_depth" in ds and np.isfinite(drawdown) and drawdown != 0.0:
        # a drained lining draws the table down: the computed phreatic surface, the undisturbed table thin
        ax.axhline(-float(table), color=_WATER_COLOR, lw=0.8, ls=":", label=f"undisturbed table ({table:g} m)")
        ax.plot(ds["surface_x"].values, -ds["phreatic_depth"].values, color=_WATER_COLOR, lw=1.2, ls="--",
                label=f"phreatic surface (drawdown {drawdown:.3g} m above the axis)")
    else:
        ax.axhline(-float(table), color=_WATER_COLOR, lw=1.2, ls="--", label=f"water table ({table:g} m)")


def ground_reaction(ds: xr.Dataset) -> dict:
    """The convergence–confinement reading of a case (SI units): ``p0`` the mean in-situ total
    stress at the axis; the FE ground reaction curve over stage 1 (``convergence``, ``pressure``:
    (1 − released)·p0, from (0, p0)); the lining's characteristic line (``k_s`` of the thick
    ring, from ``u_in``, the convergence when it is placed, plus the gap); the FE end state
    (``u_end``: mean wall convergence, ``p_end``: mean pressure on the extrados, water
    included); the closed-form curve under isotropic p0 (``closed_u``, ``closed_p``: Salençon's,
    Kirsch's for elastic ground) for a circle in one homogeneous layer, None otherwise; and, for a case whose λd
    was found from its face distance, ``installation`` (the attribute of SPEC §9.5) with the
    curve on to full release (``full_u``, ``full_p``), None otherwise."""
    from solver.analytic import interface_mean
    from solver.spec import CaseSpec
    from solver.ground.strata import geostatic_state, strata

    spec = CaseSpec.model_validate(case_spec(ds))
    layers = strata(spec)
    state = geostatic_state(spec, layers, np.array([spec.geometry.depth]))
    p0 = float(0.5 * (state["sigma_v"][0] + state["sigma_h"][0]))
    curve = json.loads(ds.attrs.get("ground_reaction_curve", "[]"))
    convergence = np.array([0.0] + [c["wall_convergence_m"] for c in curve])
    pressure = p0 * np.array([1.0] + [1.0 - c["released"] for c in curve])
    gn = ds["ground_node"].values
    inward = ds["displacement_x"].values[gn] * ds["normal_x"].values + ds["displacement_y"].values[gn] * ds["normal_y"].values
    support = ds["contact_pressure"].values + (ds["water_pressure"].values if "water_pressure" in ds else 0.0)
    g, lining = spec.geometry, spec.lining
    b, a = g.outer_radius, g.inner_radius
    k_s = lining.young * (b**2 - a**2) / ((1 + lining.poisson) * b * ((1 - 2 * lining.poisson) * b**2 + a**2))
    out = {"p0": p0, "convergence": convergence, "pressure": pressure, "k_s": k_s,
           "u_in": float(convergence[-1]) + g.gap, "u_end": interface_mean(ds, inward),
           "p_end": interface_mean(ds, support), "closed_u": None, "closed_p": None, "installation": None}
    if "installation" in ds.attrs:
        found = json.loads(ds.attrs["installation"])
        full = found["full_release_curve"] or [  # elastic ground: the straight line on to full release
            {"released": 1.0, "wall_convergence_m": float(convergence[-1]) / max(found["deconfinement"], 1e-12)}]
        out["installation"] = found
        out["full_u"] = np.array([0.0] + [c["wall_convergence_m"] for c in full])
        out["full_p"] = p0 * np.array([1.0] + [1.0 - c["released"] for c in full])
    if len(layers) == 1 and not layers[0].young_gradient and g.circle:  # a homogeneous ground has a closed form
        closed_p = np.linspace(p0, 0.0, 60)
        closed_u = closed_form_wall(layers[0], p0, closed_p, g.hole_radius)
        out["closed_u"], out["closed_p"] = np.asarray(closed_u), closed_p
    return out


def closed_form_wall(ground, p0: float, pressures: np.ndarray, radius: float) -> list[float]:
    """The wall's convergence (m) of a circular hole of ``radius`` in homogeneous ``ground`` (a
    :class:`solver.ground.strata.Stratum`) under isotropic ``p0`` at support ``pressures`` (Pa):
    Salençon's (Mohr–Coulomb), the Hoek–Brown hole's, Kirsch's (elastic)."""
    from solver.analytic import salencon

    if ground.model == "mohr-coulomb":
        return [salencon(p0, ground.cohesion, ground.friction_angle, ground.dilatancy, ground.young,
                         ground.poisson, radius, p, n=801)["u_wall"] for p in pressures]
    if ground.model == "hoek-brown":
        from solver.ground.hoek_brown_hole import hoek_brown_hole

        return [hoek_brown_hole(p0, ground.ucs, ground.gsi, ground.mi, ground.disturbance, ground.dilatancy,
                                ground.young, ground.poisson, radius, p)["u_wall"] for p in pressures]
    return list((p0 - np.asarray(pressures)) * radius * (1 + ground.poisson) / ground.young)


def case_hole_radius(ds: xr.Dataset) -> float:
    """The excavation radius of a case (m): lining outer radius plus the gap."""
    from solver.spec import CaseSpec

    return CaseSpec.model_validate(case_spec(ds)).geometry.hole_radius


def plot_ground_reaction(ds: xr.Dataset) -> Figure:
    """The convergence–confinement diagram of a case: the ground reaction curve (wall
    convergence against fictitious support pressure) the FE followed over stage 1, Salençon's
    closed-form curve for reference (isotropic p0, one homogeneous layer), the lining's
    characteristic line from the convergence at which it is placed, and the FE end state."""
    grc = ground_reaction(ds)
    fig = Figure(figsize=(8.0, 5.0), layout="constrained")
    ax = fig.add_subplot()
    mm, kpa = 1e3, 1e-3
    if grc["closed_u"] is not None:
        ax.plot(grc["closed_u"] * mm, grc["closed_p"] * kpa, color="0.45", ls="--", lw=1.2,
                label="ground reaction, closed form (isotropic p0)")
    found = grc["installation"]
    if found is not None:
        ax.plot(grc["full_u"] * mm, grc["full_p"] * kpa, color="tab:blue", lw=1.0, ls=":",
                label="ground reaction on to full release (u_max, the profile's scale)")
    ax.plot(grc["convergence"] * mm, grc["pressure"] * kpa, color="tab:blue", lw=2.0, marker="o", ms=3,
            label="ground reaction, FE stage 1 (unsupported ground)")
    where = (f"lining installed {found['face_distance_m']:g} m behind the face ({found['ldp']}: "
             f"u* = {found['ldp_ratio']:.3g})" if found is not None else "lining installed")
    ax.plot([grc["convergence"][-1] * mm], [grc["pressure"][-1] * kpa], marker="D", ms=8, color="tab:orange",
            ls="none", label=f"{where}: {grc['convergence'][-1] * mm:.3g} mm")
    u_end = max(grc["u_end"], grc["u_in"])
    line_u = np.array([grc["u_in"], u_end + 1.3 * (u_end - grc["u_in"]) + 1e-9])
    ax.plot(line_u * mm, grc["k_s"] * (line_u - grc["u_in"]) * kpa, color="tab:green", lw=1.8,
            label=f"lining characteristic line (k_s = {grc['k_s'] * 1e-6:.3g} MPa/m)")
    ax.plot([grc["u_end"] * mm], [grc["p_end"] * kpa], marker="*", ms=14, color="tab:red", ls="none",
            label=f"FE end state: {grc['p_end'] * kpa:.3g} kPa at {grc['u_end'] * mm:.3g} mm")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlim(left=0.0)
    ax.set_ylim(bottom=min(0.0, grc["p_end"] * kpa) - 0.02 * grc["p0"] * kpa, top=1.05 * grc["p0"] * kpa)
    ax.set_xlabel("wall convergence, mean over the ring (mm, inward)")
    ax.set_ylabel("support pressure on the wall (kPa)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    released = 1.0 - grc["pressure"][-1] / grc["p0"] if grc["p0"] else 0.0
    extent = ""
    if "max_plastic_extent" in ds:
        reach = float(ds["max_plastic_extent"])
        extent = (f"\nyielded ground to {reach:.3g} m from the axis (wall at {case_hole_radius(ds):.3g} m)"
                  if reach > 0 else "\nno ground yielded")
    ax.set_title(f"Ground reaction and lining, {_title(ds)}\np0 = {grc['p0'] * kpa:.4g} kPa (mean in-situ stress at "
                 f"the axis), lining placed at {100 * released:.3g} % released{extent}", fontsize="medium")
    return fig
