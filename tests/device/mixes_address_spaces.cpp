// SPDX-License-Identifier: Apache-2.0
//
// The device-mode compile check must be able to fail: here the model's array (global memory) is handed to
// the network as its input, which is the thread's own data. CTest expects this file not to compile
// (device.mixed_address_spaces_refused, WILL_FAIL), so a check that stopped telling the spaces apart fails.

#include "device_environment.h"
#include "neuralyarn/kernel/mlp.h"

float network_on_the_model(NY_GLOBAL const float *model)
{
  float out[3];
  ny::mlp_forward(model, model + 64, out);
  return out[0];
}
