// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/scenes/cycles_xml.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>

#include "neuralyarn/model/surface_fit.h"

namespace neuralyarn::scenes {

namespace {

/* Text for an XML attribute value in double quotes. */
std::string xml_escape(const std::string &in)
{
  std::string out;
  out.reserve(in.size() + in.size() / 8);
  for (const char c : in) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\n': out += "&#10;"; break;
      default: out += c;
    }
  }
  return out;
}

const char *boolean(bool b)
{
  return b ? "true" : "false";
}

/* Camera, film, integrator, background and lights. */
void write_setting(std::ostringstream &x, const Scene &scene)
{
  const Camera &c = scene.camera;
  x << "<camera width=\"" << c.width << "\" height=\"" << c.height << "\" />\n";
  x << "<film filter_type=\"" << scene.film.filter_type << "\" filter_width=\"" << scene.film.filter_width << "\" />\n";
  /* The standalone camera looks along +z of its transform. */
  x << "<transform translate=\"" << c.position.x() << " " << c.position.y() << " " << c.position.z()
    << "\">\n  <camera type=\"perspective\" fov=\"" << c.fov << "\" />\n</transform>\n";
  const Integrator &in = scene.integrator;
  x << "<integrator max_bounce=\"" << in.bounces.total << "\" max_diffuse_bounce=\"" << in.bounces.diffuse
    << "\" max_glossy_bounce=\"" << in.bounces.glossy << "\" max_transmission_bounce=\"" << in.bounces.transmission
    << "\" transparent_max_bounce=\"" << in.bounces.transparent << "\" min_bounce=\"" << in.min_bounce
    << "\" sample_clamp_direct=\"" << in.sample_clamp_direct << "\" sample_clamp_indirect=\""
    << in.sample_clamp_indirect << "\" filter_glossy=\"" << in.filter_glossy << "\" light_sampling_threshold=\""
    << in.light_sampling_threshold << "\" use_adaptive_sampling=\"" << boolean(in.use_adaptive_sampling)
    << "\" seed=\"" << in.seed << "\" />\n";
  if (!scene.lighting.empty()) {
    x << "<!-- lights: " << scene.lighting << " (" << xml_escape(scene.lighting_description) << ") -->\n";
  }
  const Background &bg = scene.background;
  x << "<background>\n  <background name=\"bg\" strength=\"" << bg.strength << "\" color=\"" << bg.colour.r << " "
    << bg.colour.g << " " << bg.colour.b << "\" />\n  <connect from=\"bg background\" to=\"output surface\" />\n"
    << "</background>\n";
  if (scene.lights.empty()) {
    return;
  }
  x << "<shader name=\"lamp\">\n  <emission name=\"e\" color=\"1 1 1\" strength=\"1\" />\n"
    << "  <connect from=\"e emission\" to=\"output surface\" />\n</shader>\n";
  x << "<state shader=\"lamp\">\n";
  for (const Light &l : scene.lights) {
    const double w = l.strength;
    if (l.kind == Light::Kind::point) {
      /* Cycles 4.3 lights are placed by their own 3x4 transform (rows; translation in the last column); the
       * enclosing <transform> does not apply to them. */
      const Eigen::Vector3d &p = l.position;
      x << "  <light light_type=\"point\" tfm=\"1 0 0 " << p.x() << " 0 1 0 " << p.y() << " 0 0 1 " << p.z()
        << "\" strength=\"" << w << " " << w << " " << w << "\" size=\"" << l.radius << "\"";
    }
    else {
      /* A distant light shines along -Z of its transform (Light::get_dir() is minus the third column; the
       * kernel's direction toward the light is that column), so the third column is the unit vector toward
       * the light; the first two only orient its disc. Its angle is the full angular diameter in radians. */
      const Eigen::Vector3d z = l.direction, u = z.unitOrthogonal(), v = z.cross(u);
      x << "  <light light_type=\"distant\" tfm=\"";
      for (int r = 0; r < 3; r++) {
        /* (+ 0.0 writes -0 as 0) */
        x << (r ? " " : "") << u[r] + 0.0 << " " << v[r] + 0.0 << " " << z[r] + 0.0 << " 0";
      }
      x << "\" strength=\"" << w << " " << w << " " << w << "\" angle=\"" << l.angle << "\"";
    }
    x << " use_mis=\"" << boolean(l.use_mis) << "\" use_camera=\"" << boolean(l.visible_to_camera) << "\" />\n";
  }
  x << "</state>\n";
}

std::string colour_text(const Rgb3 &c)
{
  return std::to_string(c.r) + " " + std::to_string(c.g) + " " + std::to_string(c.b);
}

/* The surface level's closures (D44): each weighted by an RGB curve of x = kSurfaceFront |N.I| + kSurfaceBackStart
 * Backfacing (N faces the viewer on either face), summed. */
void write_cloth_surface(std::ostringstream &x, const Material &m)
{
  if (m.surface.empty()) {
    throw std::runtime_error("a cloth surface material needs closures");
  }
  x << "  <geometry name=\"g\" />\n"
    << "  <vector_math name=\"nv\" math_type=\"dot_product\" />\n"
    << "  <connect from=\"g normal\" to=\"nv vector1\" />\n  <connect from=\"g incoming\" to=\"nv vector2\" />\n"
    << "  <math name=\"cv\" math_type=\"absolute\" />\n  <connect from=\"nv value\" to=\"cv value1\" />\n"
    << "  <math name=\"bf\" math_type=\"multiply\" value2=\"" << model::kSurfaceBackStart << "\" />\n"
    << "  <connect from=\"g backfacing\" to=\"bf value1\" />\n"
    << "  <math name=\"x\" math_type=\"multiply_add\" value2=\"" << model::kSurfaceFront << "\" />\n"
    << "  <connect from=\"cv value\" to=\"x value1\" />\n  <connect from=\"bf value\" to=\"x value3\" />\n"
    << "  <combine_color name=\"xxx\" color_type=\"rgb\" />\n";
  for (const char *c : {"r", "g", "b"}) {
    x << "  <connect from=\"x value\" to=\"xxx " << c << "\" />\n";
  }
  std::string sum;
  for (size_t k = 0; k < m.surface.size(); k++) {
    const Material::SurfaceClosure &c = m.surface[k];
    const std::string w = "w" + std::to_string(k), b = "c" + std::to_string(k);
    x << "  <rgb_curves name=\"" << w << "\" fac=\"1\" min_x=\"0\" max_x=\"1\" curves=\"";
    for (size_t i = 0; i < c.weight.size(); i++) {
      x << (i ? " " : "") << c.weight[i][0] << " " << c.weight[i][1] << " " << c.weight[i][2];
    }
    x << "\" />\n  <connect from=\"xxx color\" to=\"" << w << " value\" />\n";
    if (c.closure == "ggx") {
      x << "  <glossy_bsdf name=\"" << b << "\" distribution=\"ggx\" roughness=\"" << std::sqrt(c.alpha) << "\" />\n";
    }
    else if (c.closure == "transparent" || c.closure == "diffuse" || c.closure == "translucent") {
      x << "  <" << c.closure << "_bsdf name=\"" << b << "\" />\n";
    }
    else {
      throw std::runtime_error("unknown surface closure '" + c.closure + "'");
    }
    x << "  <connect from=\"" << w << " value\" to=\"" << b << " color\" />\n";
    if (sum.empty()) {
      sum = b + " bsdf";
    }
    else {
      const std::string a = "a" + std::to_string(k);
      x << "  <add_closure name=\"" << a << "\" />\n  <connect from=\"" << sum << "\" to=\"" << a << " closure1\" />\n"
        << "  <connect from=\"" << b << " bsdf\" to=\"" << a << " closure2\" />\n";
      sum = a + " closure";
    }
  }
  x << "  <connect from=\"" << sum << "\" to=\"output surface\" />\n";
}

/* The <shader> of a material: Blender's node defaults where the XML reader's differ (its Principled BSDF has
 * specular 0, Blender's node 0.5). */
void write_shader(std::ostringstream &x, const std::string &shader, const Material &m, const std::string &scene_path)
{
  x << "<shader name=\"" << shader << "\">\n";
  switch (m.kind) {
    case Material::Kind::neural_yarn:
      x << "  <neural_yarn_bsdf name=\"y\" model=\"" << xml_escape(model_path_for(m.model_path, scene_path)) << "\""
        << (m.model_json.empty() ? std::string() : " model_json=\"" + xml_escape(m.model_json) + "\"") << " />\n"
        << "  <connect from=\"y bsdf\" to=\"output surface\" />\n";
      break;
    case Material::Kind::khungurn_fiber:
      x << "  <khungurn_fiber_bsdf name=\"f\" C_R=\"" << m.C_R[0] << " " << m.C_R[1] << " " << m.C_R[2]
        << "\" C_TT=\"" << m.C_TT[0] << " " << m.C_TT[1] << " " << m.C_TT[2] << "\" beta_R=\"" << m.beta_R
        << "\" beta_TT=\"" << m.beta_TT << "\" gamma_TT=\"" << m.gamma_TT << "\" />\n"
        << "  <connect from=\"f bsdf\" to=\"output surface\" />\n";
      break;
    case Material::Kind::principled_hair_chiang:
    case Material::Kind::principled_hair_huang: {
      /* Huang's default aspect ratio 0.85 flattens the fiber; a ply's cross-section is round. */
      const bool huang = m.kind == Material::Kind::principled_hair_huang;
      x << "  <principled_hair_bsdf name=\"b\" model=\"" << (huang ? "Huang" : "Chiang")
        << "\" parametrization=\"Direct coloring\" color=\"" << colour_text(m.colour) << "\""
        << (huang ? " aspect_ratio=\"1\"" : "") << " />\n"
        << "  <connect from=\"b bsdf\" to=\"output surface\" />\n";
      break;
    }
    case Material::Kind::sheen:
      x << "  <principled_bsdf name=\"b\" base_color=\"" << colour_text(m.colour)
        << "\" specular_ior_level=\"0.5\" sheen_weight=\"1\" sheen_tint=\"1 1 1\" />\n"
        << "  <connect from=\"b bsdf\" to=\"output surface\" />\n";
      break;
    case Material::Kind::diffuse:
      x << "  <diffuse_bsdf name=\"y\" color=\"" << m.colour.r << " " << m.colour.g << " " << m.colour.b << "\" />\n"
        << "  <connect from=\"y bsdf\" to=\"output surface\" />\n";
      break;
    case Material::Kind::cloth_surface:
      write_cloth_surface(x, m);
      break;
  }
  x << "</shader>\n";
}

/* The curves as one <hair> element (the XML reader takes one radius for all of them). */
void write_curves(std::ostringstream &x, const CurveObject &obj)
{
  const geometry::CurveSet &c = obj.curves;
  if (c.num_curves() == 0) {
    throw std::runtime_error("object '" + obj.name + "' has no curves");
  }
  for (const float r : c.radii) {
    if (r != c.radii[0]) {
      throw std::runtime_error("object '" + obj.name + "': Cycles XML takes one radius for all curves of a <hair>");
    }
  }
  x << "<state shader=\"" << obj.shader << "\">\n<hair nkeys=\"";
  for (int k = 0; k < c.num_curves(); k++) {
    x << (k ? " " : "") << c.offsets[size_t(k) + 1] - c.offsets[size_t(k)];
  }
  x << "\"\n  radius=\"" << c.radii[0] << "\"\n  P=\"";
  for (size_t i = 0; i < c.points.size(); i++) {
    const Eigen::Vector3f &p = c.points[i];
    x << (i ? " " : "") << p.x() << " " << p.y() << " " << p.z();
  }
  x << "\" />\n</state>\n";
}

/* The mesh as one <mesh> of triangles. */
void write_mesh(std::ostringstream &x, const MeshObject &obj)
{
  if (obj.vertices.empty() || obj.triangles.empty() || obj.triangles.size() % 3) {
    throw std::runtime_error("mesh '" + obj.name + "' has no triangles");
  }
  x << "<state shader=\"" << obj.shader << "\">\n<mesh P=\"";
  for (size_t i = 0; i < obj.vertices.size(); i++) {
    const Eigen::Vector3f &p = obj.vertices[i];
    x << (i ? " " : "") << p.x() << " " << p.y() << " " << p.z();
  }
  x << "\"\n  nverts=\"";
  for (size_t i = 0; i < obj.triangles.size() / 3; i++) {
    x << (i ? " 3" : "3");
  }
  x << "\"\n  verts=\"";
  for (size_t i = 0; i < obj.triangles.size(); i++) {
    x << (i ? " " : "") << obj.triangles[i];
  }
  x << "\" />\n</state>\n";
}

}  // namespace

std::string cycles_xml(const Scene &scene, const std::string &scene_path)
{
  std::ostringstream x;
  x.precision(7);
  x << "<?xml version=\"1.0\"?>\n<!-- neuralyarn: " << scene.title
    << " (generated by `neuralyarn cycles-scene`) -->\n<cycles>\n";
  write_setting(x, scene);
  for (const CurveObject &obj : scene.objects) {
    write_shader(x, obj.shader, obj.material, scene_path);
    write_curves(x, obj);
  }
  for (const MeshObject &obj : scene.meshes) {
    write_shader(x, obj.shader, obj.material, scene_path);
    write_mesh(x, obj);
  }
  x << "</cycles>\n";
  return x.str();
}

}  // namespace neuralyarn::scenes
