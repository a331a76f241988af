// SPDX-License-Identifier: Apache-2.0
//
// The close-up's image predicted without a renderer (issue 17: the tabulated method and the split of the
// error into aggregation and fitting). In the close-up (scenes/ply_scene.h) the camera sees one straight,
// convex ply under a uniform environment or distant lights and a black background. Light that leaves the
// ply never returns to it, so the expected value of a pixel is one integral of the ply's far-field
// scattering function S |cos theta_o| at the camera ray's hit: for a distant light of irradiance E over a
// disc of directions, E times its mean over the disc; for the white environment, the albedo. No
// Monte Carlo, no bounces, no shadow rays.
//
// The same integral takes either of two functions:
//   - a model: what the native closure renders, so a render that differs from it (beyond its noise) is a
//     bug in the renderer's integration, not in the model;
//   - the radiance distribution maps themselves (nearest bin, R + M; T straight through): the best any
//     far-field model of this ply can do — the maps are the explicit fibers' own scattering, binned, and
//     for this scene the far-field assumption is exact (a distant light reaches every exit point), so
//     their prediction differs from the explicit-fiber render only by the bins' width and the maps' noise.
// The model's error against explicit fibers then splits into fitting (model against maps) and
// aggregation (maps against explicit fibers).
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "neuralyarn/kernel/frames.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/scenes/ply_scene.h"

namespace neuralyarn::scenes {

/* A far-field scattering function in the yarn frame (x = ply axis, z = the bounding cylinder's normal),
 * both directions away from the surface: S |cos theta_o| for light between w_i and w_o (w_i = toward the
 * camera), and the albedo at w_i (the white environment's pixel value). */
struct FarField {
  std::function<Rgb3(const ny::Vec3 &wi, const ny::Vec3 &wo)> eval;
  std::function<Rgb3(const ny::Vec3 &wi)> albedo;
};

/* Which of the non-delta lobes a far field holds: both (what renders), or one of them, to tell which lobe
 * a fitting error is in. A single lobe has no albedo (the environment's pixel): its `albedo` throws. */
enum class Lobes { kRM, kR, kM };
/* "RM", "R", "M"; throws std::runtime_error for anything else. */
Lobes parse_lobes(const std::string &name);

/* The model as the native closure renders it: R + M (with calibration and R azimuth); T is the
 * transparent closure (a delta that the rigs' lights never lie on, and 1 x the white background). */
FarField model_far_field(const model::YarnModel &model, Lobes lobes = Lobes::kRM);

/* How a direction pair reads the maps: the bin it falls in, or the bins' values interpolated linearly in each
 * angle between their centres (theta_i, phi_i, theta_o, phi_o: 16 bins; phi wraps, theta holds its first and last
 * centre's value beyond them), which removes the bins' steps from a predicted image (the maps' own noise stays). */
enum class MapLookup { kNearest, kInterpolated };

/* The maps: R + M at (w_i, w_o); the albedo is the exit energy (T + R + M) at w_i. The maps must outlive the
 * returned functions. */
FarField maps_far_field(const rdm::RdmMaps &maps, Lobes lobes = Lobes::kRM, MapLookup lookup = MapLookup::kNearest);

/* The model's stock-Blender fallback (its "fallback" tables, model/fallback.h) as Blender renders it:
 * transparent() and the weighted built-in lobes. Throws std::runtime_error when the model has none. */
FarField fallback_far_field(const model::YarnModel &model);

/* A pixel rectangle [x, x + w) x [y, y + h) of a width x height render of the close-up. */
struct PixelRegion {
  int width = 0, height = 0, x = 0, y = 0, w = 0, h = 0;
};

/* The camera: on the -z side of the curve's axis at `distance` curve radii, looking along +z, `fov` across
 * the image's shorter side. The close-up's by default; a scene of one straight curve along x seen so (the yarn
 * level's straight yarn, decisions D53) is the same picture at its own distance over radius. */
struct CloseupCamera {
  double distance = kCloseupCameraDistance, fov = kCloseupCameraFov;
};

/* The expected mean colour over the region of the close-up under `rig` (its environment or distant
 * lights; throws std::runtime_error for sphere lights, whose near-field position and size this does not
 * model), with the pixels filtered as the scenes state it (a box one pixel wide, decisions D36). */
/* The rig's distant lights as directions toward the light, 6 x 6 uniform in solid angle over each light's disc, each
 * with its share of the light's irradiance (the prediction's quadrature); throws std::runtime_error for sphere lights. */
std::vector<std::pair<Eigen::Vector3d, double>> distant_light_directions(const LightRig &rig);
Rgb3 predict_closeup(const FarField &f, const LightRig &rig, const PixelRegion &region,
                     const CloseupCamera &camera = {});

/* The whole width x height image, pixel by pixel (row 0 the top, as Cycles writes it): each pixel's
 * predict_closeup over itself. What a tabulated closure would render without noise when `f` holds the maps,
 * so that an image metric (FLIP) splits too; the rows in parallel. */
std::vector<Rgb3> predict_closeup_image(const FarField &f, const LightRig &rig, int width, int height,
                                        const CloseupCamera &camera = {});

/* The close-up's central region, as the evaluation harness measures it (scripts/evaluate.py central_region, the
 * issue-17 goals' region): the middle half of the width; the rows whose pixel-centre rays (x = 0) hit the
 * curve's bounding cylinder, less one row at each silhouette, where the pixel filter mixes curve and background.
 * Throws std::runtime_error when that leaves fewer than one row. */
PixelRegion central_region(int width, int height, const CloseupCamera &camera = {});

/* The regions an image fit compares: the whole frame (D53), or the frame and the central region (D54). */
enum class ImageFitRegions { kFrame, kFrameAndCentre };

/* The image fit (docs/decisions.md D53, D54): the close-up (160 x 80) under each distant-light rig, front,
 * grazing, back and axis, predicted with a far field over the whole frame (then, with kFrameAndCentre, over the
 * central region, the rigs in the same order), the rigs in parallel; and a model's error against the maps'
 * predictions, the mean over the predictions and channels of |model / maps - 1| (a channel the maps leave black
 * counts 0). It ranks M trainings as independent maps do, where the 4D L1 does not. */
std::vector<Rgb3> predict_distant_rigs(const FarField &f, ImageFitRegions regions = ImageFitRegions::kFrame);
double image_fit_error(const std::vector<Rgb3> &model, const std::vector<Rgb3> &maps);

}  // namespace neuralyarn::scenes
