// SPDX-License-Identifier: Apache-2.0
//
// The kernel headers in "device mode", compiled by clang with no system header at all (-nostdinc
// -nostdinc++): what a GPU build of the patched Cycles (CUDA, HIP, Metal, oneAPI) would see of them, as far
// as a host compiler can tell (issue 22 item 2), with the environment of device_environment.h. The functions
// below call every entry point the two closures use, as cycles_patch/ calls them, so that every template the
// kernel instantiates is checked.
//
// Compiled by CTest (tests/CMakeLists.txt, device.kernel_headers_compile): clang++-14 -fsyntax-only.

#include "device_environment.h"

#include "neuralyarn/kernel/bend.h"
#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/kernel/yarn_bsdf.h"

/* The neural yarn closure as cycles_patch/0002 calls it: the model from the lookup table, the lobes of w_i
 * (kept in the shading point's closure storage), eval with pdf, sample, and the shadow rays' P_T. The host
 * validated the array (yarn_flat_check, which device mode leaves out). */
float neural_yarn_closure(NY_GLOBAL const float *lookup_table, int offset, ny::Vec3 dPdu, ny::Vec3 N,
                          ny::Vec3 wi_world, ny::Vec3 wo_world, float u1, float u2, float u3)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(lookup_table + offset);
  ny::Frame f;
  ny::make_frame(dPdu, N, &f);
  const ny::Vec3 wi = ny::to_local(f, wi_world);
  const float P_T = ny::yarn_transmission_probability(p, wi);
  const ny::YarnLobes lobes = ny::yarn_lobes(p, wi);
  float pdf = 0.0f;
  const ny::Rgb v = ny::yarn_eval_pdf_lobes(p, lobes, ny::to_local(f, wo_world), &pdf);
  ny::YarnSample s;
  if (!ny::yarn_sample_lobes(p, lobes, u3, u1, u2, false, &s)) {
    return 0.0f;
  }
  return P_T + v.r + pdf + ny::to_world(f, s.wo).x + s.weight.g + s.pdf;
}

/* The bend at a hit on a thick curve (kernel/bend.h): the segment's four keys fetched into private memory, as
 * cycles_patch/0005 fetches them, the tangent and normal of the closure's frame. */
float neural_yarn_bend(NY_GLOBAL const float *keys, int first, float u, ny::Vec3 dPdu, ny::Vec3 N, float radius)
{
  ny::Vec3 P[4];
  for (int i = 0; i < 4; i++) {
    P[i] = ny::make_vec3(keys[4 * (first + i)], keys[4 * (first + i) + 1], keys[4 * (first + i) + 2]);
  }
  ny::Frame f;
  ny::make_frame(dPdu, N, &f);
  const ny::YarnBend b = ny::yarn_bend(ny::catmull_rom_curvature(P, u), ny::to_world(f, ny::make_vec3(1.0f, 0.0f, 0.0f)),
                                       ny::to_world(f, ny::make_vec3(0.0f, 0.0f, 1.0f)), radius);
  return b.c + b.s;
}

/* The Khungurn fiber closure as cycles_patch/0001 calls it: the lobes, eval, pdf, albedo and sample with
 * further random numbers from a generator (the shading point's LCG there). */
float fiber_closure(ny::Vec3 dPdu, ny::Vec3 N, ny::Vec3 wi_world, ny::Vec3 wo_world, float u1, float u2, float u3,
                    uint32_t *lcg)
{
  ny::FiberBsdfParams p;
  p.C_R = ny::make_rgb(0.04f, 0.087f, 0.087f);
  p.C_TT = ny::make_rgb(0.452f, 0.725f, 0.948f);
  p.beta_R = 0.126f;
  p.beta_TT = 0.175f;
  p.gamma_TT = 0.454f;
  ny::Frame f;
  ny::make_frame(dPdu, N, &f);
  const ny::Vec3 wi = ny::to_local(f, wi_world), wo = ny::to_local(f, wo_world);
  const ny::FiberLobes l = ny::fiber_lobes(p, wi, true);
  ny::Rgb e_R, e_TT;
  ny::fiber_energies(p, wi, &e_R, &e_TT);
  const float value = ny::fiber_eval_lobes(l, wo).r + ny::fiber_pdf_lobes(l, wo) + ny::fiber_albedo(l).g;
  auto next = [&]() {
    *lcg = *lcg * 1103515245u + 12345u;
    return float(*lcg >> 8) * (1.0f / 16777216.0f);
  };
  ny::Vec3 sampled;
  ny::Rgb weight;
  float pdf;
  if (!ny::fiber_sample_lobes(l, u1, u2, u3, next, &sampled, &weight, &pdf)) {
    return value;
  }
  return value + e_R.r + e_TT.b + ny::to_world(f, sampled).x + weight.g + pdf;
}
