// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/lobe_fidelity.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h" /* yarn_eval_M_lanes */
#include "neuralyarn/presets.h" /* ParameterError */
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

using nlohmann::json;

namespace {

int cells_for(double range_deg, int bins, double cell_deg)
{
  return std::clamp(int(std::lround(range_deg / cell_deg)), 1, bins);
}

/* Index of the cell that bin `i` of `n` falls into, with `cells` cells (an even split of the bins). */
int cell_of(int i, int n, int cells) { return int((int64_t(i) * cells) / n); }

/* Band of an outgoing bin: theta_o from the normal in 30-degree steps (0..5). */
int band_of(int to, int n_theta_o) { return std::min(5, int((to + 0.5) / n_theta_o * 6.0)); }

/* The unit vector of polar angle theta and azimuth phi in the entry frame, in double. */
std::array<double, 3> unit(double theta, double phi)
{
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

/* Number of incident bins in each phi_i group. */
std::vector<int> group_sizes(const LobeGrid &g)
{
  std::vector<int> n(size_t(g.phi_i_groups), 0);
  for (int pi = 0; pi < g.bins.phi_i; pi++) {
    n[size_t(cell_of(pi, g.bins.phi_i, g.phi_i_groups))]++;
  }
  return n;
}

ny::Vec3 direction(double theta, double phi)
{
  const Eigen::Vector3f w = train::entry_direction(theta, phi);
  return ny::make_vec3(w.x(), w.y(), w.z());
}

void check_same_bins(const rdm::MapResolution &x, const rdm::MapResolution &y, const char *what)
{
  if (!(x == y)) {
    throw ParameterError("maps", std::string(what) + ": the grids differ in resolution");
  }
}

json band_json(const std::vector<std::array<double, kLobeBands>> &v)
{
  json out = json::array();
  for (const auto &row : v) {
    out.push_back(std::vector<double>(row.begin(), row.end()));
  }
  return out;
}
}  // namespace

ny::Vec3 incident_sub_direction(const rdm::MapResolution &b, int ti, int pi, int s, int n)
{
  const double t0 = 0.5 * kPi * ti / b.theta_i, t1 = 0.5 * kPi * (ti + 1) / b.theta_i;
  const double u = (s / n + 0.5) / n, v = (s % n + 0.5) / n;
  const double cos_t = std::cos(t0) + u * (std::cos(t1) - std::cos(t0));
  return direction(std::acos(cos_t), -kPi + 2.0 * kPi * (pi + v) / b.phi_i);
}

void integrate_r_lobe(const ny::YarnBsdfParams &p, const rdm::MapResolution &b, int ti, int pi,
                      const std::function<void(int to, int po, const ny::Rgb &energy)> &add)
{
  integrate_r_parts(p, b, ti, pi, [&](int to, int po, float, const ny::Rgb &R, const ny::Rgb &TT, const ny::Rgb &tau) {
    add(to, po, (ny::make_rgb(1.0f) - tau) * R + tau * TT);
  });
}

void integrate_r_parts(const ny::YarnBsdfParams &p, const rdm::MapResolution &b, int ti, int pi,
                       const std::function<void(int to, int po, float phi_f, const ny::Rgb &R, const ny::Rgb &TT,
                                                const ny::Rgb &tau)> &add)
{
  constexpr int n_sub = kRSub, n_theta = 32, n_phi = 64;
  /* The samples form a (theta~, phi~) grid per node and part, and the lobe and its density are products of a
   * factor of each angle (ny::yarn_r_theta, ny::yarn_r_phi): each factor is computed once per row or column,
   * not per sample (the kernel evaluates the same functions at one w_o). The reflection part's azimuths are
   * the same for every node and incident direction. */
  struct Column {
    float phi, s, c;
  };
  static const std::array<Column, n_phi> uniform_phi = [] {
    std::array<Column, n_phi> u{};
    for (int k = 0; k < n_phi; k++) {
      const float phi = -ny::kHalfPi + ny::kPi * ((k + 0.5f) / n_phi);
      u[size_t(k)] = {phi, sinf(phi), cosf(phi)};
    }
    return u;
  }();
  std::array<Column, n_phi> tt_phi;
  std::array<ny::YarnRPhi, n_phi> a_uniform, a_tt;
  const rdm::OutgoingBinner outgoing_bin(b);
  for (int s = 0; s < n_sub * n_sub; s++) {
    const ny::YarnLobes l = ny::yarn_lobes(p, incident_sub_direction(b, ti, pi, s, n_sub));
    if (!l.valid) {
      continue; /* no R lobe below the horizon */
    }
    /* Each R node (weight 1 / n_R) on its own: one stratified set per part of its proposal (the TT part only
     * where it has a share), combined by the balance heuristic: each sample weighs eval / (sum over sets of
     * count x density). */
    const int parts = l.q_TT > 0.0f ? 2 : 1;
    const float count = float(n_sub * n_sub * n_theta * n_phi * l.n_R);
    for (int q = 0; q < l.n_R; q++) {
      const ny::YarnRNode &node = l.node[q];
      for (int k = 0; k < n_phi; k++) {
        a_uniform[size_t(k)] = ny::yarn_r_phi(l, q, uniform_phi[size_t(k)].phi);
        if (parts == 2) {
          const float phi = ny::sample_truncated_normal(node.tn_TT_phi, (k + 0.5f) / n_phi);
          tt_phi[size_t(k)] = {phi, sinf(phi), cosf(phi)};
          a_tt[size_t(k)] = ny::yarn_r_phi(l, q, phi);
        }
      }
      for (int part = 0; part < parts; part++) {
        const std::array<Column, n_phi> &cols = part == 0 ? uniform_phi : tt_phi;
        const std::array<ny::YarnRPhi, n_phi> &as = part == 0 ? a_uniform : a_tt;
        for (int j = 0; j < n_theta; j++) {
          const float theta = ny::sample_truncated_normal(part == 0 ? node.tn_R : node.tn_TT, (j + 0.5f) / n_theta);
          const float st = sinf(theta), ct = cosf(theta);
          const ny::YarnRTheta t = ny::yarn_r_theta(l, q, theta, fminf(ct, 1.0f));
          for (int k = 0; k < n_phi; k++) {
            const Column &col = cols[size_t(k)];
            /* As ny::direction_from_angles(theta, phi). */
            const ny::Vec3 wo_f = ny::make_vec3(st, ct * col.s, ct * col.c);
            if (!(wo_f.z > 0.0f)) {
              continue;
            }
            float pdf_R, pdf_TT;
            ny::yarn_pdf_R_factors(l, t, as[size_t(k)], &pdf_R, &pdf_TT);
            const float pdf = count * (parts == 2 ? pdf_R + pdf_TT : pdf_R);
            if (!(pdf > 0.0f)) {
              continue;
            }
            const ny::Vec3 wo = l.n_R == 1 ? ny::surface_fiber_to_yarn(p.twist, wo_f) : ny::r_node_to_yarn(node, wo_f);
            int to, po;
            outgoing_bin(wo.x, wo.y, wo.z, &to, &po);
            ny::Rgb R, TT;
            ny::yarn_eval_R_factors(l, t, as[size_t(k)], &R, &TT);
            add(to, po, col.phi, R * (1.0f / pdf), TT * (1.0f / pdf), l.tau);
          }
        }
      }
    }
  }
}

size_t LobeGrid::outgoing_cell(int to, int po) const
{
  return size_t(cell_of(to, bins.theta_o, theta_o_cells)) * size_t(phi_o_cells) +
         size_t(cell_of(po, bins.phi_o, phi_o_cells));
}

LobeGrid make_lobe_grid(const rdm::MapResolution &bins, const LobePooling &pooling)
{
  if (!(pooling.cell_deg > 0.0) || !std::isfinite(pooling.cell_deg)) {
    throw ParameterError("cell_deg", "the cell size must be a positive number of degrees");
  }
  LobeGrid g;
  g.bins = bins;
  g.phi_i_groups = cells_for(360.0, bins.phi_i, pooling.cell_deg);
  g.theta_o_cells = cells_for(180.0, bins.theta_o, pooling.cell_deg);
  g.phi_o_cells = cells_for(360.0, bins.phi_o, pooling.cell_deg);
  g.cells.assign(g.groups() * g.cells_per_group() * 3, 0.0);
  g.bands.assign(g.groups() * kLobeBands * 3, 0.0);
  for (int ti = 0; ti < bins.theta_i; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      g.incident_dirs.push_back(unit(rdm::bin_center(ti, 0.0, 0.5 * kPi, bins.theta_i), rdm::bin_center(pi, -kPi, kPi, bins.phi_i)));
    }
  }
  for (int to = 0; to < bins.theta_o; to++) {
    for (int po = 0; po < bins.phi_o; po++) {
      g.outgoing_dirs.push_back(unit(rdm::bin_center(to, 0.0, kPi, bins.theta_o), rdm::bin_center(po, -kPi, kPi, bins.phi_o)));
    }
  }
  return g;
}

void add_to_lobe_grid(LobeGrid *g, int ti, int pi, int to, int po, const double value[3], double w)
{
  const rdm::MapResolution &b = g->bins;
  const size_t group = size_t(ti) * size_t(g->phi_i_groups) + size_t(cell_of(pi, b.phi_i, g->phi_i_groups));
  double *c = &g->cells[(group * g->cells_per_group() + g->outgoing_cell(to, po)) * 3];
  double *band = &g->bands[(group * kLobeBands + size_t(band_of(to, b.theta_o))) * 3];
  double *axial = &g->bands[(group * kLobeBands + kLobeAxialBand) * 3];
  double *forward = &g->bands[(group * kLobeBands + kLobeForwardBand) * 3];
  double *through = &g->bands[(group * kLobeBands + kLobeThroughBand) * 3];
  /* Axial: w_o of the bin centre within 30 degrees of the ply axis (+-x); forward: within kLobeForwardDeg
   * of -w_i, w_i the incident bin centre; through: both within kLobeThroughDeg of the plane x = 0, w_o below
   * the entry point's horizon. */
  static const double cos_axial = std::cos(30.0 * kDeg), cos_forward = std::cos(kLobeForwardDeg * kDeg),
                      sin_through = std::sin(kLobeThroughDeg * kDeg);
  const std::array<double, 3> &wi = g->incident_dirs[size_t(ti) * size_t(b.phi_i) + size_t(pi)];
  const std::array<double, 3> &wo = g->outgoing_dirs[size_t(to) * size_t(b.phi_o) + size_t(po)];
  const bool ax = std::abs(wo[0]) > cos_axial;
  const bool fw = -(wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2]) > cos_forward;
  const bool th = std::abs(wi[0]) < sin_through && std::abs(wo[0]) < sin_through && wo[2] < 0.0;
  for (int k = 0; k < 3; k++) {
    c[k] += w * value[k];
    band[k] += w * value[k];
    if (ax) {
      axial[k] += w * value[k];
    }
    if (fw) {
      forward[k] += w * value[k];
    }
    if (th) {
      through[k] += w * value[k];
    }
  }
}

LobeGrid pool_map_lobe(const rdm::RdmMaps &maps, Lobe lobe, const LobePooling &pooling)
{
  const rdm::MapResolution &b = maps.bins;
  LobeGrid g = make_lobe_grid(b, pooling);
  const std::vector<float> &map = lobe == Lobe::kR ? maps.r : maps.m;
  const std::vector<int> per_group = group_sizes(g);
  tbb::parallel_for(0, b.theta_i, [&](int ti) { /* each row writes only its own groups */
    for (int pi = 0; pi < b.phi_i; pi++) {
      const double w = 1.0 / per_group[size_t(cell_of(pi, b.phi_i, g.phi_i_groups))];
      for (int to = 0; to < b.theta_o; to++) {
        const double dO = maps.outgoing_solid_angle(to);
        for (int po = 0; po < b.phi_o; po++) {
          const float *v = &map[maps.map_index(ti, pi, to, po)];
          const double e[3] = {v[0] * dO, v[1] * dO, v[2] * dO};
          add_to_lobe_grid(&g, ti, pi, to, po, e, w);
        }
      }
    }
  });
  return g;
}

LobeGrid model_lobe_grid(const YarnModel &model, const rdm::MapResolution &b, Lobe lobe, const LobePooling &pooling)
{
  LobeGrid g = make_lobe_grid(b, pooling);
  const std::vector<float> flat = model.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const std::vector<int> per_group = group_sizes(g);
  rdm::RdmMaps geometry; /* only for its solid angles */
  geometry.bins = b;
  /* The outgoing bins' centres, row-major, as direction() gives them. */
  struct {
    std::vector<float> x, y, z;
  } exits;
  if (lobe == Lobe::kM) {
    for (int to = 0; to < b.theta_o; to++) {
      for (int po = 0; po < b.phi_o; po++) {
        const ny::Vec3 wo = direction(rdm::bin_center(to, 0.0, kPi, b.theta_o), rdm::bin_center(po, -kPi, kPi, b.phi_o));
        exits.x.push_back(wo.x);
        exits.y.push_back(wo.y);
        exits.z.push_back(wo.z);
      }
    }
  }
  tbb::parallel_for(0, b.theta_i, [&](int ti) {
    for (int pi = 0; pi < b.phi_i; pi++) {
      const double w_group = 1.0 / per_group[size_t(cell_of(pi, b.phi_i, g.phi_i_groups))];
      if (lobe == Lobe::kR) {
        integrate_r_lobe(p, b, ti, pi, [&](int to, int po, const ny::Rgb &v) {
          const double e[3] = {v.r, v.g, v.b};
          add_to_lobe_grid(&g, ti, pi, to, po, e, w_group);
        });
        continue;
      }
      /* M (tens of degrees wide): at every map bin centre, for 2 x 2 incident directions inside the bin; the
       * network on a row's exits kMLanes at a time (each lane bit for bit yarn_eval_M). */
      constexpr int n_sub = 2;
      ny::Rgb v[kMLanes];
      for (int s = 0; s < n_sub * n_sub; s++) {
        const ny::YarnLobes l = ny::yarn_lobes(p, incident_sub_direction(b, ti, pi, s, n_sub));
        for (int to = 0; to < b.theta_o; to++) {
          const double dO = geometry.outgoing_solid_angle(to);
          for (int po0 = 0; po0 < b.phi_o; po0 += kMLanes) {
            const int n = std::min(kMLanes, b.phi_o - po0);
            const size_t q = size_t(to) * size_t(b.phi_o) + size_t(po0);
            yarn_eval_M_lanes(p, l, n, &exits.x[q], &exits.y[q], &exits.z[q], v);
            for (int k = 0; k < n; k++) {
              const double e[3] = {v[k].r * dO, v[k].g * dO, v[k].b * dO};
              add_to_lobe_grid(&g, ti, pi, to, po0 + k, e, w_group / (n_sub * n_sub));
            }
          }
        }
      }
    }
  });
  return g;
}

LobeComparison compare_lobes(const LobeGrid &x, const LobeGrid &a, const LobeGrid *b)
{
  check_same_bins(x.bins, a.bins, "model and maps A");
  if (b) {
    check_same_bins(a.bins, b->bins, "maps A and B");
  }
  if (x.cells.size() != a.cells.size() || (b && b->cells.size() != a.cells.size())) {
    throw ParameterError("pooling", "the grids were pooled differently");
  }
  LobeComparison r;
  r.noise_removed = b != nullptr;
  const int nt = a.bins.theta_i;
  const size_t per_row = size_t(a.phi_i_groups) * a.cells_per_group() * 3;
  const size_t bands_per_row = size_t(a.phi_i_groups) * kLobeBands * 3;
  for (int ti = 0; ti < nt; ti++) {
    double mass = 0, l1_raw = 0, l1 = 0, floor = 0;
    for (size_t i = size_t(ti) * per_row; i < size_t(ti + 1) * per_row; i++) {
      const double xa = x.cells[i], aa = a.cells[i];
      const double n = b ? 0.5 * (aa + b->cells[i]) : aa;
      mass += n;
      l1_raw += std::abs(xa - n);
      if (b) {
        const double bb = b->cells[i];
        floor += 0.5 * std::abs(aa - bb);
        l1 += std::sqrt(std::max(0.0, (xa - aa) * (xa - bb)));
      }
    }
    std::array<double, kLobeBands> xb{}, nb{};
    for (size_t i = size_t(ti) * bands_per_row; i < size_t(ti + 1) * bands_per_row; i++) {
      const int band = int((i / 3) % kLobeBands);
      xb[size_t(band)] += x.bands[i];
      nb[size_t(band)] += b ? 0.5 * (a.bands[i] + b->bands[i]) : a.bands[i];
    }
    const double inv = mass > 0 ? 1.0 / mass : 0.0;
    r.theta_i_deg.push_back(rdm::bin_center(ti, 0.0, 90.0, nt));
    r.l1_raw.push_back(l1_raw * inv);
    r.l1.push_back(b ? l1 * inv : l1_raw * inv);
    if (b) {
      r.noise_floor.push_back(floor * inv);
    }
    std::array<double, kLobeBands> ratio{}, share{};
    for (int k = 0; k < kLobeBands; k++) {
      /* A band holding less than 0.1 % of the row's energy has no meaningful ratio. */
      ratio[size_t(k)] = nb[size_t(k)] > 1e-3 * mass && mass > 0 ? xb[size_t(k)] / nb[size_t(k)] : 0.0;
      share[size_t(k)] = nb[size_t(k)] * inv;
    }
    r.band_ratio.push_back(ratio);
    r.band_share.push_back(share);
    const double xr = xb[0] + xb[1] + xb[2], nr = nb[0] + nb[1] + nb[2];
    const double xt = xb[3] + xb[4] + xb[5], ntr = nb[3] + nb[4] + nb[5];
    r.reflection_ratio.push_back(nr > 1e-3 * mass && mass > 0 ? xr / nr : 0.0);
    r.transmission_ratio.push_back(ntr > 1e-3 * mass && mass > 0 ? xt / ntr : 0.0);
  }
  for (int ti = 0; ti + 1 < nt; ti++) {
    r.l1_max_but_grazing = std::max(r.l1_max_but_grazing, r.l1[size_t(ti)]);
  }
  r.l1_grazing = r.l1.empty() ? 0.0 : r.l1.back();
  return r;
}

json LobeComparison::to_json() const
{
  json j = {{"theta_i_deg", theta_i_deg},
            {"l1", l1},
            {"l1_raw", l1_raw},
            {"noise_removed", noise_removed},
            {"l1_max_but_grazing", l1_max_but_grazing},
            {"l1_grazing", l1_grazing},
            {"reflection_ratio", reflection_ratio},
            {"transmission_ratio", transmission_ratio},
            {"band_ratio", band_json(band_ratio)},
            {"band_share", band_json(band_share)},
            {"bands", "theta_o 0-30, 30-60, 60-90, 90-120, 120-150, 150-180 deg from the ply normal; axial: "
                      "within 30 deg of the ply axis; forward: within 12 deg of -w_i; through: w_i and w_o within 15 deg "
                      "of the plane normal to the ply axis, w_o on the far side"}};
  if (noise_removed) {
    j["noise_floor"] = noise_floor;
  }
  return j;
}

json LobeFidelity::to_json() const { return {{"R", R.to_json()}, {"M", M.to_json()}, {"seconds", seconds}}; }

LobeFidelity check_lobes(const YarnModel &model, const rdm::RdmMaps &a, const rdm::RdmMaps *b,
                         const LobePooling &pooling)
{
  const auto t0 = std::chrono::steady_clock::now();
  for (const rdm::RdmMaps *m : {&a, b}) {
    if (!m) {
      continue;
    }
    if (preset_to_json(m->preset) != preset_to_json(model.preset)) {
      throw ParameterError("maps", "the maps were gathered for another preset than the model's");
    }
    if (std::find(m->count.begin(), m->count.end(), uint64_t(0)) != m->count.end()) {
      throw ParameterError("maps", "an incident bin of the maps has no paths (gather at least one path per bin)");
    }
  }
  if (b) {
    check_same_bins(a.bins, b->bins, "maps A and B");
    if (a.seed == b->seed) {
      throw ParameterError("maps", "the two maps have the same path seed: they are not independent");
    }
  }
  LobeFidelity f;
  for (Lobe lobe : {Lobe::kR, Lobe::kM}) {
    const LobeGrid x = model_lobe_grid(model, a.bins, lobe, pooling);
    const LobeGrid ga = pool_map_lobe(a, lobe, pooling);
    LobeComparison c;
    if (b) {
      const LobeGrid gb = pool_map_lobe(*b, lobe, pooling);
      c = compare_lobes(x, ga, &gb);
    }
    else {
      c = compare_lobes(x, ga);
    }
    (lobe == Lobe::kR ? f.R : f.M) = c;
  }
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return f;
}

}  // namespace neuralyarn::model
