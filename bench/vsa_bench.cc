// Times mlclust's VSA (core/vsa.h), the counterpart of bench/peers/cgal_vsa.cc.
//   vsa_bench MESH --k K [--seeding random|incremental|hierarchical] [--iterations N]
//             [--inner-iterations I] [--min-relative-decrease D] [--no-teleport] [--seed S]
//             [--repeats R] [--header]
// Prints one CSV row: mesh,faces,k,seeding,iterations,seconds,energy.
//   seconds: the best of R repeats of ComputeFaceMeasures + RunVsa, one thread (the face
//            measures are timed as CGAL's L21 metric, which computes normals and areas, is
//            timed by cgal_vsa; reading the file and building the adjacency are not timed,
//            as cgal_vsa does not time reading or building its Surface_mesh).
//   energy:  the planar (L2,1) energy of the labels, EnergyFromSums(PlanarEnergy, labels).
// Defaults match cgal_vsa's: hierarchical seeding, 30 iterations, 5 inner iterations.
#include <cstdio>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/time/clock.h"
#include "core/cluster/vsa.h"
#include "core/energy/energies.h"
#include "core/io/mesh_io.h"
#include "core/mesh/face_measures.h"

namespace {

int Usage(const char* problem) {
  if (problem != nullptr) std::fprintf(stderr, "vsa_bench: %s\n", problem);
  std::fprintf(stderr,
               "usage: vsa_bench MESH --k K [--seeding random|incremental|hierarchical]\n"
               "         [--iterations N] [--inner-iterations I] [--min-relative-decrease D]\n"
               "         [--no-teleport] [--seed S] [--repeats R] [--header]\n");
  return 2;
}

std::string MeshName(const std::string& path) {
  std::string name = path.substr(path.find_last_of('/') + 1);
  const size_t dot = name.rfind('.');
  if (dot != std::string::npos && dot > 0) name.resize(dot);
  return name;
}

}  // namespace

int main(int argc, char** argv) {
  std::string path, seeding_name = "hierarchical";
  mlclust::VsaOptions options;
  uint32_t repeats = 3;
  bool header = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--header") {
      header = true;
      continue;
    }
    if (arg == "--no-teleport") {
      options.teleport = false;
      continue;
    }
    if (arg.rfind("--", 0) != 0) {
      if (!path.empty()) return Usage("more than one mesh");
      path = arg;
      continue;
    }
    if (i + 1 >= argc) return Usage((arg + " needs a value").c_str());
    const std::string value = argv[++i];
    bool ok = true;
    if (arg == "--k") {
      ok = absl::SimpleAtoi(value, &options.clusters);
    } else if (arg == "--seeding") {
      seeding_name = value;
    } else if (arg == "--iterations") {
      ok = absl::SimpleAtoi(value, &options.iterations);
    } else if (arg == "--inner-iterations") {
      ok = absl::SimpleAtoi(value, &options.inner_iterations);
    } else if (arg == "--min-relative-decrease") {
      ok = absl::SimpleAtod(value, &options.min_relative_decrease);
    } else if (arg == "--seed") {
      ok = absl::SimpleAtoi(value, &options.seed);
    } else if (arg == "--repeats") {
      ok = absl::SimpleAtoi(value, &repeats) && repeats >= 1;
    } else {
      return Usage(("unknown option " + arg).c_str());
    }
    if (!ok) return Usage(("bad value '" + value + "' for " + arg).c_str());
  }
  if (path.empty()) return Usage("no mesh");
  const absl::StatusOr<mlclust::VsaOptions::Seeding> seeding =
      mlclust::ParseVsaSeeding(seeding_name);
  if (!seeding.ok()) return Usage(std::string(seeding.status().message()).c_str());
  options.seeding = *seeding;

  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
  if (!mesh.ok()) {
    std::fprintf(stderr, "vsa_bench: %s\n", mesh.status().ToString().c_str());
    return 1;
  }
  if (absl::Status valid = mlclust::ValidateMesh(*mesh); !valid.ok()) {
    std::fprintf(stderr, "vsa_bench: %s\n", valid.ToString().c_str());
    return 1;
  }
  const mlclust::FaceAdjacency adjacency = *mlclust::BuildFaceAdjacency(*mesh);

  double best_seconds = 0;
  mlclust::VsaResult best;
  mlclust::FaceMeasures measures;
  for (uint32_t r = 0; r < repeats; ++r) {
    const absl::Time start = absl::Now();
    measures = mlclust::ComputeFaceMeasures(*mesh);
    mlclust::MeshProblem problem{&*mesh, &adjacency, &measures, {}};
    problem.energy.kind = mlclust::MeshEnergyKind::kPlanar;
    absl::StatusOr<mlclust::VsaResult> result = mlclust::RunVsa(problem, options);
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!result.ok()) {
      std::fprintf(stderr, "vsa_bench: %s\n", result.status().ToString().c_str());
      return 1;
    }
    std::fprintf(stderr,
                 "vsa_bench: repeat %u/%u: %.6f s, %u seeding + %u iterations (best %u, %u "
                 "teleports), energy %.9g\n",
                 r + 1, repeats, seconds, result->seeding_iterations, result->iterations,
                 result->best_iteration, result->teleports, result->energy);
    if (r > 0 && result->labels != best.labels) {
      std::fprintf(stderr, "vsa_bench: repeat %u gave other labels than repeat 1\n", r + 1);
      return 1;
    }
    if (r == 0 || seconds < best_seconds) {
      best_seconds = seconds;
      best = *std::move(result);
    }
  }
  const double energy = mlclust::EnergyFromSums(mlclust::PlanarEnergy(measures), best.labels);

  if (header) std::printf("mesh,faces,k,seeding,iterations,seconds,energy\n");
  std::printf("%s,%zu,%u,%s,%u,%.6f,%.9g\n", MeshName(path).c_str(), mesh->num_faces(),
              options.clusters, seeding_name.c_str(), options.iterations, best_seconds, energy);
  return 0;
}
