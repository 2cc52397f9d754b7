#include "server/job_runner.h"

#include <algorithm>
#include <chrono>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/base/status_macros.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/point_clustering.h"
#include "core/hierarchy/elbow.h"
#include "core/hierarchy/model_selection.h"
#include "core/io/draco_codec.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "core/points/points.h"
#include "server/job_options.h"
#ifdef MLCLUST_HAVE_GPU
#include "gpu/face_measures_gpu.h"
#endif

namespace mlclust::server {
namespace {

// Streams levels to the client as they are produced: the first level sent as a snapshot
// of all labels, later levels packed into LevelBatch messages of about `batch_triplets`
// triplets (many small levels per message; never one message per triplet), flushed at
// least every `max_delay` so a slow algorithm still shows progress.
//
// With a level range [low, high] (cluster counts; 0 = no bound) only levels in the range
// are sent: the sink follows the labels through the levels before it, and the first level
// in range goes out as the snapshot. It also keeps every level's cluster count and energy
// for the elbow of the summary.
// Hands every call to two sinks; the first error wins.
class TeeSink : public LevelSink {
 public:
  TeeSink(LevelSink& first, LevelSink& second) : first_(first), second_(second) {}
  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override {
    MLCLUST_RETURN_IF_ERROR(first_.OnStart(labels, cluster_count, energy));
    return second_.OnStart(labels, cluster_count, energy);
  }
  absl::Status OnLevel(const LevelMoves& level) override {
    MLCLUST_RETURN_IF_ERROR(first_.OnLevel(level));
    return second_.OnLevel(level);
  }

 private:
  LevelSink& first_;
  LevelSink& second_;
};

class StreamingLevelSink : public LevelSink {
 public:
  StreamingLevelSink(EventChannel& events, uint32_t batch_triplets, uint32_t high = 0,
                     uint32_t low = 0)
      : events_(events),
        batch_triplets_(std::max<uint32_t>(1, batch_triplets)),
        high_(high),
        low_(low) {}

  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override {
    curve_counts_.assign(1, cluster_count);
    curve_energies_.assign(1, energy);
    if (InRange(cluster_count)) return SendSnapshot(labels, 0, cluster_count, energy);
    // Follow the labels until the first level in range.
    labels_.assign(labels.begin(), labels.end());
    return absl::OkStatus();
  }

  absl::Status OnLevel(const LevelMoves& level) override {
    if (events_.cancelled()) return absl::CancelledError("the call was cancelled");
    curve_counts_.push_back(level.cluster_count);
    curve_energies_.push_back(level.energy);
    if (!started_) {
      for (size_t i = 0; i < level.element.size(); ++i) {
        labels_[level.element[i]] = ClusterId(level.to_cluster[i]);
      }
      if (!InRange(level.cluster_count)) return absl::OkStatus();
      absl::Status s = SendSnapshot(labels_, level.level, level.cluster_count, level.energy);
      std::vector<ClusterId>().swap(labels_);
      return s;
    }
    if (!InRange(level.cluster_count)) return absl::OkStatus();
    v1::LevelBatch* batch = pending_.mutable_levels();
    if (batch->cluster_count_size() == 0) batch->set_first_level(levels_sent_);
    batch->add_cluster_count(level.cluster_count);
    batch->add_energy(level.energy);
    batch->add_source_level(level.level);
    batch->mutable_element()->Add(level.element.begin(), level.element.end());
    batch->mutable_to_cluster()->Add(level.to_cluster.begin(), level.to_cluster.end());
    batch->mutable_from_cluster()->Add(level.from_cluster.begin(), level.from_cluster.end());
    batch->add_triplet_end(static_cast<uint32_t>(batch->element_size()));
    ++levels_sent_;
    triplets_sent_ += level.element.size();
    if (static_cast<uint32_t>(batch->element_size()) >= batch_triplets_ ||
        batch->cluster_count_size() >= kMaxLevelsPerBatch ||
        absl::Now() - last_flush_ > kMaxDelay) {
      return Flush();
    }
    return absl::OkStatus();
  }

  absl::Status Flush() {
    if (!pending_.has_levels()) return absl::OkStatus();
    last_flush_ = absl::Now();
    v1::JobEvent event = std::move(pending_);
    pending_.Clear();
    return Send(std::move(event));
  }

  uint32_t levels_sent() const { return levels_sent_; }
  uint64_t triplets_sent() const { return triplets_sent_; }
  bool started() const { return started_; }
  std::span<const uint32_t> curve_counts() const { return curve_counts_; }
  std::span<const double> curve_energies() const { return curve_energies_; }

 private:
  static constexpr int kMaxLevelsPerBatch = 16384;
  static constexpr size_t kSnapshotLabels = size_t{1} << 20;
  static constexpr absl::Duration kMaxDelay = absl::Milliseconds(200);

  bool InRange(uint32_t count) const { return (high_ == 0 || count <= high_) && count >= low_; }

  // The labels in pieces of kSnapshotLabels, so no message outgrows the limits.
  absl::Status SendSnapshot(std::span<const ClusterId> labels, uint32_t level,
                            uint32_t cluster_count, double energy) {
    for (size_t first = 0; first == 0 || first < labels.size(); first += kSnapshotLabels) {
      const size_t end = std::min(labels.size(), first + kSnapshotLabels);
      v1::JobEvent event;
      v1::LevelSnapshot* snapshot = event.mutable_snapshot();
      snapshot->set_level(level);
      snapshot->set_cluster_count(cluster_count);
      snapshot->set_energy(energy);
      snapshot->set_first_element(static_cast<uint32_t>(first));
      snapshot->set_total_elements(static_cast<uint32_t>(labels.size()));
      snapshot->mutable_labels()->Reserve(static_cast<int>(end - first));
      for (size_t i = first; i < end; ++i) snapshot->add_labels(labels[i].value());
      MLCLUST_RETURN_IF_ERROR(Send(std::move(event)));
      if (end == labels.size()) break;
    }
    started_ = true;
    levels_sent_ = 1;
    last_flush_ = absl::Now();
    return absl::OkStatus();
  }

  absl::Status Send(v1::JobEvent event) {
    if (!events_.Emit(std::move(event))) return absl::CancelledError("the call was cancelled");
    return absl::OkStatus();
  }

  EventChannel& events_;
  const uint32_t batch_triplets_;
  const uint32_t high_, low_;
  bool started_ = false;
  std::vector<ClusterId> labels_;  // followed until the first level in range
  std::vector<uint32_t> curve_counts_;
  std::vector<double> curve_energies_;
  v1::JobEvent pending_;
  uint32_t levels_sent_ = 0;
  uint64_t triplets_sent_ = 0;
  absl::Time last_flush_;
};

void EmitProgress(EventChannel& events, const std::string& stage, const std::string& message) {
  v1::JobEvent event;
  event.mutable_progress()->set_stage(stage);
  event.mutable_progress()->set_message(message);
  events.Emit(std::move(event));
}

absl::Status WithContext(const absl::Status& status, absl::string_view what) {
  return absl::Status(status.code(), absl::StrCat(what, ": ", status.message()));
}

absl::StatusOr<FaceMeasures> MeasureFaces(const TriangleMesh& mesh, const v1::JobSpec& spec,
                                          const JobRunnerContext& context,
                                          std::string& device_used) {
  const std::string& device = spec.device();
  if (device != "" && device != "auto" && device != "gpu" && device != "cpu") {
    return absl::InvalidArgumentError(
        absl::StrCat("option device: '", device, "' is not one of auto, gpu, cpu"));
  }
  device_used = "cpu";
  if (device == "cpu") return ComputeFaceMeasures(mesh);
#ifdef MLCLUST_HAVE_GPU
  if (context.gl != nullptr && (device == "gpu" || !context.gl_is_software)) {
    absl::StatusOr<FaceMeasures> measures = gpu::ComputeFaceMeasuresGpu(*context.gl, mesh);
    if (measures.ok()) {
      device_used = context.gl_renderer;
      return measures;
    }
    if (device == "gpu") return WithContext(measures.status(), "face measures on the GPU");
    return ComputeFaceMeasures(mesh);  // auto: the CPU path always works
  }
#endif
  if (device == "gpu") {
    return absl::FailedPreconditionError("option device: 'gpu' but this server has no GPU");
  }
  return ComputeFaceMeasures(mesh);
}

// A single-level algorithm's result as two levels: level 0 the initial clusters, level 1
// the faces whose cluster the optimisation changed.
absl::Status StreamSingleLevel(const std::vector<ClusterId>& initial, double initial_energy,
                               const std::vector<ClusterId>& result, double energy,
                               uint32_t clusters, StreamingLevelSink& sink) {
  MLCLUST_RETURN_IF_ERROR(sink.OnStart(initial, clusters, initial_energy));
  std::vector<uint32_t> element, to, from;
  for (uint32_t f = 0; f < result.size(); ++f) {
    if (result[f] != initial[f]) {
      element.push_back(f);
      to.push_back(result[f].value());
      from.push_back(initial[f].value());
    }
  }
  LevelMoves level;
  level.cluster_count = clusters;
  level.energy = energy;
  level.element = element;
  level.to_cluster = to;
  level.from_cluster = from;
  MLCLUST_RETURN_IF_ERROR(sink.OnLevel(level));
  return sink.Flush();
}

absl::StatusOr<JobOutcome> RunMeshJob(Job& job, const JobRunnerContext& context) {
  const v1::JobSpec& spec = job.spec;
  EventChannel& events = *job.events;
  absl::StatusOr<MeshJobPlan> plan = PlanMeshJob(spec);
  if (!plan.ok()) return plan.status();
  const bool hierarchy = plan->algorithm == v1::ALGORITHM_HC ||
                         plan->algorithm == v1::ALGORITHM_ML ||
                         plan->algorithm == v1::ALGORITHM_PML;
  if (!hierarchy && (spec.levels_high() != 0 || spec.levels_low() != 0)) {
    return absl::InvalidArgumentError(
        "levels: a level range applies to the hierarchies of HC, ML and PML only");
  }

  EmitProgress(events, "decode", absl::StrCat("decoding ", job.input.size(), " bytes"));
  absl::StatusOr<TriangleMesh> mesh = DecodeDracoMesh(job.input);
  if (!mesh.ok()) return WithContext(mesh.status(), "input mesh");
  std::string().swap(job.input);  // the bytes are no longer needed
  if (absl::Status valid = ValidateMesh(*mesh); !valid.ok()) {
    return WithContext(valid, "input mesh");
  }
  const size_t num_faces = mesh->num_faces();
  if (spec.clusters() > num_faces) {
    return absl::InvalidArgumentError(absl::StrCat(
        "clusters: ", spec.clusters(), " is more than the mesh's ", num_faces, " faces"));
  }
  EmitProgress(events, "measures",
               absl::StrCat(num_faces, " faces, ", mesh->num_vertices(), " vertices"));
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(*mesh);
  if (!adjacency.ok()) return WithContext(adjacency.status(), "input mesh");
  std::string device_used;
  absl::StatusOr<FaceMeasures> measures = MeasureFaces(*mesh, spec, context, device_used);
  if (!measures.ok()) return measures.status();

  StreamingLevelSink sink(
      events, spec.batch_triplets() != 0 ? spec.batch_triplets() : context.default_batch_triplets,
      hierarchy ? spec.levels_high() : 0, hierarchy ? spec.levels_low() : 0);
  JobOutcome outcome;
  outcome.done.set_device(device_used);
  if (hierarchy) {
    const MeshProblem problem{&*mesh, &*adjacency, &*measures, plan->energy};
    EmitProgress(events, "cluster",
                 absl::StrCat(v1::Algorithm_Name(plan->algorithm), " (",
                              MeshEnergyName(plan->energy.kind), ")"));
    absl::StatusOr<MultilevelSummary> summary = RunMultilevel(problem, plan->multilevel, sink);
    if (!summary.ok()) return summary.status();
    if (!sink.started()) {
      return absl::FailedPreconditionError(
          absl::StrCat("levels: no level has a cluster count in [", spec.levels_low(), ", ",
                       spec.levels_high(), "]; the hierarchy ends at ", summary->final_clusters,
                       " clusters (one per connected component at the least)"));
    }
    if (absl::Status flushed = sink.Flush(); !flushed.ok()) return flushed;
    outcome.done.set_final_clusters(summary->final_clusters);
    for (uint32_t k : FindElbows(sink.curve_counts(), sink.curve_energies())) {
      outcome.done.add_elbow_cluster_counts(k);
    }
  } else {
    const MeshProblem problem{&*mesh, &*adjacency, &*measures, plan->energy};
    EmitProgress(events, "seed", absl::StrCat(spec.clusters(), " initial clusters"));
    absl::StatusOr<std::vector<ClusterId>> initial = InitialClusters(problem, plan->seeds);
    if (!initial.ok()) return initial.status();
    std::vector<ClusterId> labels = *initial;
    absl::StatusOr<OptimizeResult> result;
    if (plan->algorithm == v1::ALGORITHM_EMLO) {
      EmitProgress(events, "cluster",
                   absl::StrCat("EMLO (", MeshEnergyName(plan->energy.kind), ")"));
      EmloOptions options = plan->emlo;
      result = OptimizeEmlo(problem, labels, options);
    } else {
      EmitProgress(events, "cluster",
                   absl::StrCat("boundary-based (", MeshEnergyName(plan->energy.kind), ")"));
      BoundaryBasedOptions options = plan->boundary_based;
      options.on_iteration = [&](uint32_t iteration, double energy) {
        EmitProgress(events, "cluster", absl::StrCat("sweep ", iteration, ": energy ", energy));
      };
      result = OptimizeBoundaryBased(problem, labels, options);
    }
    if (!result.ok()) return result.status();
    if (events.cancelled()) return absl::CancelledError("the call was cancelled");
    MLCLUST_RETURN_IF_ERROR(StreamSingleLevel(*initial, result->initial_energy, labels,
                                              result->energy, spec.clusters(), sink));
    outcome.done.set_final_clusters(spec.clusters());
  }
  outcome.done.set_levels(sink.levels_sent());
  outcome.done.set_triplets(sink.triplets_sent());
  return outcome;
}

absl::StatusOr<JobOutcome> RunPointsJob(Job& job, const JobRunnerContext& context) {
  const v1::JobSpec& spec = job.spec;
  EventChannel& events = *job.events;
  absl::StatusOr<PointJobPlan> plan = PlanPointJob(spec);
  if (!plan.ok()) return plan.status();
  const bool hierarchy = plan->algorithm == v1::ALGORITHM_HC ||
                         plan->algorithm == v1::ALGORITHM_ML ||
                         plan->algorithm == v1::ALGORITHM_PML;
  if (!hierarchy && (spec.levels_high() != 0 || spec.levels_low() != 0)) {
    return absl::InvalidArgumentError(
        "levels: a level range applies to the hierarchies of HC, ML and PML only");
  }
  // m x d float32, little-endian, row-major.
  const uint32_t d = spec.point_dims();
  if (d == 0) return absl::InvalidArgumentError("point_dims: d = 0");
  if (job.input.size() % (size_t{4} * d) != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("points: ", job.input.size(), " bytes are not a whole number of ", d,
                     "-dimensional float32 points (", 4 * d, " bytes each)"));
  }
  PointSet points;
  points.dims = d;
  points.values.resize(job.input.size() / 4);
  std::memcpy(points.values.data(), job.input.data(), job.input.size());
  std::string().swap(job.input);
  if (absl::Status valid = ValidatePoints(points); !valid.ok()) return valid;
  if (spec.clusters() > points.num_points()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "clusters: ", spec.clusters(), " is more than the ", points.num_points(), " points"));
  }
  EmitProgress(events, "cluster",
               absl::StrCat(points.num_points(), " points in ", d,
                            " dimensions: ", v1::Algorithm_Name(plan->algorithm)));
  StreamingLevelSink sink(
      events, spec.batch_triplets() != 0 ? spec.batch_triplets() : context.default_batch_triplets,
      hierarchy ? spec.levels_high() : 0, hierarchy ? spec.levels_low() : 0);
  JobOutcome outcome;
  outcome.done.set_device("cpu");
  if (hierarchy) {
    // Every level also goes to the BIC's bookkeeping (O(1) per moved point), so the summary
    // names the BIC's choice over the whole hierarchy, whatever range is sent.
    BicLevelRecorder bic;
    TeeSink both(sink, bic);
    absl::StatusOr<PointMultilevelSummary> summary =
        RunPointMultilevel(points, plan->multilevel, both);
    if (!summary.ok()) return summary.status();
    if (!sink.started()) {
      return absl::FailedPreconditionError(
          absl::StrCat("levels: no level has a cluster count in [", spec.levels_low(), ", ",
                       spec.levels_high(), "]; the hierarchy starts at ", summary->start_clusters,
                       " voxel clusters (option grid) and ends at ", summary->final_clusters));
    }
    if (absl::Status flushed = sink.Flush(); !flushed.ok()) return flushed;
    outcome.done.set_final_clusters(summary->final_clusters);
    for (uint32_t k : FindElbows(sink.curve_counts(), sink.curve_energies())) {
      outcome.done.add_elbow_cluster_counts(k);
    }
    absl::StatusOr<BicChoice> choice = ChooseByBic(bic.levels(), bic.num_points(), d);
    if (!choice.ok()) return choice.status();
    outcome.done.set_bic_best_cluster_count(choice->best_k);
    outcome.done.set_bic_first_decrease_cluster_count(choice->first_decrease_k);
    outcome.done.set_bic_best(choice->bic[choice->best_level]);
  } else if (plan->algorithm == v1::ALGORITHM_KMEANS) {
    // Lloyd from k-means++ (or random) centres; level 0 is the assignment to the centres.
    KmeansOptions options;
    options.clusters = plan->clusters;
    options.seed = plan->seed;
    options.threads = plan->ln_kmeans.threads;
    options.max_iterations = plan->ln_kmeans.max_iterations;
    options.init = plan->kmeans_plus_plus ? KmeansOptions::Init::kKmeansPlusPlus
                                          : KmeansOptions::Init::kRandom;
    absl::StatusOr<std::vector<float>> centres =
        plan->kmeans_plus_plus
            ? KmeansPlusPlusCentres(points, plan->clusters, plan->seed, options.threads)
            : RandomPointCentres(points, plan->clusters, plan->seed);
    if (!centres.ok()) return centres.status();
    KmeansOptions once = options;
    once.max_iterations = 1;
    absl::StatusOr<KmeansResult> start = RunLloyd(points, *centres, once);
    if (!start.ok()) return start.status();
    absl::StatusOr<KmeansResult> result = RunLloyd(points, *centres, options);
    if (!result.ok()) return result.status();
    MLCLUST_RETURN_IF_ERROR(StreamSingleLevel(start->labels, start->inertia, result->labels,
                                              result->inertia, plan->clusters, sink));
  } else if (plan->grid_start) {
    // LN k-means from the voxel grid: level 0 is the voxel clusters, level 1 the result.
    absl::StatusOr<VoxelStart> start = VoxelGridStart(points, plan->grid);
    if (!start.ok()) return start.status();
    absl::StatusOr<LnKmeansResult> result =
        RunLnKmeansFromGrid(points, plan->grid, plan->ln_kmeans);
    if (!result.ok()) return result.status();
    MLCLUST_RETURN_IF_ERROR(StreamSingleLevel(start->labels, result->initial_energy, result->labels,
                                              result->energy, start->clusters, sink));
    outcome.done.set_final_clusters(start->clusters);
  } else {
    absl::StatusOr<std::vector<ClusterId>> initial = SeedPointClusters(
        points, plan->clusters, plan->kmeans_plus_plus, plan->seed, plan->ln_kmeans.threads);
    if (!initial.ok()) return initial.status();
    absl::StatusOr<LnKmeansResult> result = RunLnKmeans(points, *initial, plan->ln_kmeans);
    if (!result.ok()) return result.status();
    MLCLUST_RETURN_IF_ERROR(StreamSingleLevel(*initial, result->initial_energy, result->labels,
                                              result->energy, plan->clusters, sink));
    outcome.done.set_final_clusters(plan->clusters);
  }
  outcome.done.set_levels(sink.levels_sent());
  outcome.done.set_triplets(sink.triplets_sent());
  return outcome;
}

}  // namespace

absl::StatusOr<JobOutcome> RunJob(Job& job, const JobRunnerContext& context) {
  switch (job.spec.input_kind()) {
    case v1::INPUT_KIND_DRACO_MESH:
      return RunMeshJob(job, context);
    case v1::INPUT_KIND_POINTS_F32:
      return RunPointsJob(job, context);
    default:
      return absl::InvalidArgumentError(
          "spec.input_kind: unspecified (a Draco mesh or float32 points)");
  }
}

}  // namespace mlclust::server
