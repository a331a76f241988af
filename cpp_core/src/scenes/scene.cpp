// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/scenes/scene.h"

#include <filesystem>
#include <stdexcept>

#include "neuralyarn/io.h"
#include "neuralyarn/scenes/cycles_xml.h"
#include "neuralyarn/scenes/scene_json.h"

namespace neuralyarn::scenes {

BounceLimits BounceLimits::blender_addon()
{
  BounceLimits b;
  b.total = 12, b.diffuse = 4, b.glossy = 4, b.transmission = 12, b.transparent = 64;
  return b;
}

size_t Scene::num_curve_keys() const
{
  size_t n = 0;
  for (const CurveObject &o : objects) {
    n += o.curves.points.size();
  }
  return n;
}

size_t Scene::num_curves() const
{
  size_t n = 0;
  for (const CurveObject &o : objects) {
    n += size_t(o.curves.num_curves());
  }
  return n;
}

std::string model_path_for(const std::string &model_path, const std::string &scene_path)
{
  const std::filesystem::path scene_dir = std::filesystem::absolute(scene_path).parent_path();
  const std::string relative =
      std::filesystem::absolute(model_path).lexically_normal().lexically_relative(scene_dir).string();
  return relative.empty() ? std::filesystem::absolute(model_path).string() : relative;
}

void check_scene_extension(const std::string &path)
{
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext != ".xml" && ext != ".json") {
    throw std::runtime_error("scene '" + path + "': the extension must be .xml (Cycles XML) or .json (the scene "
                             "description for Blender)");
  }
}

void write_scene(const Scene &scene, const std::string &path)
{
  check_scene_extension(path);
  const std::string text = std::filesystem::path(path).extension() == ".xml" ? cycles_xml(scene, path)
                                                                             : scene_json(scene, path).dump() + "\n";
  try {
    write_file_atomically(path, text, ""); /* a reader never sees half a scene */
  }
  catch (const std::runtime_error &e) {
    throw std::runtime_error("cannot write scene '" + path + "': " + e.what());
  }
}

}  // namespace neuralyarn::scenes
