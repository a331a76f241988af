// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/map_file.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string_view>

#include <nlohmann/json.hpp>

#include "neuralyarn/io.h"
#include "neuralyarn/kernel/exit_placement.h"
#include "neuralyarn/version.h"

namespace neuralyarn::rdm {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const char kMagic[8] = {'N', 'Y', 'R', 'D', 'M', '\r', '\n', '\x1a'};
constexpr size_t kAlign = 64;

uint64_t fnv1a(std::string_view bytes)
{
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : bytes) {
    h = (h ^ c) * 0x100000001b3ull;
  }
  return h;
}

std::string hex(uint64_t v)
{
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", (unsigned long long)v);
  return buf;
}

template<class T> void append_le(std::string &out, T v)
{
  for (size_t i = 0; i < sizeof(T); i++) {
    out.push_back(char((uint64_t(v) >> (8 * i)) & 0xff));
  }
}

template<class T> T read_le(const char *p)
{
  uint64_t v = 0;
  for (size_t i = 0; i < sizeof(T); i++) {
    v |= uint64_t(uint8_t(p[i])) << (8 * i);
  }
  return T(v);
}

/* The payload writer: arrays appended with their descriptors. (x86-64 and aarch64 are little endian;
 * a static_assert below refuses anything else rather than writing a wrong file.) */
struct Payload {
  std::string bytes;
  json arrays = json::array();
  template<class T> void add(const std::string &name, const std::string &dtype, const std::vector<T> &v,
                             const std::vector<size_t> &shape)
  {
    while (bytes.size() % kAlign) {
      bytes.push_back('\0');
    }
    json d;
    d["name"] = name;
    d["dtype"] = dtype;
    d["shape"] = shape;
    d["offset"] = bytes.size();
    d["bytes"] = v.size() * sizeof(T);
    arrays.push_back(d);
    bytes.append(reinterpret_cast<const char *>(v.data()), v.size() * sizeof(T));
  }
};

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "map files are little endian");

json stats_json(const GatherStats &s)
{
  json j;
  j["paths"] = s.paths;
  j["seconds"] = s.seconds;
  j["seconds_tracing"] = s.seconds_tracing;
  j["paths_per_second"] = s.paths_per_second();
  j["energy_T"] = {s.energy_T[0], s.energy_T[1], s.energy_T[2]};
  j["energy_R"] = {s.energy_R[0], s.energy_R[1], s.energy_R[2]};
  j["energy_M"] = {s.energy_M[0], s.energy_M[1], s.energy_M[2]};
  j["absorbed"] = {s.absorbed[0], s.absorbed[1], s.absorbed[2]};
  j["lost"] = {s.lost[0], s.lost[1], s.lost[2]};
  j["energy_balance"] = {s.balance[0], s.balance[1], s.balance[2]};
  j["energy_balance_se"] = {s.balance_se[0], s.balance_se[1], s.balance_se[2]};
  j["paths_T"] = s.paths_T;
  j["paths_R"] = s.paths_R;
  j["paths_M"] = s.paths_M;
  j["paths_terminated"] = s.paths_terminated;
  j["paths_truncated"] = s.paths_truncated;
  j["paths_past_ends"] = s.paths_past_ends;
  j["mean_events"] = s.mean_events;
  j["p95_events"] = s.p95_events;
  j["max_events"] = s.max_events_seen;
  j["slab_crossings"] = s.slab_crossings;
  j["invalid_weights"] = s.invalid_weights;
  j["mean_displacement_R"] = s.mean_displacement;
  j["p95_displacement_R"] = s.p95_displacement;
  j["mean_displacement_M_R"] = s.mean_displacement_M;
  j["p95_displacement_M_R"] = s.p95_displacement_M;
  /* Signed, per band of |cos(w_i, axis)| (D72); the unsigned pooled keys without "_bands" were D68's. */
  j["axial_exit_reflected_bands_R"] = s.axial_exit_reflected;
  j["axial_exit_through_bands_R"] = s.axial_exit_through;
  j["mean_axial_exit_reflected_bands_R"] = s.mean_axial_exit_reflected;
  j["mean_axial_exit_through_bands_R"] = s.mean_axial_exit_through;
  /* Where around the ply the light came in, per band and row of the exit's h (D73); none in maps read from an older
   * file and written again. */
  if (!s.entry_h_through.empty()) {
    j["entry_h_reflected_bands_rows"] = s.entry_h_reflected;
    j["entry_h_through_bands_rows"] = s.entry_h_through;
  }
  /* The path-length distribution, trimmed after its last non-empty bin. */
  size_t last = 0;
  for (size_t i = 0; i < s.events_histogram.size(); i++) {
    if (s.events_histogram[i]) {
      last = i + 1;
    }
  }
  j["events_histogram"] = std::vector<uint64_t>(s.events_histogram.begin(), s.events_histogram.begin() + last);
  return j;
}

[[noreturn]] void fail(const std::string &path, const std::string &what)
{
  throw MapFileError("map file '" + path + "': " + what);
}

}  // namespace

void save_maps(const RdmMaps &maps, const std::string &path)
{
  const MapResolution &b = maps.bins;
  const size_t ti = size_t(b.theta_i), pi = size_t(b.phi_i), to = size_t(b.theta_o), po = size_t(b.phi_o);
  Payload pl;
  pl.add("count", "u64", maps.count, {ti, pi});
  pl.add("p_t", "f32", maps.p_t, {ti, pi});
  pl.add("exit_energy", "f64", maps.exit_energy, {ti, pi, 3});
  pl.add("absorbed", "f64", maps.absorbed, {ti, pi, 3});
  pl.add("r", "f32", maps.r, {ti, pi, to, po, 3});
  pl.add("m", "f32", maps.m, {ti, pi, to, po, 3});
  if (!maps.r_se.empty()) {
    pl.add("p_t_se", "f32", maps.p_t_se, {ti, pi});
    pl.add("r_se", "f32", maps.r_se, {ti, pi, to, po, 3});
    pl.add("m_se", "f32", maps.m_se, {ti, pi, to, po, 3});
  }

  json h;
  h["format"] = "neuralyarn-rdm";
  const uint32_t version = maps.structure.is_yarn() ? kMapFileVersionYarn : kMapFileVersion;
  h["version"] = version;
  h["code_version"] = std::string(kVersion) + "+" + kGitRevision;
  h["created"] = utc_now();
  h["preset"] = preset_to_json(maps.preset);
  h["geometry"] = {{"R", 1.0}, {"fiber_radius", maps.fiber_radius}, {"slab_length", maps.slab_length},
                   {"chord_sagitta_fiber_radii", maps.sagitta}, {"packing_seed", maps.packing_seed}, {"layouts", maps.layouts},
                   {"mirror_pair", true}};
  h["gather"] = {{"paths", maps.paths}, {"seed", maps.seed}, {"symmetrized", maps.symmetrized},
                 {"incident_sampling", "stratified: equal paths per incident bin, uniform solid angle within"}};
  h["bins"] = {{"theta_i", b.theta_i}, {"phi_i", b.phi_i}, {"theta_o", b.theta_o}, {"phi_o", b.phi_o},
               {"theta_i_range_deg", {0, 90}}, {"theta_o_range_deg", {0, 180}}, {"phi_range_deg", {-180, 180}}};
  h["definitions"] = {
      {"angles", "entry frame x = ply axis, z = outward normal, y = z cross x; theta = acos(z) from the "
                 "normal, phi = atan2(y, x); w_i points away from the ply (toward the light)"},
      {"p_t", "fraction of paths of the incident bin that leave without any fiber event"},
      {"r", "f |cos theta_o| per outgoing solid angle of paths with exactly one fiber event leaving with "
            "w_o.n > 0: sum of weights / paths of the incident bin / solid angle of the outgoing bin"},
      {"m", "the same for all other scattered paths"},
      {"exit_energy", "mean exit throughput per path of the incident bin (T + R + M)"},
      {"absorbed", "mean expected absorbed energy per path of the incident bin"}};
  if (maps.structure.is_yarn()) {
    h["structure"] = geometry::structure_to_json(maps.structure);
  }
  if (!maps.intersector.empty()) {
    h["geometry"]["intersector"] = maps.intersector;
  }
  if (maps.bend_sectors > 0) {
    h["geometry"]["bend"] = {{"radius", maps.bend_radius}, {"sector", maps.bend_sector}, {"sectors", maps.bend_sectors}};
  }
  h["summary"] = stats_json(maps.stats);
  h["arrays"] = pl.arrays;
  h["payload_bytes"] = pl.bytes.size();
  h["payload_fnv1a64"] = hex(fnv1a(pl.bytes));
  const std::string header = h.dump(1);

  std::string head(kMagic, 8);
  append_le<uint32_t>(head, version);
  append_le<uint64_t>(head, header.size());
  head += header;

  try {
    write_file_atomically(path, head, pl.bytes);
  }
  catch (const std::runtime_error &e) {
    fail(path, e.what());
  }
}

namespace {

/* A map file's parts: the format version, the parsed header and a view of the payload (the bulk of the
 * file, 192 MB at paper resolution: not copied). Checks the magic, the version and the header's length. */
struct Container {
  uint32_t version = 0;
  json header;
  std::string_view payload;
};

Container open_container(const std::string &path, const std::string &data)
{
  if (data.size() < 20 || std::memcmp(data.data(), kMagic, 8) != 0) {
    fail(path, "not a neuralyarn RDM file (bad magic; was it transferred in text mode or truncated?)");
  }
  Container c;
  c.version = read_le<uint32_t>(data.data() + 8);
  if (c.version != kMapFileVersion && c.version != kMapFileVersionYarn) {
    fail(path, "format version " + std::to_string(c.version) + " is not supported (this build reads versions " +
                   std::to_string(kMapFileVersion) + " and " + std::to_string(kMapFileVersionYarn) + ")");
  }
  const uint64_t hlen = read_le<uint64_t>(data.data() + 12);
  if (hlen > data.size() - 20) {
    fail(path, "truncated: header of " + std::to_string(hlen) + " bytes, file has " + std::to_string(data.size()));
  }
  try {
    c.header = json::parse(data.substr(20, hlen));
  }
  catch (const json::exception &e) {
    fail(path, std::string("corrupt header: ") + e.what());
  }
  c.payload = std::string_view(data).substr(20 + hlen);
  return c;
}

/* The header's format, and the payload against the header's length and hash. */
void check_payload(const std::string &path, const json &h, std::string_view payload)
{
  if (h.at("format").get<std::string>() != "neuralyarn-rdm") {
    fail(path, "header format is not 'neuralyarn-rdm'");
  }
  if (h.at("payload_bytes").get<uint64_t>() != payload.size()) {
    fail(path, "truncated or padded: payload is " + std::to_string(payload.size()) + " bytes, header says " +
                   std::to_string(h.at("payload_bytes").get<uint64_t>()));
  }
  if (h.at("payload_fnv1a64").get<std::string>() != hex(fnv1a(payload))) {
    fail(path, "corrupt: payload hash mismatch");
  }
}

/* The header's bins, fiber, structure, gather and geometry. */
void read_description(const std::string &path, const json &h, uint32_t version, RdmMaps &maps)
{
  const json &b = h.at("bins");
  maps.bins.theta_i = b.at("theta_i").get<int>();
  maps.bins.phi_i = b.at("phi_i").get<int>();
  maps.bins.theta_o = b.at("theta_o").get<int>();
  maps.bins.phi_o = b.at("phi_o").get<int>();
  if (maps.bins.theta_i < 1 || maps.bins.phi_i < 1 || maps.bins.theta_o < 1 || maps.bins.phi_o < 1 ||
      maps.bins.theta_i > 100000 || maps.bins.phi_i > 100000 || maps.bins.theta_o > 100000 || maps.bins.phi_o > 100000) {
    fail(path, "invalid bin counts in header");
  }
  maps.preset = preset_from_json(h.at("preset"), "map");
  if (version == kMapFileVersionYarn) {
    maps.structure = geometry::structure_from_json(h.at("structure"));
  }
  else if (h.contains("structure")) {
    fail(path, "a version 1 file with a yarn structure (version 2 holds yarns)");
  }
  maps.seed = h.at("gather").at("seed").get<uint64_t>();
  maps.paths = h.at("gather").at("paths").get<uint64_t>();
  maps.symmetrized = h.at("gather").at("symmetrized").get<bool>();
  maps.packing_seed = h.at("geometry").at("packing_seed").get<uint64_t>();
  maps.layouts = h.at("geometry").value("layouts", 1); /* files before D42: one cross-section */
  if (maps.layouts < 1) {
    fail(path, "geometry.layouts must be at least 1 cross-section");
  }
  maps.fiber_radius = h.at("geometry").at("fiber_radius").get<double>();
  maps.slab_length = h.at("geometry").at("slab_length").get<double>();
  maps.sagitta = h.at("geometry").at("chord_sagitta_fiber_radii").get<double>();
  maps.intersector = h.at("geometry").value("intersector", ""); /* yarn maps before D66: Embree's */
  if (h.at("geometry").contains("bend")) { /* a bent ply's (D75; before D76 unrecorded) */
    const json &b = h.at("geometry").at("bend");
    maps.bend_radius = b.at("radius").get<double>();
    maps.bend_sector = b.at("sector").get<int>();
    maps.bend_sectors = b.at("sectors").get<int>();
    if (!std::isfinite(maps.bend_radius) || maps.bend_radius < 0.0 || maps.bend_sectors < 1 || maps.bend_sector < 0 ||
        maps.bend_sector >= maps.bend_sectors) {
      fail(path, "geometry.bend needs a radius >= 0 and 0 <= sector < sectors");
    }
  }
}

/* The header's summary: what stats_json wrote (the parts a loaded map is asked for). */
void read_summary(const std::string &path, const json &s, GatherStats &st)
{
  st.paths = s.at("paths").get<uint64_t>();
  st.seconds = s.at("seconds").get<double>();
  for (int c = 0; c < 3; c++) {
    st.energy_T[c] = s.at("energy_T")[size_t(c)].get<double>();
    st.energy_R[c] = s.at("energy_R")[size_t(c)].get<double>();
    st.energy_M[c] = s.at("energy_M")[size_t(c)].get<double>();
    st.absorbed[c] = s.at("absorbed")[size_t(c)].get<double>();
    st.lost[c] = s.at("lost")[size_t(c)].get<double>();
  }
  st.mean_events = s.at("mean_events").get<double>();
  st.p95_events = s.at("p95_events").get<int>();
  st.events_histogram = s.at("events_histogram").get<std::vector<uint64_t>>();
  st.mean_displacement = s.at("mean_displacement_R").get<double>();
  st.p95_displacement = s.at("p95_displacement_R").get<double>();
  st.mean_displacement_M = s.at("mean_displacement_M_R").get<double>();
  st.p95_displacement_M = s.at("p95_displacement_M_R").get<double>();
  /* Measured so since D72: older files have none (D68's were pooled and unsigned: not what a model needs now). */
  if (s.contains("axial_exit_through_bands_R")) {
    st.axial_exit_reflected = s.at("axial_exit_reflected_bands_R").get<std::vector<double>>();
    st.axial_exit_through = s.at("axial_exit_through_bands_R").get<std::vector<double>>();
    st.mean_axial_exit_reflected = s.at("mean_axial_exit_reflected_bands_R").get<std::vector<double>>();
    st.mean_axial_exit_through = s.at("mean_axial_exit_through_bands_R").get<std::vector<double>>();
    const size_t nq = size_t(ny::kExitBands) * ny::kExitQuantiles;
    if (st.axial_exit_reflected.size() != nq || st.axial_exit_through.size() != nq ||
        st.mean_axial_exit_reflected.size() != size_t(ny::kExitBands) ||
        st.mean_axial_exit_through.size() != size_t(ny::kExitBands)) {
      fail(path, "summary: the axial exit offsets must hold " + std::to_string(ny::kExitBands) + " bands of " +
                     std::to_string(ny::kExitQuantiles) + " quantiles and " + std::to_string(ny::kExitBands) +
                     " means per side");
    }
  }
  /* Measured so since D73: older files have none (their models start paths on the line through the hit point). */
  if (s.contains("entry_h_through_bands_rows")) {
    st.entry_h_reflected = s.at("entry_h_reflected_bands_rows").get<std::vector<double>>();
    st.entry_h_through = s.at("entry_h_through_bands_rows").get<std::vector<double>>();
    const size_t nq = size_t(ny::kExitBands) * ny::kEntryRows * ny::kExitQuantiles;
    for (const std::vector<double> *q : {&st.entry_h_reflected, &st.entry_h_through}) {
      bool ok = q->size() == nq;
      for (size_t r = 0; ok && r < nq / ny::kExitQuantiles; r++) {
        float row[ny::kExitQuantiles];
        std::copy(q->begin() + ptrdiff_t(r * ny::kExitQuantiles), q->begin() + ptrdiff_t((r + 1) * ny::kExitQuantiles), row);
        ok = ny::entry_quantiles_check(row, ny::kExitQuantiles) == nullptr;
      }
      if (!ok) {
        fail(path, "summary: the entry's h must hold " + std::to_string(ny::kExitBands) + " bands of " +
                       std::to_string(ny::kEntryRows) + " rows of " + std::to_string(ny::kExitQuantiles) +
                       " non-decreasing quantiles in [-1, 1] per side");
      }
    }
  }
}

/* The payload's arrays, each checked against its descriptor and the bins. */
void read_arrays(const std::string &path, const json &h, std::string_view payload, RdmMaps &maps)
{
  const size_t n_in = maps.bins.incident();
  const size_t n_map = n_in * maps.bins.outgoing() * 3;
  auto find = [&](const std::string &name) -> const json * {
    for (const json &a : h.at("arrays")) {
      if (a.at("name").get<std::string>() == name) {
        return &a;
      }
    }
    return nullptr;
  };
  auto read_array = [&](const std::string &name, const std::string &dtype, size_t elems, size_t elem_size,
                        bool required, auto &out) {
    const json *a = find(name);
    if (!a) {
      if (required) {
        fail(path, "array '" + name + "' is missing");
      }
      return;
    }
    if (a->at("dtype").get<std::string>() != dtype) {
      fail(path, "array '" + name + "' has dtype " + a->at("dtype").get<std::string>() + ", expected " + dtype);
    }
    size_t prod = 1;
    for (const json &d : a->at("shape")) {
      prod *= d.get<size_t>();
    }
    const uint64_t off = a->at("offset").get<uint64_t>(), len = a->at("bytes").get<uint64_t>();
    if (prod != elems || len != elems * elem_size) {
      fail(path, "array '" + name + "' has the wrong shape for the header's bins");
    }
    if (off > payload.size() || len > payload.size() - off) {
      fail(path, "array '" + name + "' lies outside the payload");
    }
    out.resize(elems);
    std::memcpy(out.data(), payload.data() + off, len);
  };
  try {
    read_array("count", "u64", n_in, 8, true, maps.count);
    read_array("p_t", "f32", n_in, 4, true, maps.p_t);
    read_array("exit_energy", "f64", n_in * 3, 8, true, maps.exit_energy);
    read_array("absorbed", "f64", n_in * 3, 8, true, maps.absorbed);
    read_array("r", "f32", n_map, 4, true, maps.r);
    read_array("m", "f32", n_map, 4, true, maps.m);
    read_array("p_t_se", "f32", n_in, 4, false, maps.p_t_se);
    read_array("r_se", "f32", n_map, 4, false, maps.r_se);
    read_array("m_se", "f32", n_map, 4, false, maps.m_se);
  }
  catch (const MapFileError &) {
    throw;
  }
  catch (const std::exception &e) {
    fail(path, std::string("bad array descriptor: ") + e.what());
  }
}

/* Every estimate finite and non-negative. */
void check_values(const std::string &path, const RdmMaps &maps)
{
  auto check = [&](const auto &v, const char *name) {
    for (size_t i = 0; i < v.size(); i++) {
      if (!(std::isfinite(double(v[i])) && v[i] >= 0)) {
        fail(path, std::string("array '") + name + "' holds a negative or non-finite value at element " +
                       std::to_string(i));
      }
    }
  };
  check(maps.p_t, "p_t");
  check(maps.exit_energy, "exit_energy");
  check(maps.absorbed, "absorbed");
  check(maps.r, "r");
  check(maps.m, "m");
}

}  // namespace

RdmMaps load_maps(const std::string &path)
{
  std::string data;
  try {
    data = read_file(path);
  }
  catch (const std::runtime_error &e) {
    fail(path, e.what());
  }
  const Container c = open_container(path, data);
  RdmMaps maps;
  try {
    check_payload(path, c.header, c.payload);
    read_description(path, c.header, c.version, maps);
    read_summary(path, c.header.at("summary"), maps.stats);
  }
  catch (const MapFileError &) {
    throw;
  }
  catch (const std::exception &e) {
    fail(path, std::string("header is missing a key or has a wrong type: ") + e.what());
  }
  read_arrays(path, c.header, c.payload, maps);
  check_values(path, maps);
  return maps;
}

}  // namespace neuralyarn::rdm
