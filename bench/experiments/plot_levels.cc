// The --plot PNG (client/plot.h) of a levels CSV that `mlclust ... --levels-csv` wrote
// (header "clusters,energy", one row per level), with the elbows of core/hierarchy/elbow.h
// marked: what `--plot FILE.png` will draw once the CLI has it.
//   plot_levels LEVELS.csv OUT.png [TITLE]
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench/bench_util.h"
#include "client/plot.h"
#include "core/hierarchy/elbow.h"

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: plot_levels LEVELS.csv OUT.png [TITLE]");
  mlclust::client::EnergyPlotOptions options;
  const std::string levels_path = args.Positional(0);
  const std::string png_path = args.Positional(1);
  options.title = args.Positional(2, options.title);
  if (!args.Done()) return 2;
  std::ifstream in(levels_path);
  std::string line;
  std::vector<uint32_t> counts;
  std::vector<double> energies;
  std::vector<mlclust::client::EnergyCurvePoint> curve;
  while (std::getline(in, line)) {
    std::vector<std::string> fields = absl::StrSplit(line, ',');
    uint32_t k;
    double e;
    if (fields.size() != 2 || !absl::SimpleAtoi(fields[0], &k) ||
        !absl::SimpleAtod(fields[1], &e)) {
      continue;  // the header
    }
    counts.push_back(k);
    energies.push_back(e);
    curve.push_back({k, e});
  }
  options.elbows = mlclust::FindElbows(counts, energies);
  const absl::Status status = mlclust::client::WriteEnergyPlotPng(curve, options, png_path);
  if (!status.ok()) {
    std::fprintf(stderr, "%s\n", status.ToString().c_str());
    return 1;
  }
  std::printf("%zu levels, %zu elbows", curve.size(), options.elbows.size());
  for (uint32_t k : options.elbows) std::printf(" %u", k);
  std::printf("\n");
  return 0;
}
