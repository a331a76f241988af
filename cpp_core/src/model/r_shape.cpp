// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/r_shape.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/presets.h" /* ParameterError */
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

namespace {
constexpr double kMaxDensityRatio = 20.0;
}  // namespace

double r_free_path(const YarnModel &model)
{
  if (model.structure.is_yarn()) {
    return 0.0;
  }
  return kRFreePathScale * kPi / (2.0 * std::sqrt(double(model.preset.N) * model.preset.rho));
}

std::vector<float> r_surface_frames(const YarnModel &model, double spread)
{
  if (!model.structure.is_yarn()) {
    throw ParameterError("r_surface_spread",
                         "the R nodes' surface frames are a yarn-level model's (a ply has no plies)");
  }
  const std::vector<geometry::SurfaceFrame> frames = geometry::visible_surface_frames(
      geometry::Yarn(geometry::yarn_params(model.preset, model.structure), 1), ny::kYarnRNodes, spread);
  std::vector<float> out;
  for (const geometry::SurfaceFrame &f : frames) {
    /* Q = M(phi_1) R_x(a) P(phi_2) with rows T, B, N: N = (sin a sin phi_2, sin a cos phi_2, cos a) (a in [0, pi]),
     * then T = cos phi_1 m_1 - sin phi_1 m_2 with m_1, m_2 the first rows of R_x(a) P(phi_2). */
    const Eigen::Vector3d &N = f.N, &T = f.T;
    const double ca = N.z(), sa = std::hypot(N.x(), N.y());
    const double c2 = sa > 1e-12 ? N.y() / sa : 1.0, s2 = sa > 1e-12 ? N.x() / sa : 0.0;
    const Eigen::Vector3d m1(c2, -s2, 0.0), m2(ca * s2, ca * c2, -sa);
    const double c1 = T.dot(m1), s1 = -T.dot(m2);
    for (const double v : {c2, s2, ca, sa, c1, s1}) {
      out.push_back(float(v));
    }
  }
  return out;
}

void set_r_surface_spread(YarnModel *model, double spread)
{
  model->r_frames = spread > 0.0 ? r_surface_frames(*model, spread) : std::vector<float>();
  model->r_surface_spread = spread;
}

void require_one_r_node_kind(double free_path, double surface_spread)
{
  if (free_path > 0.0 && surface_spread > 0.0) {
    throw ParameterError("r_free_path", "an R node is the free path's or a surface fiber, not both: set the free "
                                        "path or the surface spread to 0");
  }
}

Eigen::VectorXd nonnegative_least_squares(const Eigen::MatrixXd &G, const Eigen::VectorXd &h)
{
  const int n = int(h.size());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  std::vector<bool> passive(size_t(n), false);
  const double tol = 1e-12 * std::max(1.0, G.diagonal().cwiseAbs().maxCoeff());
  auto solve_passive = [&] {
    std::vector<int> idx;
    for (int j = 0; j < n; j++) {
      if (passive[size_t(j)]) {
        idx.push_back(j);
      }
    }
    Eigen::MatrixXd Gp(idx.size(), idx.size());
    Eigen::VectorXd hp(idx.size());
    for (size_t a = 0; a < idx.size(); a++) {
      hp[long(a)] = h[idx[a]];
      for (size_t b = 0; b < idx.size(); b++) {
        Gp(long(a), long(b)) = G(idx[a], idx[b]);
      }
    }
    const Eigen::VectorXd zp = Gp.ldlt().solve(hp);
    Eigen::VectorXd z = Eigen::VectorXd::Zero(n);
    for (size_t a = 0; a < idx.size(); a++) {
      z[idx[a]] = zp[long(a)];
    }
    return z;
  };
  for (int outer = 0; outer < 4 * n; outer++) {
    const Eigen::VectorXd w = h - G * x;
    int j_max = -1;
    for (int j = 0; j < n; j++) {
      if (!passive[size_t(j)] && w[j] > tol && (j_max < 0 || w[j] > w[j_max])) {
        j_max = j;
      }
    }
    if (j_max < 0) {
      break;
    }
    passive[size_t(j_max)] = true;
    for (int inner = 0; inner < 4 * n; inner++) {
      const Eigen::VectorXd z = solve_passive();
      double alpha = 1.0;
      bool feasible = true;
      for (int j = 0; j < n; j++) {
        if (passive[size_t(j)] && z[j] <= 0.0) {
          feasible = false;
          alpha = std::min(alpha, x[j] / (x[j] - z[j]));
        }
      }
      if (feasible) {
        x = z;
        break;
      }
      x += alpha * (z - x);
      for (int j = 0; j < n; j++) {
        if (passive[size_t(j)] && x[j] <= 1e-15) {
          passive[size_t(j)] = false;
          x[j] = 0.0;
        }
      }
    }
  }
  return x;
}

RShapeTable fit_r_shape(const YarnModel &model, const rdm::RdmMaps &maps, const RShapeOptions &o)
{
  if (o.theta_bins < 1 || o.phi_bins < 1 || o.azimuth_bins < 2 || o.theta_bins > 1024 || o.phi_bins > 1024 ||
      o.azimuth_bins > 1024) {
    throw ParameterError("r_shape", "table bins out of range");
  }
  const rdm::MapResolution &b = maps.bins;
  const int na = o.azimuth_bins, nv = na + 1; /* the reflection's azimuth pieces and the TT part */
  const LobeGrid pooled = make_lobe_grid(b); /* its outgoing cells (about 12 degrees), as the 4D measure's */
  const size_t n_cells = pooled.cells_per_group();

  RShapeTable t;
  t.theta_bins = o.theta_bins;
  t.phi_bins = o.phi_bins;
  t.azimuth_bins = na;
  const int stride = t.stride();
  t.values.assign(size_t(o.theta_bins) * size_t(o.phi_bins) * size_t(stride), 0.0f);

  /* The model with a uniform azimuth; tau = 1 only switches the TT part's sampling on where it exists. */
  YarnModel uniform = model;
  uniform.r_shape = t;
  for (size_t r = 0; r < t.values.size(); r += size_t(stride)) {
    std::fill_n(&uniform.r_shape.values[r], na, float(1.0 / kPi));
    std::fill_n(&uniform.r_shape.values[r + size_t(na)], 3, o.fit_tt ? 1.0f : 0.0f);
  }
  const std::vector<float> flat = uniform.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  /* phi~_o bin of each map bin's centre (-1: not on the upper half, where R cannot go). */
  std::vector<int> az_of(b.outgoing(), -1);
  for (int to = 0; to < b.theta_o; to++) {
    for (int po = 0; po < b.phi_o; po++) {
      const Eigen::Vector3f w =
          train::entry_direction(rdm::bin_center(to, 0.0, kPi, b.theta_o), rdm::bin_center(po, -kPi, kPi, b.phi_o));
      const ny::Vec3 wf = ny::yarn_to_surface_fiber(p.twist, ny::make_vec3(w.x(), w.y(), w.z()));
      if (wf.z > 0.0f) {
        az_of[size_t(to) * size_t(b.phi_o) + size_t(po)] = std::min(na - 1, int((ny::phi_of(wf) + 0.5 * kPi) / kPi * na));
      }
    }
  }

  tbb::parallel_for(0, o.theta_bins, [&](int tt) {
    /* Per table cell of this theta row: the map [cell][rgb] and the pieces [cell][piece][rgb]. */
    std::vector<std::vector<double>> y(size_t(o.phi_bins)), A(size_t(o.phi_bins));
    /* And per phi~_o bin of the map bins' centres: the map, the reflection part and the TT part [bin][rgb]. */
    std::vector<std::vector<double>> y_az(size_t(o.phi_bins)), r_az(size_t(o.phi_bins)), t_az(size_t(o.phi_bins));
    for (int tp = 0; tp < o.phi_bins; tp++) {
      y[size_t(tp)].assign(n_cells * 3, 0.0);
      A[size_t(tp)].assign(n_cells * size_t(nv) * 3, 0.0);
      y_az[size_t(tp)].assign(size_t(na) * 3, 0.0);
      r_az[size_t(tp)].assign(size_t(na) * 3, 0.0);
      t_az[size_t(tp)].assign(size_t(na) * 3, 0.0);
    }
    for (int ti = 0; ti < b.theta_i; ti++) {
      if (ti * o.theta_bins / b.theta_i != tt) {
        continue;
      }
      for (int pi = 0; pi < b.phi_i; pi++) {
        const size_t tp = size_t(pi * o.phi_bins / b.phi_i);
        for (int to = 0; to < b.theta_o; to++) {
          const double dO = maps.outgoing_solid_angle(to);
          for (int po = 0; po < b.phi_o; po++) {
            const float *v = &maps.r[maps.map_index(ti, pi, to, po)];
            const int k = az_of[size_t(to) * size_t(b.phi_o) + size_t(po)];
            for (int c = 0; c < 3; c++) {
              y[tp][pooled.outgoing_cell(to, po) * 3 + size_t(c)] += v[c] * dO;
              if (k >= 0) {
                y_az[tp][size_t(k) * 3 + size_t(c)] += v[c] * dO;
              }
            }
          }
        }
        integrate_r_parts(p, b, ti, pi,
                          [&](int to, int po, float phi_f, const ny::Rgb &er, const ny::Rgb &et, const ny::Rgb &) {
                            const int k = std::clamp(int((phi_f + 0.5 * kPi) / kPi * na), 0, na - 1);
                            const int kc = az_of[size_t(to) * size_t(b.phi_o) + size_t(po)];
                            double *a = &A[tp][pooled.outgoing_cell(to, po) * size_t(nv) * 3];
                            const float vr[3] = {er.r, er.g, er.b}, vt[3] = {et.r, et.g, et.b};
                            for (int c = 0; c < 3; c++) {
                              a[size_t(k) * 3 + size_t(c)] += vr[c];
                              a[size_t(na) * 3 + size_t(c)] += vt[c];
                              if (kc >= 0) {
                                r_az[tp][size_t(kc) * 3 + size_t(c)] += vr[c];
                                t_az[tp][size_t(kc) * 3 + size_t(c)] += vt[c];
                              }
                            }
                          });
      }
    }
    for (int tp = 0; tp < o.phi_bins; tp++) {
      float *row = &t.values[(size_t(tt) * size_t(o.phi_bins) + size_t(tp)) * size_t(stride)];
      const std::vector<double> &Ap = A[size_t(tp)], &yp = y[size_t(tp)];
      auto piece = [&](size_t i, int k, int c) { return Ap[(i * size_t(nv) + size_t(k)) * 3 + size_t(c)]; };
      /* 1. The joint fit per channel: tau and the reflection's relative density b_k / mean. */
      std::vector<double> nu_joint(size_t(na), 0.0);
      int channels = 0;
      for (int c = 0; c < 3; c++) {
        Eigen::VectorXd E = Eigen::VectorXd::Zero(nv);
        for (size_t i = 0; i < n_cells; i++) {
          for (int k = 0; k < nv; k++) {
            E[k] += piece(i, k, c);
          }
        }
        /* Pieces the lobe hardly reaches are left out of the fit. */
        const double e_max = E.head(na).maxCoeff();
        std::vector<int> used;
        for (int k = 0; k < nv; k++) {
          if (E[k] > 1e-3 * e_max && e_max > 0 && (k < na || o.fit_tt)) {
            used.push_back(k);
          }
        }
        if (used.empty()) {
          continue;
        }
        Eigen::MatrixXd G = Eigen::MatrixXd::Zero(long(used.size()), long(used.size()));
        Eigen::VectorXd h = Eigen::VectorXd::Zero(long(used.size()));
        for (size_t i = 0; i < n_cells; i++) {
          for (size_t u = 0; u < used.size(); u++) {
            const double au = piece(i, used[u], c);
            h[long(u)] += au * yp[i * 3 + size_t(c)];
            for (size_t v = 0; v < used.size(); v++) {
              G(long(u), long(v)) += au * piece(i, used[v], c);
            }
          }
        }
        const Eigen::VectorXd x = nonnegative_least_squares(G, h);
        double e_R = 0, e_TT = 0, e_reached = 0;
        std::vector<double> bk(size_t(na), -1.0);
        for (size_t u = 0; u < used.size(); u++) {
          if (used[u] == na) {
            e_TT = x[long(u)] * E[na];
          }
          else {
            bk[size_t(used[u])] = x[long(u)];
            e_R += x[long(u)] * E[used[u]];
            e_reached += E[used[u]];
          }
        }
        row[na + c] = e_R + e_TT > 0 ? float(e_TT / (e_R + e_TT)) : 0.0f;
        if (e_R > 0) {
          for (int k = 0; k < na; k++) {
            nu_joint[size_t(k)] += bk[size_t(k)] >= 0 ? bk[size_t(k)] / (e_R / e_reached) : 1.0;
          }
          channels++;
        }
      }
      /* 2. The marginal ratio: what the map holds beyond the TT part against the reflection part, per phi~_o
       * bin of the map bins' centres (binning effects cancel in it). */
      std::vector<double> target(size_t(na), 0.0), lobe(size_t(na), 0.0), nu_ratio(size_t(na), 1.0);
      double lmax = 0, tsum = 0, lsum = 0;
      for (int k = 0; k < na; k++) {
        for (int c = 0; c < 3; c++) {
          const size_t i = size_t(k) * 3 + size_t(c);
          target[size_t(k)] += y_az[size_t(tp)][i] - row[na + c] * t_az[size_t(tp)][i];
          lobe[size_t(k)] += (1.0 - row[na + c]) * r_az[size_t(tp)][i];
        }
        lmax = std::max(lmax, lobe[size_t(k)]);
        tsum += target[size_t(k)];
        lsum += lobe[size_t(k)];
      }
      const double mean = lsum > 0 && tsum > 0 ? tsum / lsum : 1.0;
      for (int k = 0; k < na; k++) {
        /* A bin the lobe hardly reaches carries no information about the shape: the row's mean there. */
        nu_ratio[size_t(k)] = lobe[size_t(k)] > 1e-3 * lmax && lmax > 0 ? target[size_t(k)] / lobe[size_t(k)] / mean : 1.0;
      }
      /* 3. Of the two, the one whose lobe is closer to the map over the pooled cells (energy-weighted L1,
       * totals matched per channel as the calibration will): the joint fit sees every sample's own azimuth,
       * the ratio matches the map's marginals exactly; which is closer differs with the incidence. */
      /* Relative to uniform: mean 1, within kMaxDensityRatio either way (clamping moves the mean, so
       * three rounds of rescaling and clamping, then a last rescale). */
      auto normalised = [&](std::vector<double> v) {
        for (int pass = 0; pass < 4; pass++) {
          double sum = 0;
          for (double x : v) {
            sum += x;
          }
          for (double &x : v) {
            x = pass == 3 ? x * (na / sum)
                          : sum > 0 ? std::clamp(x * na / sum, 1.0 / kMaxDensityRatio, kMaxDensityRatio) : 1.0;
          }
        }
        return v;
      };
      auto l1_of = [&](const std::vector<double> &a) {
        double err = 0;
        for (int c = 0; c < 3; c++) {
          std::vector<double> pred(n_cells, 0.0);
          double psum = 0, ysum = 0;
          for (size_t i = 0; i < n_cells; i++) {
            for (int k = 0; k < na; k++) {
              pred[i] += (1.0 - row[na + c]) * a[size_t(k)] * piece(i, k, c);
            }
            pred[i] += row[na + c] * piece(i, na, c);
            psum += pred[i];
            ysum += yp[i * 3 + size_t(c)];
          }
          for (size_t i = 0; i < n_cells; i++) {
            err += std::abs((psum > 0 ? ysum / psum : 0.0) * pred[i] - yp[i * 3 + size_t(c)]);
          }
        }
        return err;
      };
      const std::vector<double> a_ratio = normalised(nu_ratio);
      const std::vector<double> a_joint = channels > 0 ? normalised(nu_joint) : a_ratio;
      const std::vector<double> &a = l1_of(a_joint) < l1_of(a_ratio) ? a_joint : a_ratio;
      for (int k = 0; k < na; k++) {
        row[k] = float(a[size_t(k)] / kPi);
      }
    }
  });
  return t;
}

}  // namespace neuralyarn::model
