// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/fiber_lobe_sampler.h"
#include "neuralyarn/units.h"

#include <algorithm>
#include <cmath>

namespace neuralyarn::rdm {

using ny::Rgb;
using ny::Vec3;

namespace {
constexpr double kHalfPiD = 0.5 * kPi;

/* 40-point Gauss-Legendre nodes on [-1, 1] by Newton on P_40 (computed once). */
struct GaussLegendre40 {
  double x[40], w[40];
  GaussLegendre40()
  {
    const int n = 40;
    for (int i = 0; i < n; i++) {
      double z = std::cos(kPi * (i + 0.75) / (n + 0.5));
      double dp = 0.0;
      for (int it = 0; it < 100; it++) {
        double p0 = 1.0, p1 = z;
        for (int k = 2; k <= n; k++) {
          const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
          p0 = p1;
          p1 = p2;
        }
        dp = n * (z * p1 - p0) / (z * z - 1.0);
        const double dz = p1 / dp;
        z -= dz;
        if (std::abs(dz) < 1e-16) {
          break;
        }
      }
      x[i] = z;
      w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
  }
};

const GaussLegendre40 &gl40()
{
  static const GaussLegendre40 rule;
  return rule;
}

/* integral_lo^hi phi((t - mu) / beta) / beta cos^2 t dt on panels of at most beta, 40 nodes each. */
double cos2_integral(double mu, double beta, double lo, double hi)
{
  const GaussLegendre40 &g = gl40();
  const int panels = std::max(1, int(std::ceil((hi - lo) / beta)));
  const double h = (hi - lo) / panels;
  double sum = 0.0;
  for (int p = 0; p < panels; p++) {
    const double mid = lo + (p + 0.5) * h;
    for (int i = 0; i < 40; i++) {
      const double t = mid + 0.5 * h * g.x[i];
      const double z = (t - mu) / beta;
      const double c = std::cos(t);
      sum += g.w[i] * std::exp(-0.5 * z * z) * c * c;
    }
  }
  return sum * 0.5 * h / (beta * std::sqrt(2.0 * kPi));
}
}  // namespace

double CosSquaredRatioTable::exact(double mu, double beta)
{
  const double lo = std::max(-kHalfPiD, mu - 12.0 * beta);
  const double hi = std::min(kHalfPiD, mu + 12.0 * beta);
  const double G = cos2_integral(mu, beta, lo, hi);
  const double mass = 0.5 * (std::erfc((-kHalfPiD - mu) / (beta * std::sqrt(2.0))) -
                             std::erfc((kHalfPiD - mu) / (beta * std::sqrt(2.0))));
  return mass / G;
}

CosSquaredRatioTable::CosSquaredRatioTable(double beta, int intervals) : intervals_(intervals)
{
  const double step = kHalfPiD / intervals;
  inv_step_ = float(1.0 / step);
  values_.resize(size_t(intervals) + 3);
  for (int i = -1; i <= intervals + 1; i++) {
    /* Guards: the function is even in mu, and beyond pi/2 the spline only needs a smooth continuation. */
    const double mu = std::min(std::abs(i * step), kHalfPiD);
    values_[size_t(i + 1)] = float(exact(mu, beta));
  }
  /* Continue linearly past pi/2 so the last interval's spline is not flattened. */
  values_[size_t(intervals) + 2] = 2.0f * values_[size_t(intervals) + 1] - values_[size_t(intervals)];
}

float CosSquaredRatioTable::operator()(float mu) const
{
  const float x = std::min(std::abs(mu) * inv_step_, float(intervals_));
  const int i = std::min(int(x), intervals_ - 1);
  const float t = x - float(i);
  const float p0 = values_[size_t(i)], p1 = values_[size_t(i) + 1], p2 = values_[size_t(i) + 2],
              p3 = values_[size_t(i) + 3];
  /* Catmull-Rom. */
  return p1 + 0.5f * t * (p2 - p0 + t * (2.0f * p0 - 5.0f * p1 + 4.0f * p2 - p3 + t * (3.0f * (p1 - p2) + p3 - p0)));
}

FiberLobeSampler::FiberLobeSampler(const ny::FiberBsdfParams &params, bool plain)
    : p_(params),
      plain_(plain),
      von_mises_TT_(ny::make_von_mises_proposal(1.0f / (params.gamma_TT * params.gamma_TT))),
      ratio_R_(params.beta_R),
      ratio_TT_(params.beta_TT)
{
}

}  // namespace neuralyarn::rdm
