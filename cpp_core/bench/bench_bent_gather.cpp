// SPDX-License-Identifier: Apache-2.0
//
// The radiance distribution maps of a ply bent on a circle (rdm/bent_ply.h, decisions D75), optionally held to one
// sector about the tube, or of the same cross-sections straight (--radius 0, through Embree's curves). Bent, the
// wedges walk it (D76), or with --intersector embree Embree's curves. Its maps go to bench_bent_ply --maps /
// --sector-maps (the far field predicted on a bent ply) and bench_bent_m.
//
// Usage: bench_bent_gather --preset cotton [--radius 3] [--sector k --sectors K] [--no-symmetrize] [--layouts 4]
//                          [--paths 4e6] [--seed 1] [--packing-seed 1] [--bins 22x90x45x90]
//                          [--intersector wedges|embree] --out M.nyrdm
// A benchmark: prints, never a test.
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/bent_ply.h"
#include "neuralyarn/rdm/map_file.h"
#include "cli_common.h"

using namespace neuralyarn;

int main(int argc, char **argv)
{
  CLI::App app{"The radiance distribution maps of a ply bent on a circle (or straight)"};
  std::string preset_name = "cotton", bins = "22x90x45x90", out, paths_text = "4e6", intersector = "wedges";
  rdm::Bend bend;
  rdm::GatherOptions opt;
  opt.layouts = 4;
  bool no_symmetrize = false;
  app.add_option("--preset", preset_name);
  app.add_option("--radius", bend.radius, "The circle's radius in ply radii (0: straight)");
  app.add_option("--sector", bend.sector, "Enter only in sector k of --sectors about the tube (0: the outer side)");
  app.add_option("--sectors", bend.sectors);
  app.add_flag("--no-symmetrize", no_symmetrize, "Keep the raw maps (a sector other than the outer or inner side "
               "needs it)");
  app.add_option("--layouts", opt.layouts, "Cross-sections (packing seeds --packing-seed, +1, ...)");
  app.add_option("--paths", paths_text);
  app.add_option("--seed", opt.seed);
  app.add_option("--packing-seed", opt.packing_seed);
  app.add_option("--threads", opt.threads);
  app.add_option("--intersector", intersector, "wedges (chord tubes in wedges of the circle) or embree (round curves)")
      ->check(CLI::IsMember({"wedges", "embree"}));
  app.add_option("--bins", bins);
  app.add_option("--out", out)->required();
  CLI11_PARSE(app, argc, argv);
  try {
    opt.paths = cli::parse_count(paths_text);
    opt.bins = rdm::parse_resolution(bins);
    opt.symmetrize = !no_symmetrize;
    cli::ProgressBar bar(true);
    opt.progress = [&bar](uint64_t done, uint64_t total) { bar.update(done, total); };
    const rdm::RdmMaps maps = rdm::gather_bent(find_preset(preset_name), bend, opt,
                                               intersector == "embree" ? rdm::BentIntersector::kEmbree
                                                                       : rdm::BentIntersector::kWedges);
    rdm::save_maps(maps, out);
    const auto &s = maps.stats;
    auto mean = [](const double *e) { return (e[0] + e[1] + e[2]) / 3.0; };
    std::printf("%s radius %g sector %d of %d, %d layouts, %s: %llu paths in %.1f s; energy T %.4f R %.4f M %.4f, "
                "absorbed %.4f (means of RGB)\n",
                preset_name.c_str(), bend.radius, bend.sector, bend.sectors, opt.layouts, maps.intersector.c_str(),
                (unsigned long long)s.paths, s.seconds, mean(s.energy_T), mean(s.energy_R), mean(s.energy_M),
                mean(s.absorbed));
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "bench_bent_gather: %s\n", e.what());
    return 1;
  }
  return 0;
}
