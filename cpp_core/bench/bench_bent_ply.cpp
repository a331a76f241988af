// SPDX-License-Identifier: Apache-2.0
//
// A straight ply's far field on a bent one, predicted without a renderer (decisions D74): one ply on a circle of radius
// --radius ply radii in the image plane, turned --turn degrees about the image's vertical (bench_near_field.py's
// `ring-S` and `ringy-A` scenes: the same camera, 12 ply radii away on -z, field of view 0.9 across the shorter side),
// under a distant-light rig, each camera ray's hit given the direct light of the rig through the model's far field and
// through the radiance distribution maps themselves (interpolated; the best any far-field model of a straight ply can
// do). Where explicit fibers differ from both alike, the error is the aggregation's (a straight ply's far field on a
// bent ply), not the fit's. No shadows and no light between parts of the ring: only the camera-facing hits' direct light.
// With --sector-maps, also the bent ply's own far field (decisions D75): maps gathered on the ring, one per sector of
// psi about the tube (bench_bent_gather --sector k --sectors K), each hit read from its sector's.
// With --bent-m (bench_bent_m's networks, decisions D76), two more: R from the sector's maps and M from the network
// conditioned on the bend at the hit (kappa R and psi: the circle's, or the Catmull-Rom curve's there, kernel/bend.h),
// and the same with M from the network pooled over bends — whether the bend, given to M, does what the sectors' maps do.
// Where the networks carry their calibration per map (bench_bent_m since D77), two more: the conditioned M calibrated
// by its sector's table with the sector's R (`bent_m_cal`) or the model's R (`model_r_bent_m_cal`, what a model with
// the bend would render). --bend-split tells which lobe carries the bend and whether an energy per incident direction
// does (decisions D77).
//
// Usage: bench_bent_ply --model M.json --maps M.nyrdm [--sector-maps S0.nyrdm ...] [--turn 60] [--radius 3]
//                       [--bent-m NETS.json] [--bend-split] [--rig back] [--width 160] [--height 80] [--lobes RM|R|M]
//                       [--out PREFIX] (PREFIX_NAME.exr for every image NAME printed)
// Prints each image's mean colour. A benchmark: prints, never a test.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "neuralyarn/kernel/bend.h"
#include "neuralyarn/kernel/mlp.h"
#include "neuralyarn/train/mlp.h"

#include "neuralyarn/geometry/sweep.h"
#include "neuralyarn/plots.h"
#include "neuralyarn/rdm/embree_ply.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/scenes/closeup_prediction.h"
#include "neuralyarn/scenes/ply_curves.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {

/* A table of RGB values per incident bin ([theta_i][phi_i][rgb]) at w_i, bilinear between the bins' centres (clamped in
 * theta, periodic in phi), as the calibration table reads. */
template<class T>
scenes::Rgb3 incident_rgb(const std::vector<T> &table, const rdm::MapResolution &b, const ny::Vec3 &wi)
{
  const rdm::BinTaps ti = rdm::bin_taps(std::acos(std::clamp(double(wi.z), -1.0, 1.0)), 0.0, 0.5 * kPi, b.theta_i, false),
                     pi = rdm::bin_taps(std::atan2(double(wi.y), double(wi.x)), -kPi, kPi, b.phi_i, true);
  scenes::Rgb3 s;
  for (int x = 0; x < 2; x++) {
    for (int y = 0; y < 2; y++) {
      const double w = ti.weight[x] * pi.weight[y];
      const size_t k = (size_t(ti.bin[x]) * size_t(b.phi_i) + size_t(pi.bin[y])) * 3;
      s.r += w * table[k], s.g += w * table[k + 1], s.b += w * table[k + 2];
    }
  }
  return s;
}

}  // namespace

int main(int argc, char **argv)
{
  CLI::App app{"A straight ply's far field (model and maps) on a ply bent on a circle, predicted"};
  std::string model_path, maps_path, rig_name = "back", lobes_name = "RM", out;
  double turn_deg = 60.0, radius = 3.0;
  int width = 160, height = 80, sub = 3;
  app.add_option("--model", model_path, "Model file (.json)")->required();
  app.add_option("--maps", maps_path, "Its maps (.nyrdm)")->required();
  std::vector<std::string> sector_paths;
  app.add_option("--sector-maps", sector_paths, "Maps gathered per sector about the bent tube (bench_bent_gather "
                 "--sector k --sectors K, k = 0 ... K - 1): each hit takes its sector's (the images' `sectors`)");
  std::string bent_m_path;
  app.add_option("--bent-m", bent_m_path, "bench_bent_m's networks: R from the sector's maps, M from the network "
                 "conditioned on the hit's bend (`bent_m`) and from the pooled one (`pooled_m`); needs --sector-maps");
  std::string plies_path;
  bool bend_split = false;
  app.add_flag("--bend-split", bend_split, "With --sector-maps: which lobe carries the bend, and whether its energy per "
               "incident direction does: R from the sectors' maps and M from the straight ones (`r_bent`), the other way "
               "round (`m_bent`), the straight maps' M times the sector's M energy over the straight's per incident "
               "direction (`m_energy`), and the model with its R and M so rescaled (`model_energy`)");
  app.add_option("--plies", plies_path, "Instead of the circle: the plies of a neuralyarn-plies file (bench_near_field's "
                 "plies_SCENE.json), as the Catmull-Rom curves Cycles draws through their keys");
  app.add_option("--turn", turn_deg, "The circle turned about the image's vertical (degrees)")->check(CLI::Range(0.0, 89.0));
  app.add_option("--radius", radius, "The circle's radius (ply radii)")->check(CLI::Range(1.5, 5.0));
  app.add_option("--rig", rig_name, "A distant-light rig (scenes::find_light_rig)");
  app.add_option("--width", width)->check(CLI::Range(8, 4096));
  app.add_option("--height", height)->check(CLI::Range(8, 4096));
  app.add_option("--lobes", lobes_name, "RM, R or M");
  app.add_option("--out", out, "Write PREFIX_model.exr, PREFIX_maps.exr (and with --sector-maps PREFIX_sectors.exr)");
  CLI11_PARSE(app, argc, argv);
  try {
    const model::YarnModel model = model::load_model(model_path);
    const rdm::RdmMaps maps = rdm::load_maps(maps_path);
    const scenes::Lobes lobes = scenes::parse_lobes(lobes_name);
    const std::vector<scenes::FarField> far = {
        scenes::model_far_field(model, lobes),
        scenes::maps_far_field(maps, lobes, scenes::MapLookup::kInterpolated)};
    std::vector<rdm::RdmMaps> sector_maps;
    for (const std::string &p : sector_paths) {
      sector_maps.push_back(rdm::load_maps(p));
    }
    std::vector<scenes::FarField> by_sector;
    for (const rdm::RdmMaps &m : sector_maps) {
      by_sector.push_back(scenes::maps_far_field(m, lobes, scenes::MapLookup::kInterpolated)); /* refers to m */
    }
    /* R alone from each sector's maps, M from a network of S_M |cos theta_o| (bench_bent_m). */
    std::vector<scenes::FarField> r_by_sector;
    std::vector<float> bent_m, pooled_m;
    std::vector<std::vector<float>> bent_cal; /* per sector: the conditioned M's calibration [theta_i][phi_i][rgb] */
    std::vector<float> straight_cal;          /* the same on the straight ply's maps, if among them */
    if (!bent_m_path.empty()) {
      if (by_sector.empty() || lobes != scenes::Lobes::kRM) {
        throw std::runtime_error("--bent-m needs --sector-maps (their R) and --lobes RM");
      }
      std::ifstream in(bent_m_path);
      const nlohmann::json j = nlohmann::json::parse(in);
      bent_m = j.at("conditioned").get<std::vector<float>>();
      if (j.contains("pooled")) { /* bench_bent_m --no-pooled writes none */
        pooled_m = j.at("pooled").get<std::vector<float>>();
      }
      if (j.contains("conditioned_calibration")) {
        /* Each sector map's table, found by the bend it records. */
        for (const rdm::RdmMaps &m : sector_maps) {
          const nlohmann::json *found = nullptr;
          for (const nlohmann::json &c : j.at("conditioned_calibration")) {
            if (c.at("radius").get<double>() == m.bend_radius && c.at("sector").get<int>() == m.bend_sector &&
                c.at("sectors").get<int>() == m.bend_sectors && c.at("theta_bins").get<int>() == m.bins.theta_i &&
                c.at("phi_bins").get<int>() == m.bins.phi_i) {
              found = &c;
            }
          }
          if (!found) {
            throw std::runtime_error(bent_m_path + ": no calibration for a sector map's bend");
          }
          bent_cal.push_back(found->at("c_M").get<std::vector<float>>());
          if (bent_cal.back().size() != size_t(m.bins.theta_i) * m.bins.phi_i * 3) {
            throw std::runtime_error(bent_m_path + ": a calibration table of the wrong size");
          }
        }
        for (const nlohmann::json &c : j.at("conditioned_calibration")) {
          if (c.at("radius").get<double>() == 0.0 && c.at("theta_bins").get<int>() == sector_maps[0].bins.theta_i &&
              c.at("phi_bins").get<int>() == sector_maps[0].bins.phi_i) {
            straight_cal = c.at("c_M").get<std::vector<float>>();
            if (straight_cal.size() != size_t(sector_maps[0].bins.theta_i) * sector_maps[0].bins.phi_i * 3) {
              throw std::runtime_error(bent_m_path + ": a calibration table of the wrong size");
            }
          }
        }
      }
      /* from_flat validates the arrays' headers and sizes (throws ParameterError), then the inputs. */
      if (train::Mlp<float>::from_flat(bent_m).shape().widths.front() != 8 ||
          (!pooled_m.empty() && train::Mlp<float>::from_flat(pooled_m).shape().widths.front() != 6)) {
        throw std::runtime_error(bent_m_path + ": not bench_bent_m's networks (8 and 6 inputs)");
      }
      for (const rdm::RdmMaps &m : sector_maps) {
        r_by_sector.push_back(scenes::maps_far_field(m, scenes::Lobes::kR, scenes::MapLookup::kInterpolated));
      }
    }
    /* Every image: its name and its S |cos theta_o| at a hit given the hit's sector and bend (kappa R, psi). */
    using Predict = std::function<scenes::Rgb3(const ny::Vec3 &, const ny::Vec3 &, int, double, double)>;
    struct Image {
      std::string name;
      Predict predict;
    };
    std::vector<Image> images;
    auto add = [&images](std::string name, Predict predict) { images.push_back({std::move(name), std::move(predict)}); };
    add("model", [&](const ny::Vec3 &wi, const ny::Vec3 &wo, int, double, double) {
      return far[0].eval(wi, wo);
    });
    add("maps", [&](const ny::Vec3 &wi, const ny::Vec3 &wo, int, double, double) {
      return far[1].eval(wi, wo);
    });
    if (!by_sector.empty()) {
      add("sectors", [&](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double, double) {
        return by_sector[size_t(k)].eval(wi, wo);
      });
    }
    for (const bool conditioned : {true, false}) {
      if (bent_m.empty() || (!conditioned && pooled_m.empty())) {
        break;
      }
      const float *net = conditioned ? bent_m.data() : pooled_m.data(); /* both outlive the images */
      add(conditioned ? "bent_m" : "pooled_m", [&, net](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double kappa,
                                                        double psi) {
        scenes::Rgb3 e = r_by_sector[size_t(k)].eval(wi, wo);
        const float in[8] = {wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, float(kappa * std::cos(psi)), float(kappa * std::sin(psi))};
        float m[3];
        ny::mlp_forward(net, in, m);
        e.r += m[0], e.g += m[1], e.b += m[2];
        return e;
      });
    }
    /* The conditioned M calibrated per sector (bench_bent_m's tables), with R from the sector's maps (`bent_m_cal`) or
     * the model's (`model_r_bent_m_cal`: what a model with the bend would render). */
    std::vector<scenes::FarField> model_Rc;
    if (!bent_cal.empty()) {
      model_Rc.push_back(scenes::model_far_field(model, scenes::Lobes::kR));
      const rdm::MapResolution b = sector_maps[0].bins;
      /* 0: sector R; 1: model R; 2: model R, every bend the straight ply's table; 3: the same without the bend (the
       * conditioned network's straight far field on the bent ply: what it makes of the straight maps). */
      for (const int variant : {0, 1, 2, 3}) {
        const bool model_r = variant > 0, straight = variant >= 2, no_bend = variant == 3;
        if (straight && straight_cal.empty()) {
          break;
        }
        const char *names[] = {"bent_m_cal", "model_r_bent_m_cal", "model_r_bent_m_cal0", "model_r_m0_cal0"};
        add(names[variant],
            [&, b, model_r, straight, no_bend](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double kappa, double psi) {
              scenes::Rgb3 e = model_r ? model_Rc[0].eval(wi, wo) : r_by_sector[size_t(k)].eval(wi, wo);
              const float bend = no_bend ? 0.0f : 1.0f;
              const float in[8] = {wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, bend * float(kappa * std::cos(psi)),
                                   bend * float(kappa * std::sin(psi))};
              float m[3];
              ny::mlp_forward(bent_m.data(), in, m);
              const scenes::Rgb3 c = incident_rgb(straight ? straight_cal : bent_cal[size_t(k)], b, wi);
              e.r += m[0] * c.r, e.g += m[1] * c.g, e.b += m[2] * c.b;
              return e;
            });
      }
    }
    /* --bend-split: the lobes apart, and each sector's R and M energy over the straight maps' per incident bin. */
    std::vector<scenes::FarField> r_straight, m_straight, r_sector, m_sector, r_model, m_model;
    std::vector<std::vector<double>> ratio_R, ratio_M; /* [sector][theta_i][phi_i][rgb] */
    if (bend_split) {
      if (by_sector.empty() || lobes != scenes::Lobes::kRM) {
        throw std::runtime_error("--bend-split needs --sector-maps and --lobes RM");
      }
      r_straight.push_back(scenes::maps_far_field(maps, scenes::Lobes::kR, scenes::MapLookup::kInterpolated));
      m_straight.push_back(scenes::maps_far_field(maps, scenes::Lobes::kM, scenes::MapLookup::kInterpolated));
      r_model.push_back(scenes::model_far_field(model, scenes::Lobes::kR));
      m_model.push_back(scenes::model_far_field(model, scenes::Lobes::kM));
      const std::vector<double> eR = maps.energy(maps.r), eM = maps.energy(maps.m);
      for (const rdm::RdmMaps &m : sector_maps) {
        if (m.bins.theta_i != maps.bins.theta_i || m.bins.phi_i != maps.bins.phi_i) {
          throw std::runtime_error("--bend-split: the sector maps' incident bins differ from --maps'");
        }
        r_sector.push_back(scenes::maps_far_field(m, scenes::Lobes::kR, scenes::MapLookup::kInterpolated));
        m_sector.push_back(scenes::maps_far_field(m, scenes::Lobes::kM, scenes::MapLookup::kInterpolated));
        std::vector<double> qR = m.energy(m.r), qM = m.energy(m.m);
        for (size_t i = 0; i < qR.size(); i++) {
          qR[i] = eR[i] > 1e-9 ? qR[i] / eR[i] : 1.0;
          qM[i] = eM[i] > 1e-9 ? qM[i] / eM[i] : 1.0;
        }
        ratio_R.push_back(std::move(qR));
        ratio_M.push_back(std::move(qM));
      }
      /* Where the bend moves M: each map's M energy, all of it and within 20 and 40 degrees of -w_i (bin centres;
       * the mean of RGB, averaged over incident bins by solid angle), each sector's over the straight maps'. */
      auto m_shares = [](const rdm::RdmMaps &m) {
        const rdm::MapResolution &b = m.bins;
        const double c20 = std::cos(20.0 * kDeg), c40 = std::cos(40.0 * kDeg);
        double e[3] = {0, 0, 0}, w = 0.0;
        for (int ti = 0; ti < b.theta_i; ti++) {
          const double t_i = 0.5 * kPi * (ti + 0.5) / b.theta_i, dI = m.incident_solid_angle(ti);
          for (int pi = 0; pi < b.phi_i; pi++) {
            const double p_i = -kPi + 2.0 * kPi * (pi + 0.5) / b.phi_i;
            const Eigen::Vector3d wi(std::sin(t_i) * std::cos(p_i), std::sin(t_i) * std::sin(p_i), std::cos(t_i));
            for (int to = 0; to < b.theta_o; to++) {
              const double t_o = kPi * (to + 0.5) / b.theta_o, dO = m.outgoing_solid_angle(to);
              for (int po = 0; po < b.phi_o; po++) {
                const double p_o = -kPi + 2.0 * kPi * (po + 0.5) / b.phi_o;
                const Eigen::Vector3d wo(std::sin(t_o) * std::cos(p_o), std::sin(t_o) * std::sin(p_o), std::cos(t_o));
                const float *v = &m.m[m.map_index(ti, pi, to, po)];
                const double x = (double(v[0]) + v[1] + v[2]) / 3.0 * dO * dI, c = -wi.dot(wo);
                e[0] += x, e[1] += c > c40 ? x : 0.0, e[2] += c > c20 ? x : 0.0;
              }
            }
            w += dI;
          }
        }
        return std::array<double, 3>{e[0] / w, e[1] / w, e[2] / w};
      };
      const std::array<double, 3> straight_shares = m_shares(maps);
      std::printf("M energy of each sector over the straight maps' (mean over incident bins): all, within 40 and 20 "
                  "degrees of -w_i\n");
      for (size_t k = 0; k < sector_maps.size(); k++) {
        const std::array<double, 3> e = m_shares(sector_maps[k]);
        std::printf("  sector %zu: %.3f %.3f %.3f\n", k, e[0] / straight_shares[0], e[1] / straight_shares[1],
                    e[2] / straight_shares[2]);
      }
      const rdm::MapResolution b = maps.bins;
      auto ratio = [b](const std::vector<double> &q, const ny::Vec3 &wi) { return incident_rgb(q, b, wi); };
      auto sum = [](scenes::Rgb3 a, const scenes::Rgb3 &x, const scenes::Rgb3 &qa, const scenes::Rgb3 &qx) {
        return scenes::Rgb3{a.r * qa.r + x.r * qx.r, a.g * qa.g + x.g * qx.g, a.b * qa.b + x.b * qx.b};
      };
      const scenes::Rgb3 one{1.0, 1.0, 1.0};
      add("r_bent", [&, sum, one](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double, double) {
        return sum(r_sector[size_t(k)].eval(wi, wo), m_straight[0].eval(wi, wo), one, one);
      });
      add("m_bent", [&, sum, one](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double, double) {
        return sum(r_straight[0].eval(wi, wo), m_sector[size_t(k)].eval(wi, wo), one, one);
      });
      add("m_energy", [&, sum, one, ratio](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double,
                                                           double) {
        return sum(r_sector[size_t(k)].eval(wi, wo), m_straight[0].eval(wi, wo), one, ratio(ratio_M[size_t(k)], wi));
      });
      add("rm_energy", [&, sum, ratio](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double, double) {
        return sum(r_straight[0].eval(wi, wo), m_straight[0].eval(wi, wo), ratio(ratio_R[size_t(k)], wi),
                   ratio(ratio_M[size_t(k)], wi));
      });
      add("model_energy", [&, sum, ratio](const ny::Vec3 &wi, const ny::Vec3 &wo, int k, double,
                                                           double) {
        return sum(r_model[0].eval(wi, wo), m_model[0].eval(wi, wo), ratio(ratio_R[size_t(k)], wi),
                   ratio(ratio_M[size_t(k)], wi));
      });
    }
    std::vector<std::vector<Eigen::Vector3d>> lines, ply_keys;
    std::unique_ptr<rdm::EmbreePly> curves;
    constexpr int kPerSpan = 16; /* the polyline's chords per key span */
    if (!plies_path.empty()) {
      for (const auto &keys : scenes::read_ply_curves(plies_path).plies) {
        lines.push_back(geometry::catmull_rom_polyline(keys, kPerSpan));
        ply_keys.push_back(keys);
      }
      curves = std::make_unique<rdm::EmbreePly>(scenes::curve_set(lines, 1.0), "");
    }
    const auto lights = scenes::distant_light_directions(scenes::find_light_rig(rig_name));
    const double turn = turn_deg * kDeg;
    /* The circle's plane: e1 (the image's x turned toward the camera) and e2 (the image's vertical). */
    const Eigen::Vector3d e1(std::cos(turn), 0.0, std::sin(turn)), e2(0.0, 1.0, 0.0), e3 = e1.cross(e2);
    const Eigen::Vector3d o(0.0, 0.0, -scenes::kCloseupCameraDistance);
    const double t = std::tan(0.5 * scenes::kCloseupCameraFov) * (width >= height ? 1.0 : double(height) / width);
    const double aspect = double(width) / height;
    std::vector<std::vector<float>> img(images.size(), std::vector<float>(size_t(width) * height * 3, 0.0f));
    for (int py = 0; py < height; py++) {
      for (int px = 0; px < width; px++) {
        for (int k = 0; k < sub * sub; k++) {
          const double u = (2.0 * (px + (k % sub + 0.5) / sub) / width - 1.0) * t * aspect;
          const double v = (1.0 - 2.0 * (py + (k / sub + 0.5) / sub) / height) * t;
          const Eigen::Vector3d d = Eigen::Vector3d(u, v, 1.0).normalized();
          /* The frame at the hit (X along the curve, Z the tube's normal, Y = Z x X) and psi, the normal's angle about
           * the tube from the bend's outward direction (away from the centre of curvature) toward outward x X. */
          Eigen::Vector3d X, Y, Z;
          double psi = 0.0, kappa = 0.0; /* kappa in 1 / ply radius */
          if (!curves) {
            /* Sphere tracing the tube of radius 1 about the circle. */
            double s = 0.0;
            bool hit = false;
            Eigen::Vector3d p;
            for (int step = 0; step < 512 && s < 4.0 * scenes::kCloseupCameraDistance; step++) {
              p = o + s * d;
              const double dist = std::hypot(std::hypot(p.dot(e1), p.dot(e2)) - radius, p.dot(e3)) - 1.0;
              if (dist < 1e-7) {
                hit = true;
                break;
              }
              s += dist;
            }
            if (!hit) {
              continue;
            }
            /* X along the circle (increasing angle, as the scene's keys run). */
            const double a = std::atan2(p.dot(e2), p.dot(e1));
            const Eigen::Vector3d out = std::cos(a) * e1 + std::sin(a) * e2;
            X = -std::sin(a) * e1 + std::cos(a) * e2;
            Z = (p - radius * out).normalized();
            psi = std::atan2(Z.dot(e3), Z.dot(out));
            kappa = 1.0 / radius;
          }
          else {
            rdm::EmbreeHit h;
            if (!curves->intersect(ny::make_vec3(float(o.x()), float(o.y()), float(o.z())),
                                   ny::make_vec3(float(d.x()), float(d.y()), float(d.z())), 0.0f,
                                   std::numeric_limits<float>::infinity(), &h)) {
              continue;
            }
            const Eigen::Vector3d p = o + double(h.t) * d;
            const std::vector<Eigen::Vector3d> &q = lines[size_t(h.fiber)];
            /* The nearest chord of the ply's polyline and its foot: the Catmull-Rom segment and u there, whose bend the
             * kernel's (kernel/bend.h). */
            size_t j = 0;
            double best = std::numeric_limits<double>::infinity(), foot = 0.0;
            for (size_t i = 0; i + 1 < q.size(); i++) {
              const Eigen::Vector3d e = q[i + 1] - q[i];
              const double f = std::clamp((p - q[i]).dot(e) / e.squaredNorm(), 0.0, 1.0);
              const double dist = (p - q[i] - f * e).squaredNorm();
              if (dist < best) {
                best = dist;
                j = i;
                foot = f;
              }
            }
            X = (q[j + 1] - q[j]).normalized();
            const Eigen::Vector3d r = p - q[j] - (p - q[j]).dot(X) * X;
            Z = r.normalized();
            const std::vector<Eigen::Vector3d> &keys = ply_keys[size_t(h.fiber)];
            const size_t n = keys.size(), span = n < 3 ? j : j / kPerSpan;
            const double u = n < 3 ? foot : (double(j % kPerSpan) + foot) / kPerSpan;
            const size_t at[4] = {span ? span - 1 : 0, span, std::min(span + 1, n - 1), std::min(span + 2, n - 1)};
            ny::Vec3 P[4];
            for (int i = 0; i < 4; i++) {
              P[i] = ny::make_vec3(float(keys[at[i]].x()), float(keys[at[i]].y()), float(keys[at[i]].z()));
            }
            auto v3 = [](const Eigen::Vector3d &w) { return ny::make_vec3(float(w.x()), float(w.y()), float(w.z())); };
            const ny::YarnBend b = ny::yarn_bend(ny::catmull_rom_curvature(P, float(u)), v3(X), v3(Z), 1.0f);
            kappa = std::hypot(double(b.c), double(b.s));
            psi = std::atan2(double(b.s), double(b.c));
          }
          Y = Z.cross(X);
          auto local = [&](const Eigen::Vector3d &w) {
            return ny::make_vec3(float(w.dot(X)), float(w.dot(Y)), float(w.dot(Z)));
          };
          const ny::Vec3 wi = local(-d);
          if (!(wi.z > 0.0f)) {
            continue;
          }
          const int K = int(by_sector.size());
          const int sector = K > 0 ? int(std::lround(psi / (2.0 * kPi / K)) % K + K) % K : 0;
          for (size_t f = 0; f < images.size(); f++) {
            float *q = &img[f][(size_t(py) * width + px) * 3];
            for (const auto &[dir, irradiance] : lights) {
              const scenes::Rgb3 e = images[f].predict(wi, local(dir), sector, kappa, psi);
              const double w = irradiance / (sub * sub);
              q[0] += float(w * e.r), q[1] += float(w * e.g), q[2] += float(w * e.b);
            }
          }
        }
      }
    }
    for (size_t f = 0; f < img.size(); f++) {
      double m[3] = {0, 0, 0};
      for (size_t i = 0; i < img[f].size(); i++) {
        m[i % 3] += img[f][i] / (double(width) * height);
      }
      std::printf("%s: frame mean %.6f %.6f %.6f\n", images[f].name.c_str(), m[0], m[1], m[2]);
      if (!out.empty()) {
        write_rgb_exr(img[f], width, height, out + "_" + images[f].name + ".exr");
      }
    }
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "bench_bent_ply: %s\n", e.what());
    return 1;
  }
  return 0;
}
