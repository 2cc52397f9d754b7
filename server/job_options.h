// Turns a JobSpec from the wire into typed library options, checking every field: a bad
// value is INVALID_ARGUMENT naming the option; an algorithm or energy this server does not
// run is UNIMPLEMENTED.
#ifndef MLCLUST_SERVER_JOB_OPTIONS_H_
#define MLCLUST_SERVER_JOB_OPTIONS_H_

#include "absl/status/statusor.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/point_clustering.h"
#include "core/energy/energies.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::server {

// Option names accepted in JobSpec.options (values are text):
//   init              random | lneigh               (EMLO, BB; default lneigh)
//   level             l of the l-neighbourhood seeds, 0 = chosen from k (default 0)
//   density           power | linear                (cvd-adaptive, mwcvd-*; default linear for
//                     mwcvd-*, power for cvd-adaptive: ResolveDensityOptions)
//   gamma, delta      the power mapping (rho' + delta)^gamma (defaults 2, 1e-2)
//   rho-max           rho^new, the linear mapping's upper end (default 50 for mwcvd-area/max,
//                     3 for mwcvd-variance, 10 for cvd-adaptive)
//   mwcvd-p           the p of w^M (default 10)
//   planar-tolerance  the sphere energy's Delta_zero (default 5e-5)
//   threads           BB worker threads, 0 = all cores (default 0)
//   max-iterations    BB sweeps (default 200)
//   guard             on | off: the connectivity guard (default on)
//   optimizer         emlo | bb | none: ML's and PML's local optimiser (default emlo)
//   p-percent         ML: merge this % of the clusters first without optimising (Alg. 4.2)
//   pml-until         PML: continue as ML below this many clusters (default 0: PML to the end)
//   threads           also PML's worker threads
struct MeshJobPlan {
  v1::Algorithm algorithm = v1::ALGORITHM_HC;
  MeshEnergyOptions energy;
  SeedOptions seeds;
  EmloOptions emlo;
  BoundaryBasedOptions boundary_based;
  MultilevelOptions multilevel;  // HC, ML, PML
};

absl::StatusOr<MeshJobPlan> PlanMeshJob(const v1::JobSpec& spec);

// Point jobs. Options: grid (voxels per dimension of the start, 0 = from m and d),
// optimizer lnkmeans | none, pml-until, threads, init kmeans++ | random (LN k-means),
// max-iterations (LN k-means).
struct PointJobPlan {
  v1::Algorithm algorithm = v1::ALGORITHM_ML;
  PointMultilevelOptions multilevel;  // HC, ML, PML
  LnKmeansOptions ln_kmeans;
  bool kmeans_plus_plus = true;
  // LN k-means from the voxel grid (option init=grid, with option grid): one cluster per
  // occupied cell, so clusters is 0.
  bool grid_start = false;
  uint32_t grid = 0;
  uint32_t clusters = 0;
  uint64_t seed = 1;
};
absl::StatusOr<PointJobPlan> PlanPointJob(const v1::JobSpec& spec);

// The energy part alone (spec.energy and the energy options; other options ignored).
absl::StatusOr<MeshEnergyOptions> PlanMeshEnergy(const v1::JobSpec& spec);

// The core energy kind of a wire energy (ENERGY_UNSPECIFIED is CVD).
absl::StatusOr<MeshEnergyKind> MeshEnergyFromWire(v1::Energy energy);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_JOB_OPTIONS_H_
