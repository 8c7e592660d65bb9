"""The catalogue of a result's names (SPEC §3, §9): every scalar and per-joint variable with its
units and long name, as :func:`solver.results.dataset.to_dataset` stores them and every table,
page and plot reads them."""
from __future__ import annotations

SCALARS = {
    "max_contact_pressure": ("Pa", "maximum contact pressure"),
    "contact_extent": ("degree", "angular extent of the interface in contact"),
    "crown_settlement": ("m", "settlement of the lining crown (downward positive)"),
    "max_thrust": ("N m-1", "maximum lining thrust (compression positive)"),
    "max_abs_moment": ("N m m-1", "maximum absolute lining bending moment"),
    "lining_weight": ("N m-1", "weight of the (half) lining per metre of tunnel"),
    "bolt_theta": ("degree", "position of the accepted bolt point"),
    "bolt_trials": ("1", "number of bolt points tried"),
    "iterations": ("1", "inner solver iterations over all bolt trials"),
    "converged": ("1", "1 if the contact solve converged to an admissible solution"),
    "kkt_residual": ("1", "relative residual of the discrete KKT conditions"),
    "solve_seconds": ("s", "wall-clock seconds from case to dataset (building a shared model not included)"),
    "max_utilization": ("1", "largest EN 1992 utilization of the lining section (<= 1 passes)"),
    "max_shear_utilization": ("1", "largest EN 1992-1-1 shear utilization |V_Ed| / V_Rd,c of the lining section "
                                   "(6.2.2 reinforced, 12.6.3 plain; <= 1 passes)"),
    "max_crack_width": ("m", "largest characteristic crack width w_k of the lining section (EN 1992-1-1 7.3.4; "
                             "inf where a plain section cracks)"),
    "max_surface_settlement": ("m", "largest settlement of the ground surface since excavation"),
    "volume_loss": ("1", "settlement trough area over excavated area (the trough: where the surface settles)"),
    "ground_crown_settlement": ("m", "settlement of the ground at the tunnel crown since excavation"),
    "ground_loss": ("1", "area lost at the excavation boundary over the excavated area (since excavation)"),
    "gaussian_max_settlement": ("m", "largest settlement of the Gaussian trough holding the ground loss"),
    "design_volume_loss": ("1", "volume loss of the design trough (settlement.volume_loss, else the ground loss)"),
    "design_max_settlement": ("m", "largest settlement of the design trough (settlement.volume_loss, "
                                   "settlement.trough_width_factor)"),
    "max_slope": ("1", "largest slope |dS/dx| of the design trough (at x = i)"),
    "max_horizontal_strain": ("1", "largest horizontal tensile strain of the design trough (O'Reilly and New: "
                                   "horizontal displacement x S(x) / z0)"),
    "axis_settlement": ("m", "FE ground surface settlement above the tunnel axis (downward positive)"),
    "max_surface_heave": ("m", "largest upward displacement of the FE ground surface (>= 0)"),
    "plastic_area": ("m2", "area of yielded ground around the whole tunnel"),
    "max_plastic_extent": ("m", "largest distance of a yielded face from the tunnel axis (0 if none)"),
    "stage1_plastic_area": ("m2", "area of ground at yield at the end of stage 1, before the lining was placed"),
    "stage1_max_plastic_extent": ("m", "largest distance from the tunnel axis of a face at yield at the end of "
                                  "stage 1 (0 if none)"),
    "water_inflow": ("m3 s-1", "steady water inflow into the whole tunnel per metre (0 unless the lining drains)"),
    "phreatic_drawdown": ("m", "lowering of the water table above the tunnel axis (0 unless the lining drains; "
                               "0 in dry ground)"),
    "max_joint_opening": ("m", "largest opening of the segmental lining's joints (0 for a monolithic lining)"),
    "max_joint_rotation": ("rad", "largest absolute rotation across a joint (0 for a monolithic lining)"),
    "max_joint_eccentricity": ("1", "largest |M|/(N a/2) at a joint: <= 1 when every joint carries its thrust "
                               "within its contact strip of height a (0 for a monolithic lining)"),
    "deconfinement": ("1", "share of the excavation load released before the lining is placed (lambda_d: given, "
                           "or found from the face distance; 0 for 'wished-in-place')"),
    "ldp_ratio": ("1", "u*: the wall convergence at the lining's installation over that far behind the face, of "
                       "the longitudinal displacement profile (0 unless excavation.face_distance is given)"),
    "max_joint_utilization": ("1", "largest EN 1992-1-1 (12.10) utilization of a joint's contact strip at its "
                              "thrust (<= 1 passes; 0 for a monolithic lining)"),
}

#: Per-joint results on dim ``joint`` (SPEC §3): name -> (units, long name); ``joint_theta`` is
#: the dim's coordinate, ``joint_open`` a 0/1 flag.
JOINT_VARIABLES = {
    "joint_thrust": ("N m-1", "thrust across the joint's contact strip (compression positive)"),
    "joint_moment": ("N m m-1", "moment of the joint's contact force about the lining's mid-surface "
                                "(positive: inner fibre in compression)"),
    "joint_opening": ("m", "largest normal gap across the joint's contact strip"),
    "joint_rotation": ("rad", "relative rotation of the joint's faces (positive: opening at the extrados)"),
    "joint_open": ("1", "1 where the joint has opened (a gap over part of its contact strip)"),
    "joint_eccentricity": ("1", "|M|/(N a/2): eccentricity of the joint's thrust over the strip's half height "
                                "(<= 1: within the contact strip)"),
    "joint_utilization": ("1", "EN 1992-1-1 (12.10) utilization of the joint's contact strip as a plain section at "
                               "the joint's design thrust: |M_Ed| / (N_Ed (a - x) / 2), x = N_Ed / (eta fcd,pl b) "
                               "(<= 1 passes)"),
}
#: ``joint_eccentricity`` up to this is "within the strip" (round-off of a thrust at the strip's edge).
ECCENTRICITY_LIMIT = 1.0 + 1e-6
#: Long name of ``utilization`` in a segmental lining.
JOINT_UTILIZATION = ("EN 1992-1-1 utilization of the lining section (<= 1 passes; NaN at the joints' stations, "
                     "where the section is the joint's contact strip: see joint_utilization)")


