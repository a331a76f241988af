// SPDX-License-Identifier: Apache-2.0
//
// A ply's fibers along a curved centreline (a knitted or woven ply): the straight ply's helices (ply.h)
// laid out in the centreline's rotation-minimising frame, so that the twist w = pi alpha / R is relative to
// the ply itself — a bent ply adds no twist of its own (as yarn.h's torsion term for helical plies).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "neuralyarn/geometry/ply.h"

namespace neuralyarn::geometry {

/* The curve Cycles renders through the keys of one curve: the uniform Catmull-Rom spline through them, the first
 * and the last key repeated (Embree's round Catmull-Rom curves, as Cycles hands them over), as a polyline of
 * `per_span` segments per span between two keys. Two keys give the straight segment. */
std::vector<Eigen::Vector3d> catmull_rom_polyline(const std::vector<Eigen::Vector3d> &keys, int per_span = 16);

/* Arc length of that curve (of catmull_rom_polyline at its default resolution). */
double centreline_length(const std::vector<Eigen::Vector3d> &keys);

/* The fibers of `ply` along `centreline` — the curve a renderer draws through its keys (catmull_rom_polyline:
 * the explicit fibers follow the very ply curve the aggregated model is rendered on; at least two keys, not
 * all the same), resampled evenly in arc length with max(turns * segments_per_turn, length / R, keys - 1)
 * segments. The frame starts with the normal closest to +y (+z where the tangent is near y) and is carried
 * by double reflection (Wang et al. 2008); a fiber at cross-section centre (y, z) sits at
 *     C(s) + (y cos ws - z sin ws) N(s) + (y sin ws + z cos ws) B(s),  B = T x N,
 * so a straight centreline along +x from the origin gives export_fibers(ply, 0, length). Throws
 * ParameterError for a degenerate or non-finite centreline. */
CurveSet sweep_fibers(const Ply &ply, const std::vector<Eigen::Vector3d> &centreline, int segments_per_turn = 32);

/* The segments sweep_fibers gives each fiber of a ply with these parameters along a centreline of `length`
 * and `points` points (so a scene can count its keys, N (segments + 1) a ply, before sweeping). */
int64_t sweep_segments(const PlyParams &params, double length, size_t points, int segments_per_turn);

}  // namespace neuralyarn::geometry
