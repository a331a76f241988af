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
NY_KERNEL_FN int mlp_param_count(int L, const int *widths)
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

NY_KERNEL_FN float mlp_apply_head(int head, float z)
{
  if (head == kMlpHeadSigmoid) {
    /* 1 / (1 + e^-z), written so that neither branch overflows. */
    if (z >= 0.0f) {
      return 1.0f / (1.0f + expf(-z));
    }
    const float e = expf(z);
    return e / (1.0f + e);
  }
  if (head == kMlpHeadExp) {
    return expf(fminf(z, kMlpMaxExpArgument));
  }
  return z;
}

/* Evaluates the network stored at `params` on `input` (w_0 floats) into `output` (w_L floats). Uses two
 * stack buffers of kMlpMaxWidth floats; no heap. */
NY_KERNEL_FN void mlp_forward(const float *params, const float *input, float *output)
{
  const int L = (int)params[0];
  int widths[kMlpMaxLayers + 1] = {0};
  for (int l = 0; l <= L; l++) {
    widths[l] = (int)params[1 + l];
  }
  const int head = (int)params[L + 2];
  const float *p = params + L + 3;

  float buf_a[kMlpMaxWidth], buf_b[kMlpMaxWidth];
  float *in = buf_a, *out = buf_b;
  for (int i = 0; i < widths[0]; i++) {
    in[i] = input[i];
  }
  for (int l = 0; l < L; l++) {
    const int n_in = widths[l], n_out = widths[l + 1];
    const float *W = p;
    const float *b = W + n_out * n_in;
    const float *a = b + n_out;
    const bool hidden = l < L - 1;
    float z[kMlpMaxWidth];
    for (int o = 0; o < n_out; o++) {
      z[o] = b[o];
    }
    for (int i = 0; i < n_in; i++) {
      const float x = in[i];
      const float *col = W + i * n_out;
      for (int o = 0; o < n_out; o++) {
        z[o] += col[o] * x;
      }
    }
    for (int o = 0; o < n_out; o++) {
      if (hidden) {
        out[o] = z[o] >= 0.0f ? z[o] : a[o] * z[o]; /* channel-wise PReLU */
      }
      else {
        output[o] = mlp_apply_head(head, z[o]);
      }
    }
    p = a + (hidden ? n_out : 0);
    float *t = in;
    in = out;
    out = t;
  }
}

}  // namespace ny
