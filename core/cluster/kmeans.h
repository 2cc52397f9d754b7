// Brute-force k-means: Lloyd's algorithm (every point checked against every centre) seeded
// by greedy k-means++ (Arthur & Vassilvitskii 2007, with scikit-learn's local trials). The
// baseline that LN k-means (dissertation Alg. 6.1) and the point hierarchies are measured
// against, and the `--algo kmeans` engine.
//
// The energy is the within-cluster sum of squares, sum_i ||x_i - c(i)||^2 with c(i) the mean
// of point i's cluster ("inertia" in scikit-learn's words; the SSE that core/model_selection.h
// takes).
//
// Determinism: on one machine the same points, options and seed give the same result, bit for
// bit, for any thread count (work is split into blocks of fixed size and their partial sums
// are added in block order). Distances are compared in float by a vectorised kernel that
// uses AVX2 and FMA where the x86-64 processor has them, so a machine without them may break
// near-ties differently.
#ifndef MLCLUST_CORE_CLUSTER_KMEANS_H_
#define MLCLUST_CORE_CLUSTER_KMEANS_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/points/points.h"

namespace mlclust {

// How a Lloyd run goes: its seeding, iterations, tolerance, seed, threads and cancellation.
// KmeansOptions is one; bisecting k-means and X-means are one too, for the k-means runs
// inside them, and hand it on whole (KmeansOptionsFor).
struct KmeansRunOptions {
  enum class Init {
    // greedy k-means++ (KmeansPlusPlusCentres below).
    kKmeansPlusPlus,
    // k different points (by index) chosen uniformly at random (scikit-learn's
    // init="random").
    kRandom,
  };
  Init init = Init::kKmeansPlusPlus;
  // At least 1. Each iteration assigns every point to its nearest centre and moves every
  // centre to the mean of its points.
  uint32_t max_iterations = 300;
  // Stops after the first iteration that moved the centres by sum_c ||c_new - c_old||^2 <=
  // tolerance x (the mean over dimensions of the points' variance), as scikit-learn's tol;
  // and, whatever the tolerance, after an iteration that moved no point (a fixed point).
  // 0: only the latter. >= 0.
  double tolerance = 1e-4;
  // Seeds the initialisation (core/random.h): the same seed, the same centres.
  uint64_t seed = 1;
  // Worker threads; 0: all cores. The result does not depend on it.
  int threads = 0;
  // Checked before each k-means++ centre and by every block of points in each iteration
  // (core/base/cancel.h); a set flag returns CANCELLED.
  const std::atomic<bool>* cancel = nullptr;
};

struct KmeansOptions : KmeansRunOptions {
  // k: in [1, points].
  uint32_t clusters = 0;
  // Called after each iteration with its number (1-based) and the energy of its partition
  // (KmeansResult::inertia of a run stopped there). Never increases from one call to the
  // next, up to rounding (about 1e-15 relative).
  std::function<void(uint32_t iteration, double inertia)> on_iteration;
  // With it, KmeansResult::first_labels and first_inertia keep the partition of the first
  // iteration: every point at its nearest initial centre (empty clusters filled as below),
  // exactly what a run with max_iterations = 1 returns as labels and inertia. A caller
  // that reports the seeding as a level of its own so needs no second run of that
  // iteration. Costs one copy of the labels.
  bool keep_first_assignment = false;
};

// A k-means run of `clusters` clusters with `run`'s settings (the rest as KmeansOptions'
// defaults).
inline KmeansOptions KmeansOptionsFor(const KmeansRunOptions& run, uint32_t clusters) {
  KmeansOptions options;
  static_cast<KmeansRunOptions&>(options) = run;
  options.clusters = clusters;
  return options;
}

struct KmeansResult {
  // One cluster per point, 0..k-1; every cluster holds at least one point.
  std::vector<ClusterId> labels;
  // k x d, row-major: centre c is the mean of the points labelled c (rounded to float).
  // Unless `converged`, a further assignment could still move points to other centres.
  std::vector<float> centres;
  // sum_i ||x_i - mean of its cluster||^2 in double precision (the means in double too).
  double inertia = 0;
  uint32_t iterations = 0;  // Lloyd iterations run
  bool converged = false;   // stopped by the tolerance or at a fixed point
  double seconds_init = 0;  // seeding (0 for RunLloyd)
  double seconds_iterations = 0;
  // With KmeansOptions::keep_first_assignment: the labels and inertia after the first
  // iteration (see there); empty and 0 otherwise.
  std::vector<ClusterId> first_labels;
  double first_inertia = 0;
};

// Seeds (options.init) and runs Lloyd (RunLloyd) on `points`.
//
// An iteration that leaves a cluster empty moves, for each empty cluster in id order, the
// point farthest from its current centre (among clusters with more than one point; ties to
// the smaller point id) into it, as scikit-learn does: the energy only falls, and every
// cluster of the result is non-empty. Equal centres (from duplicate points) are allowed.
//
// Each iteration finds every point's nearest centre in float (vectorised, parallel over
// blocks of points: m k d distance terms); a point leaves its cluster only where that lowers
// its distance in double, so the energy never rises. Then O(m d) work in double. Memory:
// the labels, the centres, and per-chunk sums of at most 32 MiB (more only where k (d + 1)
// doubles exceed it); nothing is allocated per iteration.
//
// Errors: ValidatePoints' INVALID_ARGUMENT; INVALID_ARGUMENT naming 'clusters' for k < 1 or
// k > m, 'max_iterations' for 0, 'tolerance' for a negative or NaN one, 'threads' for < 0,
// and 'points' where the coordinates span more than 1e17 (their squared distances would
// overflow float). CANCELLED if options.cancel was set.
absl::StatusOr<KmeansResult> RunKmeans(const PointSet& points, const KmeansOptions& options);

// Greedy k-means++ (scikit-learn's _kmeans_plusplus): the first centre is a uniformly random
// point; each further centre is the best, by the energy after adding it, of 2 + floor(ln k)
// points drawn with probability proportional to their squared distance to the nearest centre
// so far (uniformly while every point sits on a centre). Returns k x d floats (each a copy of
// a point). O(m k d log k) distance terms, parallel over blocks of points, with a transposed
// copy of the points (m d floats) while it runs; `threads` as in KmeansOptions. Errors as
// RunKmeans ('clusters', 'threads', ValidatePoints', 'points').
absl::StatusOr<std::vector<float>> KmeansPlusPlusCentres(const PointSet& points, uint32_t k,
                                                         uint64_t seed, int threads = 0);

// Lloyd's iterations from the given centres (k x d floats, k = centres.size() / d in
// [1, m]), so that another engine can start from its own seeds. Uses options.max_iterations,
// tolerance, threads and on_iteration; options.clusters must be 0 or k; init and seed are
// not used. The first iteration assigns every point to its nearest given centre. Errors as
// RunKmeans, and INVALID_ARGUMENT naming 'centres' for a size that is not a whole number of
// points, a non-finite value, or a k that differs from options.clusters.
absl::StatusOr<KmeansResult> RunLloyd(const PointSet& points, std::vector<float> centres,
                                      const KmeansOptions& options);

namespace detail {
// For tests: where kBaseline, the distance kernels are the baseline x86-64 (SSE2) ones even
// on a processor with AVX2, so that tests reach them. Not thread-safe against running
// k-means; kAuto (the default) picks AVX2 and FMA where the processor has them.
enum class KmeansKernels { kAuto, kBaseline };
void SetKmeansKernelsForTesting(KmeansKernels kernels);
}  // namespace detail

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_KMEANS_H_
