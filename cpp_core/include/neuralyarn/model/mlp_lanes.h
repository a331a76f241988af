// SPDX-License-Identifier: Apache-2.0
//
// The kernel's networks (kernel/mlp.h) on L inputs at once, for the host's quadratures, which evaluate one
// network at thousands of directions per incident direction (model/calibration.h m_lobe_energy). The
// kernel's loop vectorises over a layer's outputs; here the loop over the L lanes vectorises, and a block of
// outputs stays in registers. Every lane sums in mlp_layer's order (bias, then the inputs in order, without
// fused multiply-adds: cpp_core builds with -ffp-contract=off), so each lane is bit for bit what
// ny::mlp_forward_io gives for that input alone (tests/cpp/test_mlp.cpp).
//
// Arrays are lane-minor: in[i * L + l] is input i of lane l, out[o * L + l] output o of lane l. The first S
// inputs may be shared by every lane (the M network's w_i in a quadrature over exits): they are passed once,
// and the first layer adds them to its bias before the lanes' own inputs, the order every lane sums in anyway.
#pragma once

#include "neuralyarn/kernel/mlp.h"

namespace neuralyarn::model {

/* One weight layer NI -> NO of the flat layout at `p` (W input-major, b, PReLU slopes when hidden) on L
 * lanes, its first S inputs `shared` by every lane and the others lane-minor in `in`; returns the pointer past
 * the layer's parameters. */
template<int NI, int NO, int L, int S = 0>
const float *mlp_layer_lanes(const float *p, bool hidden, const float *shared, const float *in, float *out)
{
  const float *W = p;
  const float *b = W + NO * NI;
  const float *a = b + NO;
  /* Outputs per block: as many accumulator vectors as hide the adds' latency without spilling. */
  constexpr int B = NO % 7 == 0 ? 7 : NO % 4 == 0 ? 4 : NO % 3 == 0 ? 3 : 1;
  for (int ob = 0; ob < NO; ob += B) {
    float z[B][L];
    for (int k = 0; k < B; k++) {
      float z0 = b[ob + k];
      for (int i = 0; i < S; i++) {
        z0 += W[i * NO + ob + k] * shared[i];
      }
      NY_SIMD_LOOP
      for (int l = 0; l < L; l++) {
        z[k][l] = z0;
      }
    }
    for (int i = S; i < NI; i++) {
      const float *x = in + (i - S) * L;
      for (int k = 0; k < B; k++) {
        const float w = W[i * NO + ob + k];
        NY_SIMD_LOOP
        for (int l = 0; l < L; l++) {
          z[k][l] += w * x[l];
        }
      }
    }
    for (int k = 0; k < B; k++) {
      const float slope = a[ob + k];
      NY_SIMD_LOOP
      for (int l = 0; l < L; l++) {
        out[(ob + k) * L + l] = ny::mlp_prelu(hidden, slope, z[k][l]);
      }
    }
  }
  return a + (hidden ? NO : 0);
}

/* An I-H-H-O network (`p` past the header) on L lanes, head included; the first S inputs `shared`. */
template<int I, int H, int O, int L, int S = 0>
void mlp_forward_sized_lanes(const float *p, int head, const float *shared, const float *in, float *out)
{
  float h1[H * L], h2[H * L], z[O * L];
  p = mlp_layer_lanes<I, H, L, S>(p, true, shared, in, h1);
  p = mlp_layer_lanes<H, H, L>(p, true, nullptr, h1, h2);
  mlp_layer_lanes<H, O, L>(p, false, nullptr, h2, z);
  if (head == ny::kMlpHeadExp) {
    /* The head outside the loop, so that it vectorises: the quadratures spend much of their time here. */
    NY_SIMD_LOOP
    for (int j = 0; j < O * L; j++) {
      out[j] = ny::mlp_exp_head(z[j]);
    }
    return;
  }
  for (int j = 0; j < O * L; j++) {
    out[j] = ny::mlp_apply_head(head, z[j]);
  }
}

/* ny::mlp_forward_io<I, O> on L lanes whose first S inputs are `shared`: the trainer's shapes (3-7-7-1,
 * 6-21-21-3, 6-32-32-3, 6-21-21-6, 6-32-32-6) vectorised over the lanes, any other lane by lane through
 * mlp_forward_io. */
template<int I, int O, int L, int S = 0>
void mlp_forward_io_lanes(const float *params, const float *shared, const float *in, float *out)
{
  static_assert(0 <= S && S <= I, "the shared inputs are among the inputs");
  const int H = ny::mlp_two_hidden_width<I, O>(params), head = H > 0 ? int(params[5]) : 0;
  if constexpr (I == 3 && O == 1) {
    if (H == 7) {
      return mlp_forward_sized_lanes<3, 7, 1, L, S>(params + 6, head, shared, in, out);
    }
  }
  if constexpr (I == 6 && (O == 3 || O == 6)) {
    if (H == 21) {
      return mlp_forward_sized_lanes<6, 21, O, L, S>(params + 6, head, shared, in, out);
    }
    if (H == 32) {
      return mlp_forward_sized_lanes<6, 32, O, L, S>(params + 6, head, shared, in, out);
    }
  }
  for (int l = 0; l < L; l++) {
    float x[I], y[O];
    for (int i = 0; i < I; i++) {
      x[i] = i < S ? shared[i] : in[(i - S) * L + l];
    }
    ny::mlp_forward_io<I, O>(params, x, y);
    for (int o = 0; o < O; o++) {
      out[o * L + l] = y[o];
    }
  }
}

/* All inputs per lane. */
template<int I, int O, int L>
void mlp_forward_io_lanes(const float *params, const float *in, float *out)
{
  mlp_forward_io_lanes<I, O, L, 0>(params, nullptr, in, out);
}

}  // namespace neuralyarn::model
