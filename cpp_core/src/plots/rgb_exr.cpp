// SPDX-License-Identifier: Apache-2.0
//
// An RGB float image as OpenEXR (OpenImageIO): the CLI's predicted images (cycles-scene --predict-image).
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

#include <OpenImageIO/imageio.h>

#include "neuralyarn/plots.h"

namespace neuralyarn {

void write_rgb_exr(const std::vector<float> &rgb, int width, int height, const std::string &path)
{
  if (!(width > 0 && height > 0) || rgb.size() != size_t(width) * size_t(height) * 3) {
    throw std::runtime_error("write_rgb_exr: " + std::to_string(rgb.size()) + " values for a " +
                             std::to_string(width) + " x " + std::to_string(height) + " RGB image");
  }
  /* Written under another name and moved into place: a reader never sees half a file (the process id keeps two
   * writers of one path apart; OpenImageIO picks the format by the extension). */
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid()) + ".exr";
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(tmp);
  if (!out) {
    throw std::runtime_error("cannot write " + path + ": " + OIIO::geterror());
  }
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::FLOAT);
  spec.attribute("compression", "zip");
  if (!out->open(tmp, spec) || !out->write_image(OIIO::TypeDesc::FLOAT, rgb.data()) || !out->close()) {
    const std::string why = out->geterror();
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot write " + path + ": " + why);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot write " + path + ": " + why);
  }
}

}  // namespace neuralyarn
