// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/scenes/closeup_prediction.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/units.h"

namespace neuralyarn::scenes {

namespace {

Rgb3 to_rgb3(const ny::Rgb &c) { return {c.r, c.g, c.b}; }

/* Sub-pixel offsets of the scenes' pixel filter, a box kPixelFilterWidth wide (ply_scene.h): a midpoint rule
 * of n points, each of weight 1 / n. */
std::vector<double> box_offsets(int n)
{
  std::vector<double> offset;
  for (int k = 0; k < n; k++) {
    offset.push_back(kPixelFilterWidth * ((k + 0.5) / n - 0.5));
  }
  return offset;
}

/* Directions uniform in solid angle over a disc of angular diameter `deg` about the unit vector `z`
 * (Cycles' distant light): n x n strata in (cos theta, phi). */
std::vector<Eigen::Vector3d> disc_directions(const Eigen::Vector3d &z, double deg, int n)
{
  const Eigen::Vector3d u = z.unitOrthogonal(), v = z.cross(u);
  const double cos_max = std::cos(0.5 * deg * kDeg);
  std::vector<Eigen::Vector3d> out;
  for (int a = 0; a < n; a++) {
    for (int b = 0; b < n; b++) {
      const double c = 1.0 - (1.0 - cos_max) * (a + 0.5) / n, s = std::sqrt(std::max(0.0, 1.0 - c * c));
      const double phi = 2.0 * kPi * (b + 0.5) / n;
      out.push_back(c * z + s * std::cos(phi) * u + s * std::sin(phi) * v);
    }
  }
  return out;
}
}  // namespace

Lobes parse_lobes(const std::string &name)
{
  if (name == "RM") {
    return Lobes::kRM;
  }
  if (name == "R") {
    return Lobes::kR;
  }
  if (name == "M") {
    return Lobes::kM;
  }
  throw std::runtime_error("unknown lobes '" + name + "': RM, R or M");
}

namespace {

[[noreturn]] void single_lobe_albedo()
{
  throw std::runtime_error("one lobe alone has no albedo: predict the environment with both lobes (RM)");
}

}  // namespace

FarField model_far_field(const model::YarnModel &model, Lobes lobes)
{
  auto flat = std::make_shared<std::vector<float>>(model.kernel_flat());
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat->data());
  FarField f;
  f.eval = [flat, p, lobes](const ny::Vec3 &wi, const ny::Vec3 &wo) {
    const ny::YarnLobes l = ny::yarn_lobes(p, wi);
    if (!l.valid) {
      return Rgb3{0.0, 0.0, 0.0};
    }
    switch (lobes) {
      case Lobes::kR:
        return to_rgb3(ny::yarn_eval_R(p, l, wo));
      case Lobes::kM:
        return to_rgb3(ny::yarn_eval_M(p, l, wo));
      case Lobes::kRM:
        break;
    }
    return to_rgb3(ny::yarn_eval_lobes(p, l, wo));
  };
  f.albedo = [flat, p, lobes](const ny::Vec3 &wi) {
    if (lobes != Lobes::kRM) {
      single_lobe_albedo();
    }
    return to_rgb3(model::white_furnace(p, wi));
  };
  return f;
}

namespace {

/* theta and phi of a unit vector in the maps' frame, as rdm::incident_bin and outgoing_bin read them. */
double angle_theta(const ny::Vec3 &w) { return std::acos(std::clamp(double(w.z), -1.0, 1.0)); }
double angle_phi(const ny::Vec3 &w) { return std::atan2(double(w.y), double(w.x)); }

FarField interpolated_maps_far_field(const rdm::RdmMaps &maps, double r_on, double m_on, Lobes lobes)
{
  const rdm::MapResolution &b = maps.bins;
  FarField f;
  f.eval = [&maps, &b, r_on, m_on](const ny::Vec3 &wi, const ny::Vec3 &wo) {
    const rdm::BinTaps ti = rdm::bin_taps(angle_theta(wi), 0.0, 0.5 * kPi, b.theta_i, false),
                       pi = rdm::bin_taps(angle_phi(wi), -kPi, kPi, b.phi_i, true),
                       to = rdm::bin_taps(angle_theta(wo), 0.0, kPi, b.theta_o, false),
                       po = rdm::bin_taps(angle_phi(wo), -kPi, kPi, b.phi_o, true);
    Rgb3 sum;
    for (int a = 0; a < 2; a++) {
      for (int c = 0; c < 2; c++) {
        for (int d = 0; d < 2; d++) {
          for (int e = 0; e < 2; e++) {
            const double w = ti.weight[a] * pi.weight[c] * to.weight[d] * po.weight[e];
            const size_t k = maps.map_index(ti.bin[a], pi.bin[c], to.bin[d], po.bin[e]);
            sum.r += w * (r_on * maps.r[k] + m_on * maps.m[k]);
            sum.g += w * (r_on * maps.r[k + 1] + m_on * maps.m[k + 1]);
            sum.b += w * (r_on * maps.r[k + 2] + m_on * maps.m[k + 2]);
          }
        }
      }
    }
    return sum;
  };
  f.albedo = [&maps, &b, lobes](const ny::Vec3 &wi) {
    if (lobes != Lobes::kRM) {
      single_lobe_albedo();
    }
    const rdm::BinTaps ti = rdm::bin_taps(angle_theta(wi), 0.0, 0.5 * kPi, b.theta_i, false),
                       pi = rdm::bin_taps(angle_phi(wi), -kPi, kPi, b.phi_i, true);
    Rgb3 sum;
    for (int a = 0; a < 2; a++) {
      for (int c = 0; c < 2; c++) {
        const double w = ti.weight[a] * pi.weight[c];
        const size_t k = maps.incident_index(ti.bin[a], pi.bin[c]) * 3;
        sum.r += w * maps.exit_energy[k], sum.g += w * maps.exit_energy[k + 1], sum.b += w * maps.exit_energy[k + 2];
      }
    }
    return sum;
  };
  return f;
}

}  // namespace

FarField maps_far_field(const rdm::RdmMaps &maps, Lobes lobes, MapLookup lookup)
{
  const double r_on = lobes == Lobes::kM ? 0.0 : 1.0, m_on = lobes == Lobes::kR ? 0.0 : 1.0;
  if (lookup == MapLookup::kInterpolated) {
    return interpolated_maps_far_field(maps, r_on, m_on, lobes);
  }
  FarField f;
  f.eval = [&maps, r_on, m_on](const ny::Vec3 &wi, const ny::Vec3 &wo) {
    int ti, pi, to, po;
    rdm::incident_bin(maps.bins, wi.x, wi.y, wi.z, &ti, &pi);
    rdm::outgoing_bin(maps.bins, wo.x, wo.y, wo.z, &to, &po);
    const size_t k = maps.map_index(ti, pi, to, po);
    return Rgb3{r_on * maps.r[k] + m_on * maps.m[k], r_on * maps.r[k + 1] + m_on * maps.m[k + 1],
                r_on * maps.r[k + 2] + m_on * maps.m[k + 2]};
  };
  f.albedo = [&maps, lobes](const ny::Vec3 &wi) {
    if (lobes != Lobes::kRM) {
      single_lobe_albedo();
    }
    int ti, pi;
    rdm::incident_bin(maps.bins, wi.x, wi.y, wi.z, &ti, &pi);
    const size_t k = maps.incident_index(ti, pi) * 3;
    return Rgb3{maps.exit_energy[k], maps.exit_energy[k + 1], maps.exit_energy[k + 2]};
  };
  return f;
}

FarField fallback_far_field(const model::YarnModel &model)
{
  if (!model.fallback) {
    throw std::runtime_error("the model has no fallback tables: run `neuralyarn fallback MODEL`");
  }
  auto f = std::make_shared<model::FallbackTables>(*model.fallback);
  auto dir = [](const ny::Vec3 &w) { return model::cycles_lobes::Dir{w.x, w.y, w.z}; };
  FarField out;
  out.eval = [f, dir](const ny::Vec3 &wi, const ny::Vec3 &wo) {
    const auto v = model::fallback_eval(*f, dir(wi), dir(wo));
    return Rgb3{v[0], v[1], v[2]};
  };
  /* 32 x 32 samples per GGX albedo: per pixel sample this is the cost; well within the image noise. */
  out.albedo = [f, dir](const ny::Vec3 &wi) {
    const auto v = model::fallback_albedo(*f, dir(wi), 32);
    return Rgb3{v[0], v[1], v[2]};
  };
  return out;
}

std::vector<std::pair<Eigen::Vector3d, double>> distant_light_directions(const LightRig &rig)
{
  std::vector<std::pair<Eigen::Vector3d, double>> lights;
  for (const RigLight &l : rig.lights) {
    if (l.kind != RigLight::Kind::distant) {
      throw std::runtime_error("light rig '" + rig.name +
                               "' has sphere lights: the prediction covers the environment and distant lights");
    }
    const auto dirs = disc_directions(Eigen::Vector3d(l.x, l.y, l.z).normalized(), l.size, 6);
    for (const auto &d : dirs) {
      lights.emplace_back(d, l.strength / double(dirs.size()));
    }
  }
  return lights;
}

Rgb3 predict_closeup(const FarField &f, const LightRig &rig, const PixelRegion &r, const CloseupCamera &camera)
{
  if (!(r.width > 0 && r.height > 0 && r.w > 0 && r.h > 0 && r.x >= 0 && r.y >= 0 && r.x + r.w <= r.width &&
        r.y + r.h <= r.height))
  {
    throw std::runtime_error("the predicted region lies outside the image");
  }
  if (!(camera.distance > 1.0 && camera.fov > 0.0 && camera.fov < kPi)) {
    throw std::runtime_error("the predicted camera must lie outside the curve, with a field of view in (0, pi)");
  }
  const std::vector<std::pair<Eigen::Vector3d, double>> lights = distant_light_directions(rig);
  /* The ply runs along x, so the image varies across rows, and most steeply in the rows its silhouette
   * crosses (a rim lit from behind glows within a fraction of a pixel of it): those rows get 256 sub-rows. */
  const std::vector<double> offset_x = box_offsets(4), offset_y = box_offsets(8), offset_rim = box_offsets(256);
  /* Cycles' standalone camera applies the field of view to the shorter side of the image; raster row 0
   * is the top (+y). */
  const double aspect = double(r.width) / double(r.height);
  const double t = std::tan(0.5 * camera.fov) * (r.width >= r.height ? 1.0 : 1.0 / aspect);
  const Eigen::Vector3d o(0.0, 0.0, -camera.distance);
  auto raster_v = [&](double y) { return (1.0 - 2.0 * y / r.height) * t; };
  /* A camera ray (u, v, 1) passes the axis at distance D |v| / sqrt(1 + v^2), whatever u. */
  auto hits = [&](double y) {
    const double v = raster_v(y);
    return -o.z() * std::abs(v) / std::sqrt(1.0 + v * v) <= 1.0;
  };
  Rgb3 sum;
  for (int py = r.y; py < r.y + r.h; py++) {
    const double y0 = py + 0.5 - 0.5 * kPixelFilterWidth, y1 = py + 0.5 + 0.5 * kPixelFilterWidth;
    const std::vector<double> &offset_y_row = hits(y0) != hits(y1) || hits(y0) != hits(py + 0.5) ? offset_rim : offset_y;
    const double wgt = 1.0 / (double(offset_x.size()) * offset_y_row.size() * r.w * r.h);
    for (int px = r.x; px < r.x + r.w; px++) {
      for (const double oy : offset_y_row) {
        for (const double ox : offset_x) {
          const double u = (2.0 * (px + 0.5 + ox) / r.width - 1.0) * t * aspect;
          const double v = raster_v(py + 0.5 + oy);
          const Eigen::Vector3d d = Eigen::Vector3d(u, v, 1.0).normalized();
          /* The cylinder y^2 + z^2 = 1 (axis x): nearest hit. */
          const double a = d.y() * d.y() + d.z() * d.z(), b = 2.0 * o.z() * d.z(), c = o.z() * o.z() - 1.0;
          const double disc = b * b - 4.0 * a * c;
          if (!(disc >= 0.0)) {
            /* The background: white in the environment, black otherwise (camera rays do not see the
             * distant lights). */
            const double bg = rig.environment ? 1.0 : 0.0;
            sum.r += wgt * bg, sum.g += wgt * bg, sum.b += wgt * bg;
            continue;
          }
          const double s = (-b - std::sqrt(disc)) / (2.0 * a);
          const Eigen::Vector3d n(0.0, s * d.y(), o.z() + s * d.z());
          /* Yarn frame: x = +x (the curve runs from -x to +x), z = n, y = z x x = (0, n_z, -n_y). */
          auto local = [&n](const Eigen::Vector3d &w) {
            return ny::make_vec3(float(w.x()), float(w.y() * n.z() - w.z() * n.y()),
                                 float(w.y() * n.y() + w.z() * n.z()));
          };
          const ny::Vec3 wi = local(-d);
          if (!(wi.z > 0.0f)) {
            continue;
          }
          if (rig.environment) {
            const Rgb3 e = f.albedo(wi);
            sum.r += wgt * e.r, sum.g += wgt * e.g, sum.b += wgt * e.b;
          }
          for (const auto &[dir, irradiance] : lights) {
            const Rgb3 e = f.eval(wi, local(dir));
            sum.r += wgt * irradiance * e.r, sum.g += wgt * irradiance * e.g, sum.b += wgt * irradiance * e.b;
          }
        }
      }
    }
  }
  return sum;
}

std::vector<Rgb3> predict_closeup_image(const FarField &f, const LightRig &rig, int width, int height,
                                        const CloseupCamera &camera)
{
  if (!(width > 0 && height > 0)) {
    throw std::runtime_error("the predicted image needs a positive width and height");
  }
  std::vector<Rgb3> out(size_t(width) * size_t(height));
  tbb::parallel_for(0, height, [&](int py) {
    for (int px = 0; px < width; px++) {
      out[size_t(py) * size_t(width) + size_t(px)] = predict_closeup(f, rig, PixelRegion{width, height, px, py, 1, 1},
                                                                     camera);
    }
  });
  return out;
}

PixelRegion central_region(int width, int height, const CloseupCamera &camera)
{
  if (width <= 0 || height <= 0 || !(camera.distance > 1.0)) {
    throw std::runtime_error("central_region: needs a positive image size and a camera outside the curve");
  }
  /* Cycles' standalone camera applies the field of view to the image's shorter side. A ray from (0, 0, -d)
   * with direction (0, v, 1) passes the axis at distance d |v| / sqrt(1 + v^2): it hits the cylinder of radius 1
   * for |v| <= 1 / sqrt(d^2 - 1). */
  const double t = std::tan(0.5 * camera.fov) * (width >= height ? 1.0 : double(height) / double(width));
  const double v_max = 1.0 / std::sqrt(camera.distance * camera.distance - 1.0);
  int first = -1, last = -1;
  for (int py = 0; py < height; py++) {
    if (std::abs((1.0 - 2.0 * (py + 0.5) / height) * t) <= v_max) {
      first = first < 0 ? py : first;
      last = py;
    }
  }
  if (first < 0 || last - first < 2) {
    throw std::runtime_error("central_region: the curve covers too few rows of a " + std::to_string(width) + " x " +
                             std::to_string(height) + " image for a central region");
  }
  return {width, height, width / 4, first + 1, width - 2 * (width / 4), last - first - 1};
}

std::vector<Rgb3> predict_distant_rigs(const FarField &f, ImageFitRegions regions)
{
  /* The scenes' rigs of distant lights alone, in their order (ply_scene.h: front, grazing, back, axis). */
  std::vector<const LightRig *> rigs;
  for (const LightRig &rig : light_rigs()) {
    if (!rig.environment && !rig.lights.empty() &&
        std::all_of(rig.lights.begin(), rig.lights.end(),
                    [](const RigLight &l) { return l.kind == RigLight::Kind::distant; }))
    {
      rigs.push_back(&rig);
    }
  }
  constexpr int width = 160, height = 80; /* the close-up's image (scripts/evaluate.py DEFAULTS) */
  std::vector<PixelRegion> where{PixelRegion{width, height, 0, 0, width, height}};
  if (regions == ImageFitRegions::kFrameAndCentre) {
    where.push_back(central_region(width, height));
  }
  const size_t n = rigs.size();
  std::vector<Rgb3> out(n * where.size());
  tbb::parallel_for(0, int(out.size()), [&](int k) {
    out[size_t(k)] = predict_closeup(f, *rigs[size_t(k) % n], where[size_t(k) / n]);
  });
  return out;
}

double image_fit_error(const std::vector<Rgb3> &model, const std::vector<Rgb3> &maps)
{
  if (model.size() != maps.size() || maps.empty()) {
    throw std::runtime_error("image_fit_error: the model's and the maps' predictions differ in number");
  }
  /* One channel's term, written out per channel: GCC 12 at -O3 -march=native vectorised the loop over an array
   * of the three channels with AVX masked loads of the model's values under the first vector's mask alone, so a
   * black channel of the maps counted 1 instead of 0 (decisions D55; build.no_grouped_masked_loads). */
  const auto term = [](double x, double t) { return t > 0.0 ? std::abs(x / t - 1.0) : 0.0; };
  double sum = 0.0;
  for (size_t k = 0; k < maps.size(); k++) {
    sum += term(model[k].r, maps[k].r) + term(model[k].g, maps[k].g) + term(model[k].b, maps[k].b);
  }
  return sum / double(3 * maps.size());
}

}  // namespace neuralyarn::scenes
