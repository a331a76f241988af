# SPDX-License-Identifier: Apache-2.0
"""Yarn geometry for the Neural Yarn add-on: importers, generators and spline evaluation.

Pure Python + numpy (no bpy), relative imports only, so this package runs as `neural_yarn.geometry` inside
Blender and as a plain package under pytest. Every function returns `YarnCurve`s (Z-up polylines with a
radius per vertex) and raises `GeometryError` for any bad input.
"""
from .bcc import BCCData, bcc_bytes, read_bcc, read_bcc_control_points, to_z_up, write_bcc
from .curves import (
    CURVE_TYPES,
    GeometryError,
    YarnCurve,
    bezier,
    bounding_box,
    bspline,
    catmull_rom,
    control_point_problem,
    evaluate_spline,
    evaluate_splines,
    median_control_point_spacing,
    yarn_radius_from_passes,
    polyline,
    polyline_length,
    resample,
    spline_curve,
    validate,
)
from .knit import crane_course, knit_pattern, plain_knit
from .leaf import estimate_period, read_leaf, read_leaf_sidecar, read_leaf_text, tile_pattern, weld_endpoints
from .ply import (
    explicit_fiber_warning,
    neighbour_ply_distance,
    parallel_transport_frames,
    ply_center_distance,
    twist_plies,
)
from .weave import weave_clearance, weave_pattern, woven_fabric

__all__ = [
    "BCCData",
    "CURVE_TYPES",
    "GeometryError",
    "YarnCurve",
    "bcc_bytes",
    "bezier",
    "bounding_box",
    "bspline",
    "catmull_rom",
    "control_point_problem",
    "crane_course",
    "estimate_period",
    "evaluate_spline",
    "evaluate_splines",
    "explicit_fiber_warning",
    "median_control_point_spacing",
    "yarn_radius_from_passes",
    "neighbour_ply_distance",
    "parallel_transport_frames",
    "knit_pattern",
    "plain_knit",
    "ply_center_distance",
    "polyline",
    "polyline_length",
    "read_bcc",
    "read_bcc_control_points",
    "read_leaf",
    "read_leaf_sidecar",
    "read_leaf_text",
    "resample",
    "spline_curve",
    "tile_pattern",
    "to_z_up",
    "twist_plies",
    "validate",
    "weave_clearance",
    "weave_pattern",
    "weld_endpoints",
    "woven_fabric",
    "write_bcc",
]
