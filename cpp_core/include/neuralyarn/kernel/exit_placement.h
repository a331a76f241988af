// SPDX-License-Identifier: Apache-2.0
//
// Where along the ply the light scattered inside an aggregated ply leaves it (decisions D68, D72).
//
// The aggregated BSDF is a far-field function: a renderer evaluates it at the hit point and continues the path
// from there. Inside real fibers, light also travels along the ply (cotton: half of what goes through more than a
// ply radius, a tenth more than six), so a part of a ply in another ply's shadow still glows with light that
// entered where the ply is lit; a far-field BSDF leaves that part dark. The gather measures, energy-weighted at
// the levels below, how far along the axis the exits lie from where a renderer's ray from the entry point would
// leave (rdm::GatherStats::axial_exit_through, axial_exit_reflected: through the far side, on the entry side),
// signed (positive: further the way the light travelled along the axis; fibers scatter light on cones about
// their axes, so it keeps going the way it came) and per band of the light's direction cosine with the ply's
// axis (light along the axis travels far along it, light across it hardly, and both ways). A model carries
// those quantiles (model::NearField), and a renderer moves the origin of a path that leaves a neural yarn
// closure's ply by an offset drawn from those of its side and its direction, in ply radii along the curve,
// toward where the path goes: there the light it stands for came in.
//
// The quantiles become knots at the levels 0, the gather's nine and 1 (the ends extrapolated by the step next to
// them); between knots the inverse distribution is linear, and between the bands' centres the offsets are.
//
// Where around the ply the light came in (decisions D73): light enters a ply most where its surface faces the light,
// not on the line through the point a renderer shades. Seen along the light's direction, the ply's width runs
// across h in [-1, 1]; the gather measures, per side and band, the distribution of the entry's h given the exit's
// (rdm::GatherStats::entry_h_through, entry_h_reflected: kEntryRows rows of the exit's h, nine quantiles each of
// the entry's), and a renderer starts the path from the ply's face toward its direction at an h drawn from the row
// of the hit point's h (linear between rows and between bands, as the offsets are between bands).
#pragma once

#include "platform.h"

namespace ny {

/* Bands of |cos| between the light's direction and the ply's axis, of equal width; the gather's quantile levels
 * (rdm::GatherStats) per band, and the knots': 0, those nine, 1. */
constexpr int kExitBands = 5;
constexpr int kExitQuantiles = 9;
constexpr int kExitKnots = kExitQuantiles + 2;
/* The knots of one side: kExitKnots per band, band after band. */
constexpr int kExitSideSize = kExitBands * kExitKnots;
/* Knot k's level (a function, not a table: device code reads no namespace-scope arrays). */
NY_KERNEL_FN float exit_knot_level(int k)
{
  return k <= 0 ? 0.0f : k == 1 ? 0.01f : k == 2 ? 0.05f : k == 3 ? 0.1f : k == 4 ? 0.25f : k == 5 ? 0.5f :
         k == 6 ? 0.75f : k == 7 ? 0.9f : k == 8 ? 0.95f : k == 9 ? 0.99f : 1.0f;
}
/* Largest |quantile| a model may carry (ply radii). */
constexpr float kExitMaxOffset = 1000.0f;
static_assert(kExitBands >= 2, "exit_sample_offset interpolates between two bands");

/* The entry's h (decisions D73): rows of the exit's h across [-1, 1] (centres -0.9, -0.7, ..., 0.9), per band; a
 * side's entry knots, band after band, row after row; a side's block in a kernel array holds its size
 * (kExitSideSize, or kExitSideSizeWithEntry with the entry's knots after the offsets'), then the knots. */
constexpr int kEntryRows = 10;
constexpr int kEntrySideSize = kExitBands * kEntryRows * kExitKnots;
constexpr int kExitSideSizeWithEntry = kExitSideSize + kEntrySideSize;
static_assert(kEntryRows >= 2, "entry_sample_h interpolates between two rows");

#ifndef NY_KERNEL_DEVICE
/* Checks kExitQuantiles quantiles: `n` of them, each in [lo, hi] (NaN is not), non-decreasing. Returns null if they
 * are fine, else what is wrong: `count` or `range`, or that they decrease. */
inline const char *quantiles_check(const float *q, int n, float lo, float hi, const char *count, const char *range)
{
  if (n != kExitQuantiles) {
    return count;
  }
  for (int k = 0; k < n; k++) {
    if (!(q[k] >= lo && q[k] <= hi)) {
      return range;
    }
    if (k > 0 && !(q[k] >= q[k - 1])) {
      return "decreases: quantiles at higher levels must not be smaller";
    }
  }
  return nullptr;
}

/* Checks one band's quantiles (kExitQuantiles of them, signed ply radii): finite, within kExitMaxOffset,
 * non-decreasing. Returns null if they are fine, else what is wrong. */
inline const char *exit_quantiles_check(const float *q, int n)
{
  return quantiles_check(q, n, -kExitMaxOffset, kExitMaxOffset,
                         "must hold nine quantiles per band (at 1, 5, 10, 25, 50, 75, 90, 95 and 99 %)",
                         "holds a value that is not a finite number in [-1000, 1000] ply radii");
}

/* Up to `n` numbers of JSON array `a` into `out` (n + 1 floats: one more, if there are more, so that a check names
 * the count; a non-number as infinity, which every range check refuses); how many were read (0 for a non-array). */
template<class Json> int json_numbers(const Json &a, float *out, int n)
{
  int m = 0;
  if (a.is_array()) {
    for (const Json &v : a) {
      if (m > n) {
        break;
      }
      out[m++] = v.is_number() ? v.template get<float>() : NY_INFINITY;
    }
  }
  return m;
}

/* The knots (kExitKnots floats) of one band's checked quantiles: the first and the last stepped out by the
 * difference next to them (the 0-1 % and 99-100 % shares spread as the 1-5 % and 95-99 % ones are, so no
 * offset is unbounded). */
inline void exit_knots(const float *q, float *knots)
{
  for (int k = 0; k < kExitQuantiles; k++) {
    knots[k + 1] = q[k];
  }
  knots[0] = q[0] - (q[1] - q[0]);
  knots[kExitKnots - 1] = q[kExitQuantiles - 1] + (q[kExitQuantiles - 1] - q[kExitQuantiles - 2]);
}

/* A side's knots (kExitSideSize floats) from its checked quantiles (kExitBands x kExitQuantiles). */
inline void exit_side_knots(const float *q, float *knots)
{
  for (int b = 0; b < kExitBands; b++) {
    exit_knots(q + b * kExitQuantiles, knots + b * kExitKnots);
  }
}

/* Models from before D72 carry six quantiles of |offset| (at 25, 50, 75, 90, 95 and 99 %), pooled over every
 * incidence: the signed quantiles of the same offsets taken either way with equal chance, for every band. */
constexpr int kExitLegacyQuantiles = 6;
inline void exit_quantiles_from_magnitudes(const float *m, float *q)
{
  /* |offset| at level l: linear between (0, 0) and the six quantiles. */
  auto magnitude = [&](float l) {
    const float levels[kExitLegacyQuantiles + 1] = {0.0f, 0.25f, 0.5f, 0.75f, 0.9f, 0.95f, 0.99f};
    float prev = 0.0f;
    for (int k = 1; k <= kExitLegacyQuantiles; k++) {
      if (l <= levels[k]) {
        return prev + (m[k - 1] - prev) * ((l - levels[k - 1]) / (levels[k] - levels[k - 1]));
      }
      prev = m[k - 1];
    }
    return m[kExitLegacyQuantiles - 1];
  };
  /* The levels are symmetric about the median (exit_knot_level): the upper half, mirrored. */
  for (int k = kExitQuantiles / 2; k < kExitQuantiles; k++) {
    q[k] = magnitude(2.0f * exit_knot_level(k + 1) - 1.0f);
    q[kExitQuantiles - 1 - k] = -q[k];
  }
}

/* One side's quantiles (kExitBands x kExitQuantiles floats, band after band) from a model file's "near_field"
 * object, any JSON type with nlohmann::json's interface (the model reader's and Cycles' host's): its
 * "through_bands" or "reflected_bands" (`through` picks), else the pre-D72 "axial_exit_through" or
 * "axial_exit_reflected", converted for every band. Returns 1 when read, 0 when the entry side is absent, -1 when
 * the side is malformed or the far side (required) absent, with *problem what is wrong and *key the key it is
 * wrong in (null for an absent far side). */
template<class Json>
int exit_side_from_json(const Json &near_field, bool through, float *q, const char **key, const char **problem)
{
  const char *bands_key = through ? "through_bands" : "reflected_bands";
  const char *legacy_key = through ? "axial_exit_through" : "axial_exit_reflected";
  *problem = nullptr;
  float band[kExitQuantiles + 1];
  if (near_field.contains(bands_key)) {
    *key = bands_key;
    const Json &a = near_field[bands_key];
    if (!a.is_array() || int(a.size()) != kExitBands) {
      *problem = "must hold five bands (of |cos| between the light and the ply's axis: 0-0.2 ... 0.8-1)";
      return -1;
    }
    for (int b = 0; b < kExitBands; b++) {
      const int n = json_numbers(a[size_t(b)], band, kExitQuantiles);
      if ((*problem = exit_quantiles_check(band, n)) != nullptr) {
        return -1;
      }
      for (int k = 0; k < kExitQuantiles; k++) {
        q[b * kExitQuantiles + k] = band[k];
      }
    }
    return 1;
  }
  if (!near_field.contains(legacy_key)) {
    *key = nullptr;
    *problem = through ? "must hold 'through_bands' (or a model's from before D72: 'axial_exit_through')" : nullptr;
    return through ? -1 : 0;
  }
  *key = legacy_key;
  float m[kExitLegacyQuantiles + 1];
  const int n = json_numbers(near_field[legacy_key], m, kExitLegacyQuantiles);
  bool ok = n == kExitLegacyQuantiles;
  for (int k = 0; ok && k < n; k++) {
    ok = m[k] >= 0.0f && m[k] <= kExitMaxOffset && (k == 0 || m[k] >= m[k - 1]);
  }
  if (!ok) {
    *problem = "must hold six non-decreasing quantiles in [0, 1000] ply radii (at 25, 50, 75, 90, 95 and 99 %)";
    return -1;
  }
  exit_quantiles_from_magnitudes(m, band);
  for (int b = 0; b < kExitBands; b++) {
    for (int k = 0; k < kExitQuantiles; k++) {
      q[b * kExitQuantiles + k] = band[k];
    }
  }
  return 1;
}

/* Checks one row's quantiles of the entry's h (kExitQuantiles of them): in [-1, 1], non-decreasing. Returns null
 * if they are fine, else what is wrong. */
inline const char *entry_quantiles_check(const float *q, int n)
{
  return quantiles_check(q, n, -1.0f, 1.0f, "must hold nine quantiles per row (at 1, 5, 10, 25, 50, 75, 90, 95 and 99 %)",
                         "holds a value that is not a number in [-1, 1] (across the ply's width)");
}

/* A side's entry knots (kEntrySideSize floats) from its checked quantiles (kExitBands x kEntryRows x
 * kExitQuantiles): each row's as exit_knots, the stepped-out ends kept on the width. */
inline void entry_side_knots(const float *q, float *knots)
{
  for (int r = 0; r < kExitBands * kEntryRows; r++) {
    float *k = knots + r * kExitKnots;
    exit_knots(q + r * kExitQuantiles, k);
    k[0] = k[0] < -1.0f ? -1.0f : k[0];
    k[kExitKnots - 1] = k[kExitKnots - 1] > 1.0f ? 1.0f : k[kExitKnots - 1];
  }
}

/* One side's quantiles of the entry's h (kExitBands x kEntryRows x kExitQuantiles floats) from a model file's
 * "near_field" object: its "through_entry" or "reflected_entry" (`through` picks). Returns 1 when read, 0 when
 * absent (the path starts on the line through the hit point, as before D73), -1 when malformed, with *key and
 * *problem. */
template<class Json>
int entry_side_from_json(const Json &near_field, bool through, float *q, const char **key, const char **problem)
{
  *key = through ? "through_entry" : "reflected_entry";
  *problem = nullptr;
  if (!near_field.contains(*key)) {
    return 0;
  }
  const Json &a = near_field[*key];
  if (!a.is_array() || int(a.size()) != kExitBands) {
    *problem = "must hold five bands (of |cos| between the light and the ply's axis) of ten rows";
    return -1;
  }
  for (int b = 0; b < kExitBands; b++) {
    const Json &rows = a[size_t(b)];
    if (!rows.is_array() || int(rows.size()) != kEntryRows) {
      *problem = "must hold ten rows per band (of the leaving point's h across the width: -1 ... 1)";
      return -1;
    }
    for (int r = 0; r < kEntryRows; r++) {
      float row[kExitQuantiles + 1];
      if ((*problem = entry_quantiles_check(row, json_numbers(rows[size_t(r)], row, kExitQuantiles))) != nullptr) {
        return -1;
      }
      for (int k = 0; k < kExitQuantiles; k++) {
        q[(b * kEntryRows + r) * kExitQuantiles + k] = row[k];
      }
    }
  }
  return 1;
}

/* One side of a model file's "near_field": its offsets' quantiles into `q` (kExitBands x kExitQuantiles) as
 * exit_side_from_json, its entry h's into `e` (kExitBands x kEntryRows x kExitQuantiles) as entry_side_from_json,
 * *has_offsets and *has_entry whether it holds them; an entry h needs its side's offsets. Returns false with *key and
 * *problem when the side is malformed. */
template<class Json>
bool near_field_side_from_json(const Json &near_field, bool through, float *q, float *e, bool *has_offsets,
                               bool *has_entry, const char **key, const char **problem)
{
  const int got = exit_side_from_json(near_field, through, q, key, problem);
  if (got < 0) {
    return false;
  }
  const int entry = entry_side_from_json(near_field, through, e, key, problem);
  if (entry < 0) {
    return false;
  }
  if (entry > 0 && got == 0) {
    *problem = "needs the offsets of its side ('reflected_bands') as well"; /* the far side's are required */
    return false;
  }
  *has_offsets = got > 0;
  *has_entry = entry > 0;
  return true;
}

/* One side's block of a kernel array (at most 1 + kExitSideSizeWithEntry floats) from a model file's "near_field":
 * [0] for a side without offsets, else [its size, the offsets' knots, the entry's knots if it has them]. Returns
 * the floats written, or -1 with *key and *problem (near_field_side_from_json). */
template<class Json>
int exit_side_block_from_json(const Json &near_field, bool through, float *block, const char **key,
                              const char **problem)
{
  float q[kExitBands * kExitQuantiles], e[kExitBands * kEntryRows * kExitQuantiles];
  bool has_offsets = false, has_entry = false;
  if (!near_field_side_from_json(near_field, through, q, e, &has_offsets, &has_entry, key, problem)) {
    return -1;
  }
  if (!has_offsets) {
    block[0] = 0.0f;
    return 1;
  }
  exit_side_knots(q, block + 1);
  if (!has_entry) {
    block[0] = float(kExitSideSize);
    return 1 + kExitSideSize;
  }
  entry_side_knots(e, block + 1 + kExitSideSize);
  block[0] = float(kExitSideSizeWithEntry);
  return 1 + kExitSideSizeWithEntry;
}
#endif

/* One band's offset at level u in [0, 1]: the inverse distribution through its knots. */
NY_KERNEL_FN float exit_band_offset(NY_GLOBAL const float *knots, float u)
{
  for (int k = 1; k < kExitKnots; k++) {
    const float l0 = exit_knot_level(k - 1), l1 = exit_knot_level(k);
    if (u < l1) {
      return knots[k - 1] + (knots[k] - knots[k - 1]) * ((u - l0) / (l1 - l0));
    }
  }
  return knots[kExitKnots - 1];
}

/* Where x in [0, n - 1] lies between the centres of n equal cells over [0, 1] of `a` (first cell, weight): NaN
 * lands in the first cell (int(NaN) is undefined). */
NY_KERNEL_FN int exit_cell(float a, int n, NY_PRIVATE float *w)
{
  float x = a * float(n) - 0.5f;
  x = x > 0.0f ? (x < float(n - 1) ? x : float(n - 1)) : 0.0f;
  int c = int(x);
  c = c > n - 2 ? n - 2 : c;
  *w = x - float(c);
  return c;
}

/* The entry's h (across the ply's width seen along the path's direction, [-1, 1]) for a path that leaves a ply
 * at `h_exit` in a direction at `cos_axis` to its axis, at level u in [0, 1): the side's entry knots
 * (kEntrySideSize floats), linear between the two nearest bands and the two nearest rows. */
NY_KERNEL_FN float entry_sample_h(NY_GLOBAL const float *knots, float cos_axis, float h_exit, float u)
{
  u = u < 0.0f ? 0.0f : (u > 1.0f ? 1.0f : u);
  float wb, wr;
  const int b = exit_cell(cos_axis < 0.0f ? -cos_axis : cos_axis, kExitBands, &wb);
  const int r = exit_cell(0.5f * (h_exit + 1.0f), kEntryRows, &wr);
  NY_GLOBAL const float *k = knots + (b * kEntryRows + r) * kExitKnots;
  const float h00 = exit_band_offset(k, u), h01 = exit_band_offset(k + kExitKnots, u);
  k += kEntryRows * kExitKnots;
  const float h10 = exit_band_offset(k, u), h11 = exit_band_offset(k + kExitKnots, u);
  const float h = (1.0f - wb) * (h00 + (h01 - h00) * wr) + wb * (h10 + (h11 - h10) * wr);
  return h < -1.0f ? -1.0f : (h > 1.0f ? 1.0f : h);
}

/* An offset along the ply's axis (ply radii, positive along `cos_axis`'s axis direction) for a path that leaves
 * the ply in a direction at `cos_axis` to that axis, at level u in [0, 1): the side's bands (`knots`,
 * kExitSideSize floats) at |cos_axis|, linear between the two nearest band centres, turned toward where the path
 * goes along the axis (where the light it stands for came from). */
NY_KERNEL_FN float exit_sample_offset(NY_GLOBAL const float *knots, float cos_axis, float u)
{
  u = u < 0.0f ? 0.0f : (u > 1.0f ? 1.0f : u);
  float w;
  const int b = exit_cell(cos_axis < 0.0f ? -cos_axis : cos_axis, kExitBands, &w);
  const float s0 = exit_band_offset(knots + b * kExitKnots, u);
  const float s1 = exit_band_offset(knots + (b + 1) * kExitKnots, u);
  const float s = s0 + (s1 - s0) * w;
  return cos_axis < 0.0f ? -s : s;
}

}  // namespace ny
