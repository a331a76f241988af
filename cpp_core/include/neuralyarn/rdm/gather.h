// SPDX-License-Identifier: Apache-2.0
//
// Monte Carlo gathering of the radiance distribution map (RDM): paper Sec. 4 ("Data"), done correctly
// (docs/rdm.md has the full definition; docs/decisions.md D7-D10 the choices).
//
// Each path enters the ply's bounding cylinder (radius R) at a uniformly random point with direction -w_i,
// w_i on the upper hemisphere of the entry frame (x = ply axis, z = outward normal n, y = z x x), and
// random-walks through the fibers: at every tube entry the fiber BSDF is sampled in the fiber's frame
// (x = chord tangent, z = tube normal) and the path continues from the hit point, through the fiber when
// the direction points into it, as a renderer's ray does (D32). Fiber events are counted explicitly:
//     T: 0 events;   R: exactly 1 event and w_o . n > 0;   M: everything else that leaves,
// where w_o is the exit direction in the entry frame (far field: the exit point is only a diagnostic).
// Russian roulette from the second event on, with survival probability min(1, max channel throughput),
// keeps it unbiased (single scattering is never left to it, D34).
//
// Incident directions are stratified: path k belongs to incident bin k mod (n_theta_i n_phi_i), so every
// incident bin gets the same number of paths (+-1), and w_i is uniform in solid angle inside its bin.
// Paths alternate, per round over the incident bins, between the ply and its mirror image (the ply rotated
// by pi about a radial axis), which makes the 180-degree symmetry about n exact in expectation.
//
// Every accumulator is an integer (weights in 32.32 fixed point, added atomically), so the result does not
// depend on the order in which threads finish: the same seed gives bit-identical maps at any thread count.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "neuralyarn/geometry/yarn_structure.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/kernel/exit_placement.h"
#include "neuralyarn/rdm/ply_tracer.h"

namespace neuralyarn::rdm {

/* Bins: theta measured from the normal (polar), phi = atan2(y, x) in the entry frame, both uniform:
 * theta_i in [0, pi/2], theta_o in [0, pi], phi in [-pi, pi). The paper's map is 22 x 90 x 45 x 90. */
struct MapResolution {
  int theta_i = 22, phi_i = 90, theta_o = 45, phi_o = 90;
  size_t incident() const { return size_t(theta_i) * size_t(phi_i); }
  size_t outgoing() const { return size_t(theta_o) * size_t(phi_o); }
  bool operator==(const MapResolution &o) const
  {
    return theta_i == o.theta_i && phi_i == o.phi_i && theta_o == o.theta_o && phi_o == o.phi_o;
  }
};

struct GatherOptions {
  uint64_t paths = 10'000'000;
  uint64_t seed = 1;       /* seeds every path                                                   */
  uint64_t packing_seed = 1; /* seeds the fiber cross-section (the geometry)                    */
  /* Cross-sections the paths are spread over, seeded packing_seed, packing_seed + 1, ...: one cross-section
   * is one draw of the ply, and its far field differs from another's (D42); the maps of several hold
   * their mean. Ply level only. */
  int layouts = 1;
  int threads = 0;         /* 0: all cores                                                       */
  MapResolution bins;
  bool symmetrize = true;  /* average each bin with its image under the 180-degree rotation      */
  bool variance = false;   /* also accumulate squared weights (per-bin standard errors)          */
  int max_events = 1 << 20;/* a path still inside after this many events is dropped and counted  */
  TracerOptions tracer;
  bool plain_estimator = false; /* benchmarks only: FiberLobeSampler's textbook mode               */
  /* Called from worker threads (serialised by the caller's own means) as paths complete. */
  std::function<void(uint64_t done, uint64_t total)> progress;
};

/* Summary numbers of one gather. Energies are means per path (RGB); they sum with `absorbed` and `lost`
 * to 1 in expectation. */
struct GatherStats {
  uint64_t paths = 0;
  double seconds = 0.0;         /* wall time of gather(): packing, allocation, tracing, finalisation */
  double seconds_tracing = 0.0; /* of which tracing the paths                                       */
  double energy_T[3] = {0, 0, 0}, energy_R[3] = {0, 0, 0}, energy_M[3] = {0, 0, 0};
  double absorbed[3] = {0, 0, 0}; /* expected energy absorbed at the events, per path  */
  double lost[3] = {0, 0, 0};     /* energy of paths that hit max_events                */
  /* Per path, exit weight + absorbed + lost has expectation exactly 1: its mean and standard error. */
  double balance[3] = {0, 0, 0}, balance_se[3] = {0, 0, 0};
  uint64_t paths_T = 0, paths_R = 0, paths_M = 0, paths_terminated = 0, paths_truncated = 0;
  /* A finite medium (the yarn level): paths that left through an end rather than the envelope. */
  uint64_t paths_past_ends = 0;
  std::vector<uint64_t> events_histogram; /* [e] = paths with e events (last bin: that many or more) */
  double mean_events = 0.0;
  int p95_events = 0, max_events_seen = 0;
  uint64_t events_total = 0, slab_crossings = 0, invalid_weights = 0;
  /* Distance between entry and exit point in ply radii, over paths that scattered and left: */
  double mean_displacement = 0.0, p95_displacement = 0.0;
  double mean_displacement_M = 0.0, p95_displacement_M = 0.0;
  /* How far along the ply (yarn) axis scattered light travels inside before it leaves: the offset of its exit along
   * the axis (ply radii) from where a ray from the entry point along the exit direction would leave, signed
   * (positive the way the light travelled along the axis, -w_i's) and weighted by the exit energy (mean of RGB) times
   * the light that came in with it (cos theta_i times its theta bin's share of the solid angle over its share of the
   * paths; since D73),
   * per band of |cos(w_i, axis)| (ny::kExitBands of equal width), at the levels ny::exit_knot_level(1 ..
   * ny::kExitQuantiles), band after band: over the exits on the entry side (R and M, w_o.z > 0 in the entry frame)
   * and over those through the far side; with each band's mean. A far-field BSDF puts every exit at its entry
   * point, so light that enters a lit part of a ply and leaves in a shadowed part is what it cannot render
   * (decisions D68, D72; kernel/exit_placement.h). Empty for maps written before D72 (whose offsets were pooled
   * over the incidences and unsigned). */
  std::vector<double> axial_exit_reflected, axial_exit_through;
  std::vector<double> mean_axial_exit_reflected, mean_axial_exit_through;
  /* Where around the ply the light came in, given where it leaves (decisions D73): across the ply's width seen along
   * w_i (h in [-1, 1]), the entry's h at the levels ny::exit_knot_level(1 .. ny::kExitQuantiles) per row of the
   * exit's h (ny::kEntryRows over [-1, 1]) per band of |cos(w_i, axis)|, band after band, row after row, weighted by
   * the light that came in (exit energy times the entry's cosine times its theta bin's share of the solid angle over
   * its share of the paths), mirror-symmetric in h; on the exit point's half facing w_i and on the other (through
   * the far side). Empty for maps written before D73. */
  std::vector<double> entry_h_reflected, entry_h_through;
  double paths_per_second() const { return seconds > 0.0 ? double(paths) / seconds : 0.0; }
};

/* The maps. Arrays are row-major in the order of their index lists. */
struct RdmMaps {
  MapResolution bins;
  FiberPreset preset;
  geometry::YarnStructure structure; /* the level: a ply (plies = 1) or a K-ply yarn */
  uint64_t seed = 0, packing_seed = 0, paths = 0;
  int layouts = 1; /* cross-sections, seeded packing_seed, packing_seed + 1, ... (GatherOptions) */
  bool symmetrized = false;
  double fiber_radius = 0.0, slab_length = 0.0, sagitta = 0.0; /* ply radius R = 1 */
  /* The yarn level's intersector ("slabs": chord tubes within `sagitta`; "embree": round curves of 128 segments
   * per turn); empty for a ply, whose PlyTracer the sagitta describes. */
  std::string intersector;
  /* A bent ply's maps (rdm/bent_ply.h, decisions D75): its circle's radius in ply radii (0: the same cross-sections
   * walked straight) and the sector of psi the paths entered in; bend_sectors 0: not a bent ply's. */
  double bend_radius = 0.0;
  int bend_sector = 0, bend_sectors = 0;
  /* The R lobe's surface-fiber twist: the preset's alpha for a ply, the yarn's surface twist for a yarn. */
  double surface_alpha() const { return structure.is_yarn() ? structure.surface_alpha : preset.alpha; }
  std::vector<uint64_t> count;    /* [theta_i][phi_i]: paths                                    */
  std::vector<float> p_t;         /* [theta_i][phi_i]: fraction passing unscattered, P(T | w_i) */
  std::vector<float> r, m;        /* [theta_i][phi_i][theta_o][phi_o][rgb]: f |cos theta_o|     */
  std::vector<double> exit_energy;/* [theta_i][phi_i][rgb]: mean exit throughput, T + R + M (averaged as p_t) */
  std::vector<double> absorbed;   /* [theta_i][phi_i][rgb]: mean absorbed energy                */
  /* Standard errors of the bin estimates (only with GatherOptions::variance): */
  std::vector<float> p_t_se, r_se, m_se;
  GatherStats stats;

  size_t incident_index(int ti, int pi) const { return size_t(ti) * size_t(bins.phi_i) + size_t(pi); }
  size_t map_index(int ti, int pi, int to, int po) const
  {
    return ((incident_index(ti, pi) * size_t(bins.theta_o) + size_t(to)) * size_t(bins.phi_o) + size_t(po)) * 3;
  }
  /* Solid angle of outgoing bin theta_o index `to` (any phi_o), and of incident bin `ti` (any phi_i). */
  double outgoing_solid_angle(int to) const;
  double incident_solid_angle(int ti) const;
  /* Energy of a map (r or m) per incident bin, channel by channel: sum over w_o of value * solid angle.
   * Row-major [theta_i][phi_i][rgb]. */
  std::vector<double> energy(const std::vector<float> &map) const;
};

/* Gathers the maps of one fiber preset (its N, rho, alpha and shading) for a ply of radius 1. Throws
 * ParameterError for invalid options or geometry that cannot be packed. */
RdmMaps gather(const FiberPreset &preset, const GatherOptions &options);

class FiberMedium;

/* The same random walks through any medium and its mirror image (rdm/fiber_medium.h), recorded as maps of
 * `structure` (the yarn level's gather_yarn calls it). */
RdmMaps gather_through(const FiberPreset &preset, const geometry::YarnStructure &structure, const GatherOptions &options,
                       const FiberMedium &medium, const FiberMedium &mirror);

/* "22x90x45x90" (theta_i x phi_i x theta_o x phi_o); throws ParameterError("bins") otherwise. Their
 * ranges are checked by validate(GatherOptions). */
MapResolution parse_resolution(const std::string &text);

/* Validates options without gathering (the CLI calls it before allocating anything). */
void validate(const GatherOptions &options);

/* The mean of two gathers of the same preset and resolution with different path seeds, weighted by their
 * paths: statistically a gather of both path counts (the standard errors are dropped). Throws
 * ParameterError if they do not fit together. */
RdmMaps mean_of_maps(const RdmMaps &a, const RdmMaps &b);

/* Bin helpers shared with the loader, tests and trainer. */
int bin_of(double value, double lo, double hi, int n);
double bin_center(int index, double lo, double hi, int n);

/* The two bin centres about `value` on an axis of n bins over [lo, hi] and their linear weights (summing to 1);
 * beyond the first or last centre both are that bin, or, with `wraps`, the axis is periodic (azimuths). */
struct BinTaps {
  int bin[2];
  double weight[2];
};
BinTaps bin_taps(double value, double lo, double hi, int n, bool wraps);

/* The bins of a direction (x, y, z) in the entry frame (z = the ply normal; unit length): incident
 * (theta_i in [0, pi/2], clamped) and outgoing (theta_o in [0, pi]). */
void incident_bin(const MapResolution &b, double x, double y, double z, int *ti, int *pi);
void outgoing_bin(const MapResolution &b, double x, double y, double z, int *to, int *po);

/* outgoing_bin for many directions: a first guess from a table (over cos theta_o, and over a pseudo-angle of the
 * azimuth that needs one division), settled against the bins' edges (precomputed) so that the bin is the one of
 * the exact angle, as outgoing_bin's, at a fraction of its double acos and atan2 (the R lobe's quadrature bins
 * ~10^8 samples per bake). */
class OutgoingBinner {
 public:
  explicit OutgoingBinner(const MapResolution &b);
  void operator()(double x, double y, double z, int *to, int *po) const;

 private:
  /* Table cells: fine enough that no cell holds more than one bin edge at the paper's resolution (a theta_o bin
   * is 0.0024 wide in cos theta_o at the poles, an azimuth bin 0.087 in the pseudo-angle), so a guess is at
   * most one bin off; any guess settles to the same bin. */
  static constexpr int kGuessCells = 4096;
  int n_theta_, n_phi_;
  std::vector<double> cos_theta_edge_;       /* cos(pi t / n), t = 0..n            */
  std::vector<double> phi_edge_c_, phi_edge_s_; /* cos and sin of -pi + 2 pi k / n, k = 0..n */
  std::vector<int> theta_guess_, phi_guess_; /* the bin at each cell's centre */
};

}  // namespace neuralyarn::rdm
