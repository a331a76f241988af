// SPDX-License-Identifier: Apache-2.0
//
// Inference of the model's tiny MLPs (paper Sec. 3: T is 3-7-7-1 with a sigmoid head, M is 6-21-21-3 with
// an exp head; hidden layers use channel-wise PReLU) from one flat float array — the array the trainer
// writes into model files and the Cycles patch uploads into a lookup table, with the offset in the closure.
//
// Layout (all floats; integers stored exactly as floats):
//   [0]              L, the number of weight layers (>= 1)
//   [1 .. L + 1]     the widths w_0 (inputs) .. w_L (outputs), each in [1, kMlpMaxWidth]
//   [L + 2]          the head: 0 identity, 1 sigmoid, 2 exp
//   then per layer l = 0 .. L-1:
//       W_l          w_{l+1} x w_l, column-major (input-major: the w_{l+1} weights of input 0, then of
//                    input 1, ...), so the inner loop runs over outputs, contiguously and without a
//                    reduction: it vectorises without reassociating sums (docs/benchmarks.md, MLP)
//       b_l          w_{l+1}
//       a_l          w_{l+1} PReLU slopes, for hidden layers only (l < L - 1)
// mlp_param_count(L, widths) gives the total; the host validates an array before the kernel sees it.
#pragma once

#include "platform.h"

namespace ny {

constexpr int kMlpMaxWidth = 64;
constexpr int kMlpMaxLayers = 8;

enum MlpHead { kMlpHeadIdentity = 0, kMlpHeadSigmoid = 1, kMlpHeadExp = 2 };

/* Largest exp() argument of the exp head: exp(80) ~ 5.5e34 stays finite in float. */
constexpr float kMlpMaxExpArgument = 80.0f;

/* Number of floats of a network with L weight layers and widths[0..L]. */
NY_KERNEL_FN int mlp_param_count(int L, NY_PRIVATE const int *widths)
{
  int n = L + 3;
  for (int l = 0; l < L; l++) {
    n += widths[l + 1] * widths[l] + widths[l + 1];
    if (l < L - 1) {
      n += widths[l + 1];
    }
  }
  return n;
}

/* The exp head: e^z with z clamped to kMlpMaxExpArgument by a comparison, which is fminf's value (a NaN gives the
 * bound) but stays inline, so that the host's loops over many outputs vectorise with fast_exp. */
NY_KERNEL_FN float mlp_exp_head(float z) { return fast_exp(z < kMlpMaxExpArgument ? z : kMlpMaxExpArgument); }

NY_KERNEL_FN float mlp_apply_head(int head, float z)
{
  if (head == kMlpHeadSigmoid) {
    /* 1 / (1 + e^-z), written so that neither branch overflows. */
    if (z >= 0.0f) {
      return 1.0f / (1.0f + fast_exp(-z));
    }
    const float e = fast_exp(z);
    return e / (1.0f + e);
  }
  if (head == kMlpHeadExp) {
    return mlp_exp_head(z);
  }
  return z;
}

/* A hidden layer's channel-wise PReLU (slope a below 0); the output layer passes z through. */
NY_KERNEL_FN float mlp_prelu(bool hidden, float a, float z) { return (hidden && z < 0.0f) ? a * z : z; }

/* One weight layer of n_in -> n_out: z = b + W x (summed over the inputs in order), then PReLU (hidden) or
 * nothing; `p` points at W and the pointer past this layer's parameters is returned. NI and NO, when not 0,
 * are the widths known at compile time (and n_in, n_out equal them): the loops unroll and z stays in
 * registers. With runtime widths the accumulators go through memory on every input and the loops' remainders
 * branch: the model's networks run much slower that way (docs/benchmarks.md, "Neural closure vs Principled
 * Hair"). One body for both, so both give the same result bit for bit (tests/cpp/test_mlp.cpp). */
template<int NI = 0, int NO = 0>
NY_KERNEL_FN NY_GLOBAL const float *mlp_layer(NY_GLOBAL const float *p, int n_in, int n_out, bool hidden,
                                             NY_PRIVATE const float *in, NY_PRIVATE float *out)
{
  const int ni = NI > 0 ? NI : n_in, no = NO > 0 ? NO : n_out;
  NY_GLOBAL const float *W = p;
  NY_GLOBAL const float *b = W + no * ni;
  NY_GLOBAL const float *a = b + no;
  float z[NO > 0 ? NO : kMlpMaxWidth];
  for (int o = 0; o < no; o++) {
    z[o] = b[o];
  }
  for (int i = 0; i < ni; i++) {
    const float x = in[i];
    NY_GLOBAL const float *col = W + i * no;
    NY_SIMD_LOOP
    for (int o = 0; o < no; o++) {
      z[o] += col[o] * x;
    }
  }
  for (int o = 0; o < no; o++) {
    out[o] = mlp_prelu(hidden, a[o], z[o]);
  }
  return a + (hidden ? no : 0);
}

/* Outputs of a compile-time hidden layer computed side by side: a block's width in floats (one AVX2 vector). */
constexpr int kMlpBlock = 8;

NY_KERNEL_FN constexpr int mlp_blocks(int n) { return (n + kMlpBlock - 1) / kMlpBlock; }

/* mlp_layer<NI, NO> for a hidden layer, its outputs in whole blocks of kMlpBlock: every output is summed and
 * activated exactly as there (bias, then the inputs in order, then mlp_prelu: the same result bit for bit), but
 * one loop of kMlpBlock lanes does a block of each input's column per statement. A width like 21 otherwise
 * leaves GCC at -O2 (Cycles' kernel) with a vector loop and its remainder per input, the accumulators going
 * through memory: the M network took 2.2x as long (docs/benchmarks.md, decisions D63). The padding lanes
 * read up to kMlpBlock - 1 floats past each column, the biases and the slopes, which lie inside the next
 * layer's parameters (mlp_forward_sized checks that the network is long enough); their outputs, past NO in
 * `out` (mlp_blocks(NO) * kMlpBlock floats), are never read. */
template<int NI, int NO>
NY_KERNEL_FN NY_GLOBAL const float *mlp_hidden_layer_blocks(NY_GLOBAL const float *p, NY_PRIVATE const float *in,
                                                           NY_PRIVATE float *out)
{
  constexpr int K = mlp_blocks(NO);
  static_assert(K >= 1 && K <= 4, "mlp_hidden_layer_blocks: up to 4 blocks");
  NY_GLOBAL const float *W = p;
  NY_GLOBAL const float *b = W + NO * NI;
  NY_GLOBAL const float *a = b + NO;
  float z[K * kMlpBlock];
  NY_SIMD_LOOP
  for (int o = 0; o < K * kMlpBlock; o++) {
    z[o] = b[o];
  }
  for (int i = 0; i < NI; i++) {
    const float x = in[i];
    NY_GLOBAL const float *col = W + i * NO;
    /* The blocks written out, not a loop over them: a loop inside the lanes' loop keeps GCC 12 from
     * vectorising it. */
    NY_SIMD_LOOP
    for (int o = 0; o < kMlpBlock; o++) {
      z[o] += col[o] * x;
      if (K > 1) {
        z[kMlpBlock + o] += col[kMlpBlock + o] * x;
      }
      if (K > 2) {
        z[2 * kMlpBlock + o] += col[2 * kMlpBlock + o] * x;
      }
      if (K > 3) {
        z[3 * kMlpBlock + o] += col[3 * kMlpBlock + o] * x;
      }
    }
  }
  NY_SIMD_LOOP
  for (int o = 0; o < K * kMlpBlock; o++) {
    out[o] = mlp_prelu(true, a[o], z[o]);
  }
  return a + NO;
}

/* A network of two hidden layers of width H with compile-time widths I-H-H-O (`p` past the header). */
template<int I, int H, int O>
NY_KERNEL_FN void mlp_forward_sized(NY_GLOBAL const float *p, int head, NY_PRIVATE const float *input,
                                    NY_PRIVATE float *output)
{
  /* The hidden layers' padding lanes read at most this far past the second one's slopes: into the output
   * layer's H * O weights and O biases. */
  static_assert(mlp_blocks(H) * kMlpBlock - H <= H * O + O, "mlp_forward_sized: network too short to pad");
  float h1[mlp_blocks(H) * kMlpBlock], h2[mlp_blocks(H) * kMlpBlock], z[O];
  /* A width of whole blocks (32) runs as fast or 6 % faster through mlp_layer's one loop (D63). */
  if (H % kMlpBlock != 0) {
    p = mlp_hidden_layer_blocks<I, H>(p, input, h1);
    p = mlp_hidden_layer_blocks<H, H>(p, h1, h2);
  }
  else {
    p = mlp_layer<I, H>(p, I, H, true, input, h1);
    p = mlp_layer<H, H>(p, H, H, true, h1, h2);
  }
  mlp_layer<H, O>(p, H, O, false, h2, z);
  for (int o = 0; o < O; o++) {
    output[o] = mlp_apply_head(head, z[o]);
  }
}

/* Evaluates the network stored at `params` on `input` (w_0 floats) into `output` (w_L floats), with runtime
 * widths. Uses stack buffers of kMlpMaxWidth floats; no heap. */
NY_KERNEL_FN void mlp_forward(NY_GLOBAL const float *params, NY_PRIVATE const float *input, NY_PRIVATE float *output)
{
  const int L = (int)params[0];
  const int head = (int)params[L + 2];
  NY_GLOBAL const float *p = params + L + 3;
  float buf_a[kMlpMaxWidth], buf_b[kMlpMaxWidth];
  NY_PRIVATE float *in = buf_a;
  NY_PRIVATE float *out = buf_b;
  for (int i = 0; i < (int)params[1]; i++) {
    in[i] = input[i];
  }
  for (int l = 0; l < L; l++) {
    const int n_in = (int)params[1 + l], n_out = (int)params[2 + l];
    p = mlp_layer(p, n_in, n_out, l < L - 1, in, out);
    NY_PRIVATE float *t = in;
    in = out;
    out = t;
  }
  for (int o = 0; o < (int)params[1 + L]; o++) {
    output[o] = mlp_apply_head(head, in[o]);
  }
}

/* The shapes the trainer makes, by input and output width: I-H-H-O with the hidden widths H it uses
 * (3-7-7-1 for T and rho_R, 3-7-7-3 for an RGB rho_R, decisions D65; 6-21-21-3, and 6-32-32-3 since D22, for M;
 * 6-H-H-6 for a two-sided M, D45), chosen by overloading on MlpIO<I, O> (not `if constexpr` nor a specialised
 * static member, which some kernel languages or Cycles' NY_KERNEL_FN do not take). Returns false for any other
 * shape. */
template<int I, int O> struct MlpIO {
};

template<int I, int O>
NY_KERNEL_FN bool mlp_forward_trainer_shape(MlpIO<I, O>, NY_GLOBAL const float *, int, int, NY_PRIVATE const float *,
                                            NY_PRIVATE float *)
{
  return false;
}

/* T and rho_R: 3 -> 1, or an RGB rho_R 3 -> 3 (decisions D65). */
template<int O>
NY_KERNEL_FN bool mlp_forward_trainer_shape(MlpIO<3, O>, NY_GLOBAL const float *p, int H, int head,
                                            NY_PRIVATE const float *input, NY_PRIVATE float *output)
{
  if (H != 7) {
    return false;
  }
  mlp_forward_sized<3, 7, O>(p, head, input, output);
  return true;
}

/* M: 6 -> 3, or 6 -> 6 two-sided (the flat array's check admits no other output width). */
template<int O>
NY_KERNEL_FN bool mlp_forward_trainer_shape(MlpIO<6, O>, NY_GLOBAL const float *p, int H, int head,
                                            NY_PRIVATE const float *input, NY_PRIVATE float *output)
{
  if (H == 21) {
    mlp_forward_sized<6, 21, O>(p, head, input, output);
    return true;
  }
  if (H == 32) {
    mlp_forward_sized<6, 32, O>(p, head, input, output);
    return true;
  }
  return false;
}

/* H when the network at `params` is I-H-H-O (two hidden layers of one width, the trainer's form), else 0;
 * its layers then start at params + 6 and its head is params[5]. */
template<int I, int O>
NY_KERNEL_FN int mlp_two_hidden_width(NY_GLOBAL const float *params)
{
  return (params[0] == 3.0f && params[1] == (float)I && params[4] == (float)O && params[2] == params[3]) ?
             (int)params[2] :
             0;
}

/* mlp_forward() for a network known to map I inputs to O outputs (the flat array's validation checks it):
 * the trainer's shapes with compile-time widths, bit-identical to mlp_forward(); any other through
 * mlp_forward(). */
template<int I, int O>
NY_KERNEL_FN void mlp_forward_io(NY_GLOBAL const float *params, NY_PRIVATE const float *input, NY_PRIVATE float *output)
{
  const int H = mlp_two_hidden_width<I, O>(params);
  if (H > 0 && mlp_forward_trainer_shape(MlpIO<I, O>(), params + 6, H, (int)params[5], input, output)) {
    return;
  }
  mlp_forward(params, input, output);
}

}  // namespace ny
