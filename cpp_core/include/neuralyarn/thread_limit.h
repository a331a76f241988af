// SPDX-License-Identifier: Apache-2.0
//
// The host's parallel loops (tbb::parallel_for) take a thread count, 0 meaning all cores.
#pragma once

#include <cstddef>
#include <memory>

#include <tbb/global_control.h>

namespace neuralyarn {

/* At most `threads` workers while the returned object lives (0: all cores, no limit). */
inline std::unique_ptr<tbb::global_control> thread_limit(int threads)
{
  return threads > 0 ? std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                             size_t(threads))
                     : nullptr;
}

}  // namespace neuralyarn
