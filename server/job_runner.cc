#include "server/job_runner.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "core/base/status_macros.h"
#include "core/cluster/registry.h"
#include "core/hierarchy/elbow.h"
#include "core/hierarchy/model_selection.h"
#include "core/io/draco_codec.h"
#include "core/io/draco_peek.h"
#include "core/io/prepare_mesh.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "core/mesh/polygons.h"
#include "core/plan/device_policy.h"
#include "core/points/points.h"
#include "server/job_options.h"
#include "server/preview.h"

namespace mlclust::server {
namespace {

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

// Streams levels to the client as they are produced: the first level sent as a snapshot
// of all labels, later levels packed into LevelBatch messages of about `batch_triplets`
// triplets (many small levels per message; never one message per triplet), flushed at
// least every `max_delay` so a slow algorithm still shows progress.
//
// With a level range [low, high] (cluster counts; 0 = no bound) only levels in the range
// are sent: the sink follows the labels through the levels before it, and the first level
// in range goes out as the snapshot. It also keeps every level's cluster count and energy
// for the elbow of the summary.
//
// Progress: where `progress` is set, the sink reports how far the algorithm is (Progress
// .fraction of its "cluster" stage) at most every kProgressEvery and at the end: for a
// hierarchy the share of the merges (or, divisive, the splits undone) from level 0's count
// to `target_clusters`; for a single-level algorithm 1 once the result arrives.
class StreamingLevelSink : public LevelSink {
 public:
  StreamingLevelSink(EventChannel& events, uint32_t batch_triplets, uint32_t high = 0,
                     uint32_t low = 0)
      : events_(events),
        batch_triplets_(std::max<uint32_t>(1, batch_triplets)),
        high_(high),
        low_(low) {}

  // Reports fractions through `progress` (fraction, message); hierarchies run from level 0's
  // count to `target_clusters`.
  void ReportProgress(std::function<void(double, const std::string&)> progress, bool hierarchy,
                      uint32_t target_clusters) {
    progress_ = std::move(progress);
    hierarchy_ = hierarchy;
    target_clusters_ = target_clusters;
  }

  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override {
    start_clusters_ = cluster_count;
    last_progress_ = absl::Now();
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
    MaybeReportProgress(level.cluster_count);
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
    if (packed_) return AddPackedLevel(level);
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
    pending_triplets_ = 0;
    v1::JobEvent event = std::move(pending_);
    pending_.Clear();
    return Send(std::move(event));
  }

  // JobSpec.packed_triplets: triplets go as raw little-endian uint32 in LevelBatch's packed
  // fields (levels whole, as with the repeated fields; the result store cuts a batch over
  // its message limit, packed or not).
  void UsePackedTriplets() { packed_ = true; }

  uint32_t levels_sent() const { return levels_sent_; }
  uint64_t triplets_sent() const { return triplets_sent_; }
  bool started() const { return started_; }
  std::span<const uint32_t> curve_counts() const { return curve_counts_; }
  std::span<const double> curve_energies() const { return curve_energies_; }

  // The engine may stop above the target (one cluster per connected component): the end.
  void ReportProgressDone() {
    if (!progress_ || reported_done_ || curve_counts_.empty()) return;
    reported_done_ = true;
    progress_(1, absl::StrCat(curve_counts_.size() - 1, " levels, ", curve_counts_.back(),
                              " clusters: done"));
  }

 private:
  static constexpr int kMaxLevelsPerBatch = 16384;
  static constexpr size_t kSnapshotLabels = size_t{1} << 20;
  static constexpr absl::Duration kMaxDelay = absl::Milliseconds(200);
  static constexpr absl::Duration kProgressEvery = absl::Milliseconds(250);

  static void AppendPacked(std::string* bytes, std::span<const uint32_t> values) {
    static_assert(std::endian::native == std::endian::little,
                  "packed triplets are little-endian uint32");
    const size_t old_size = bytes->size();
    bytes->resize(old_size + values.size_bytes());
    if (!values.empty()) std::memcpy(bytes->data() + old_size, values.data(), values.size_bytes());
  }

  absl::Status AddPackedLevel(const LevelMoves& level) {
    v1::LevelBatch* batch = pending_.mutable_levels();
    if (batch->cluster_count_size() == 0) {
      batch->set_first_level(levels_sent_);
      const size_t reserve = std::min<size_t>(batch_triplets_, size_t{1} << 18) * 4;
      batch->mutable_packed_element()->reserve(reserve);
      batch->mutable_packed_to_cluster()->reserve(reserve);
      batch->mutable_packed_from_cluster()->reserve(reserve);
    }
    batch->add_cluster_count(level.cluster_count);
    batch->add_energy(level.energy);
    batch->add_source_level(level.level);
    AppendPacked(batch->mutable_packed_element(), level.element);
    AppendPacked(batch->mutable_packed_to_cluster(), level.to_cluster);
    AppendPacked(batch->mutable_packed_from_cluster(), level.from_cluster);
    pending_triplets_ += level.element.size();
    batch->add_triplet_end(static_cast<uint32_t>(pending_triplets_));
    ++levels_sent_;
    triplets_sent_ += level.element.size();
    if (pending_triplets_ >= batch_triplets_ || batch->cluster_count_size() >= kMaxLevelsPerBatch ||
        absl::Now() - last_flush_ > kMaxDelay) {
      return Flush();
    }
    return absl::OkStatus();
  }

  bool InRange(uint32_t count) const { return (high_ == 0 || count <= high_) && count >= low_; }

  void MaybeReportProgress(uint32_t count) {
    if (!progress_) return;
    double fraction = 1;
    if (hierarchy_) {
      const double span = std::abs(static_cast<double>(start_clusters_) - target_clusters_);
      fraction =
          span == 0
              ? 1
              : std::clamp(std::abs(static_cast<double>(start_clusters_) - count) / span, 0.0, 1.0);
    }
    const absl::Time now = absl::Now();
    if (fraction < 1 && now - last_progress_ < kProgressEvery) return;
    if (fraction >= 1 && reported_done_) return;
    reported_done_ = fraction >= 1;
    last_progress_ = now;
    progress_(fraction, absl::StrCat(curve_counts_.size() - 1, " levels, ", count, " clusters"));
  }

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
  bool packed_ = false;
  size_t pending_triplets_ = 0;  // in pending_, packed only
  uint32_t levels_sent_ = 0;
  uint64_t triplets_sent_ = 0;
  absl::Time last_flush_;
  std::function<void(double, const std::string&)> progress_;
  bool hierarchy_ = false;
  uint32_t target_clusters_ = 1;
  uint32_t start_clusters_ = 0;
  bool reported_done_ = false;
  absl::Time last_progress_;
};

// Progress.fraction: how far the stage is, 0 at its start (and where not known), 1 at its end.
void EmitProgress(EventChannel& events, const std::string& stage, const std::string& message,
                  const std::string& device, double fraction = 0) {
  v1::JobEvent event;
  event.mutable_progress()->set_stage(stage);
  event.mutable_progress()->set_message(message);
  event.mutable_progress()->set_device(device);
  event.mutable_progress()->set_fraction(fraction);
  events.Emit(std::move(event));
}

absl::Status WithContext(const absl::Status& status, absl::string_view what) {
  return absl::Status(status.code(), absl::StrCat(what, ": ", status.message()));
}

// The device each stage ran on, in the order the stages started (Done.devices): every
// stage's Progress goes through Note, so what Done says is what the events said.
class StagesRan {
 public:
  void Note(const StagePlan& stage, const DeviceCaps& caps) {
    const std::string device = StageDeviceName(stage, caps);
    for (auto& [name, ran] : stages_) {
      if (name == stage.name()) {
        ran = device;
        return;
      }
    }
    stages_.emplace_back(stage.name(), device);
  }

  // Done.devices, and Done.device for clients before it: the renderer where any stage ran
  // on the GPU, else "cpu".
  void WriteTo(v1::Done& done) const {
    std::string any = "cpu";
    for (const auto& [name, device] : stages_) {
      v1::StageRan* ran = done.add_devices();
      ran->set_stage(name);
      ran->set_device(device);
      if (device != "cpu") any = device;
    }
    done.set_device(any);
  }

 private:
  std::vector<std::pair<std::string, std::string>> stages_;
};

// Progress for a stage of the plan, noted in `ran`.
void EmitStage(EventChannel& events, StagesRan& ran, const StagePlan& stage, const DeviceCaps& caps,
               const std::string& message, double fraction = 0) {
  ran.Note(stage, caps);
  EmitProgress(events, stage.name(), message, StageDeviceName(stage, caps), fraction);
}

// The job's first Progress (stage "plan") where the plan has something to say: each stage
// the job asked on the GPU, or that auto moved off it, with why it is on the CPU.
void EmitPlanNotes(EventChannel& events, const JobPlan& plan, const DeviceCaps& caps) {
  std::vector<std::string> notes;
  for (const StagePlan& stage : plan.stages) {
    if (!stage.why.empty()) notes.push_back(absl::StrCat(stage.name(), " on the CPU: ", stage.why));
  }
  if (notes.empty()) return;
  for (const StagePlan& stage : plan.stages) {
    if (stage.device == StageDevice::kGpu) {
      notes.push_back(absl::StrCat(stage.name(), " on ", StageDeviceName(stage, caps)));
    }
  }
  EmitProgress(events, "plan", absl::StrJoin(notes, "; "), "");
}

// Progress events for the run functions' stages, naming the device each runs on; the GPU
// stages (over the worker's GL context) where the plan puts a stage on the GPU.
RunContext MakeRunContext(const Job& job, const DeviceCaps& caps, DeviceStages* devices,
                          StagesRan& ran) {
  EventChannel& events = *job.events;
  RunContext run;
  run.cancel = job.cancel_flag();
  run.devices = devices;
  run.on_stage = [&events, &ran, caps](const StagePlan& stage, const std::string& message) {
    EmitStage(events, ran, stage, caps, message);
  };
  run.on_fraction = [&events, &ran, caps](const StagePlan& stage, double fraction,
                                          const std::string& message) {
    EmitStage(events, ran, stage, caps, message, fraction);
  };
  return run;
}

// The device limits for the input as read (a mesh's faces, known only once decoded): the
// policy's FitDevicesToInput, and a "plan" Progress for each stage it moved to the CPU.
absl::Status FitPlanToInput(EventChannel& events, const DeviceCaps& caps, const InputShape& input,
                            JobPlan& plan) {
  const std::vector<StagePlan> before = plan.stages;
  MLCLUST_RETURN_IF_ERROR(FitDevicesToInput(caps, input, plan));
  for (size_t i = 0; i < plan.stages.size(); ++i) {
    if (plan.stages[i].device != before[i].device) {
      EmitProgress(events, "plan",
                   absl::StrCat(plan.stages[i].name(), " on the CPU: ", plan.stages[i].why), "");
    }
  }
  return absl::OkStatus();
}

StreamingLevelSink MakeSink(const Job& job, const JobPlan& plan, const JobRunnerContext& context,
                            const DeviceCaps& caps) {
  const v1::JobSpec& spec = job.spec;
  const bool hierarchy = plan.algorithm->hierarchy;
  StreamingLevelSink sink(
      *job.events,
      spec.batch_triplets() != 0 ? spec.batch_triplets() : context.default_batch_triplets,
      hierarchy ? spec.levels_high() : 0, hierarchy ? spec.levels_low() : 0);
  // Detached jobs' levels go to the result store's record, which reads the repeated fields.
  if (spec.packed_triplets() && !spec.detach()) sink.UsePackedTriplets();
  // The hierarchy's far end: one cluster for a divisive one, else the lowest count asked for
  // (the engine may stop above it: one cluster per connected component).
  const uint32_t target =
      plan.algorithm->divisive ? 1 : std::max<uint32_t>({1, spec.clusters(), spec.levels_low()});
  const StagePlan* cluster = FindStage(plan, PlanStage::kCluster);
  const std::string device = cluster != nullptr ? StageDeviceName(*cluster, caps) : "cpu";
  EventChannel* events = job.events.get();
  sink.ReportProgress(
      [events, device](double fraction, const std::string& message) {
        EmitProgress(*events, "cluster", message, device, fraction);
      },
      hierarchy, target);
  return sink;
}

// Meshes: section 4.4's elbow, the end of a (near) zero plateau (shape identification,
// where the right energy stays zero up to the true number of shapes). Points: ours, any jump
// of the curve (the variance is never near zero; chapter 6 chooses K by the BIC).
void AddElbows(const StreamingLevelSink& sink, v1::Done& done, ElbowOptions::Rule rule) {
  ElbowOptions options;
  options.rule = rule;
  for (uint32_t k : FindElbows(sink.curve_counts(), sink.curve_energies(), options)) {
    done.add_elbow_cluster_counts(k);
  }
}

absl::StatusOr<JobOutcome> RunMeshJob(Job& job, JobPlan& plan, const JobRunnerContext& context) {
  const v1::JobSpec& spec = job.spec;
  const DeviceCaps& caps = context.device;
  EventChannel& events = *job.events;
  StagesRan ran;
  EmitProgress(events, "decode", absl::StrCat("decoding ", job.input.size(), " bytes"), "cpu", 0);
  // Decode (faces in the client's order where the payload carries face ids), then the one
  // set-up path (core/mesh/prepared_mesh.h): validate, adjacency, measures -- the measures
  // on the device the plan's "measures" stage names.
  absl::StatusOr<DecodedDracoMesh> decoded = DecodeDracoMeshWithFaceIds(job.input);
  if (!decoded.ok()) return WithContext(decoded.status(), "input mesh");
  std::string().swap(job.input);  // the bytes are no longer needed
  InputShape shape;
  shape.elements = decoded->mesh.num_faces();
  shape.vertices = decoded->mesh.num_vertices();
  shape.polygons = spec.polygon_triangle_counts_size() > 0;
  MLCLUST_RETURN_IF_ERROR(FitPlanToInput(events, caps, shape, plan));
  const StagePlan measures_stage = *FindStage(plan, PlanStage::kMeasures);
  const bool gpu_measures = measures_stage.device == StageDevice::kGpu;
  const std::string measures_note = absl::StrCat(
      decoded->mesh.num_faces(), " faces, ", decoded->mesh.num_vertices(), " vertices; ",
      decoded->has_face_ids ? "faces put back in order by the face id attribute"
                            : "faces in the decoded order");
  PrepareMeshOptions options;
  options.cancel = job.cancel_flag();
  if (gpu_measures) {
    options.measure_faces = [&](const TriangleMesh& mesh, const std::atomic<bool>* /*cancel*/) {
      EmitStage(events, ran, measures_stage, caps, measures_note, 0);
      return context.devices->MeasureFaces(mesh);
    };
  }
  absl::StatusOr<PreparedMesh> ready = PrepareMesh(std::move(decoded->mesh), options);
  if (!ready.ok()) {
    // Errors of the GPU measures carry their own context ("face measures on the GPU: ...").
    return gpu_measures && ready.status().code() != absl::StatusCode::kInvalidArgument
               ? ready.status()
               : WithContext(ready.status(), "input mesh");
  }
  PreparedMesh prepared = *std::move(ready);
  EmitStage(events, ran, measures_stage, caps, measures_note, 1);
  const size_t num_faces = prepared.mesh.num_faces();
  if (plan.clusters > num_faces) {
    return absl::InvalidArgumentError(absl::StrCat(
        "clusters: ", plan.clusters, " is more than the mesh's ", num_faces, " faces"));
  }
  // Per-polygon clustering (JobSpec.polygon_triangle_counts, issue 13).
  std::optional<MeshPolygons> polygons;
  if (spec.polygon_triangle_counts_size() > 0) {
    absl::StatusOr<MeshPolygons> made =
        MakeMeshPolygons(std::span<const uint32_t>(spec.polygon_triangle_counts().data(),
                                                   spec.polygon_triangle_counts().size()),
                         prepared.adjacency);
    if (!made.ok()) return WithContext(made.status(), "spec.polygon_triangle_counts");
    polygons = *std::move(made);
    if (plan.clusters > polygons->num_polygons()) {
      return absl::InvalidArgumentError(absl::StrCat("clusters: ", plan.clusters,
                                                     " is more than the mesh's ",
                                                     polygons->num_polygons(), " polygons"));
    }
    EmitStage(events, ran, measures_stage, caps,
              absl::StrCat(polygons->num_polygons(), " polygons: each one element"), 1);
  }

  StreamingLevelSink sink = MakeSink(job, plan, context, caps);
  // The preview (JobSpec.preview) follows every level to the one it draws.
  LevelSink* run_sink = &sink;
  std::optional<PreviewLevelSink> preview_levels;
  std::optional<TeeSink> with_preview;
  if (spec.has_preview()) {
    preview_levels.emplace(spec.preview().cluster_count());
    run_sink = &with_preview.emplace(sink, *preview_levels);
  }
  MeshProblem problem{&prepared.mesh, &prepared.adjacency, &prepared.measures, plan.mesh_energy};
  if (polygons.has_value()) problem.polygons = &*polygons;
  absl::StatusOr<RunSummary> summary = plan.algorithm->run_mesh(
      problem, plan, *run_sink, MakeRunContext(job, caps, context.devices, ran));
  if (!summary.ok()) return summary.status();
  if (!sink.started()) {
    return absl::FailedPreconditionError(
        absl::StrCat("levels: no level has a cluster count in [", spec.levels_low(), ", ",
                     spec.levels_high(), "]; the hierarchy ends at ", summary->final_clusters,
                     " clusters (one per connected component at the least)"));
  }
  MLCLUST_RETURN_IF_ERROR(sink.Flush());
  sink.ReportProgressDone();
  JobOutcome outcome;
  if (preview_levels.has_value()) {
    EmitProgress(
        events, "preview",
        absl::StrCat("drawing the level with ", preview_levels->cluster_count(), " clusters"),
        caps.renderer);
    const absl::Time preview_start = absl::Now();
    absl::StatusOr<v1::Preview> preview =
        RenderPreview(context.gl, caps.renderer, prepared.mesh, prepared.adjacency, *preview_levels,
                      spec.preview());
    if (!preview.ok()) return preview.status();
    outcome.done.set_seconds_preview(absl::ToDoubleSeconds(absl::Now() - preview_start));
    v1::JobEvent event;
    *event.mutable_preview() = *std::move(preview);
    if (!events.Emit(std::move(event))) return absl::CancelledError("the call was cancelled");
  }
  ran.WriteTo(outcome.done);
  outcome.done.set_final_clusters(summary->final_clusters);
  if (plan.algorithm->hierarchy) {
    AddElbows(sink, outcome.done, ElbowOptions::Rule::kEndOfZeroPlateau);
  }
  outcome.done.set_levels(sink.levels_sent());
  outcome.done.set_triplets(sink.triplets_sent());
  return outcome;
}

absl::StatusOr<JobOutcome> RunPointsJob(Job& job, JobPlan& plan, const JobRunnerContext& context) {
  const v1::JobSpec& spec = job.spec;
  const DeviceCaps& caps = context.device;
  StagesRan ran;
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
  if (plan.clusters > points.num_points()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "clusters: ", plan.clusters, " is more than the ", points.num_points(), " points"));
  }
  InputShape shape;
  shape.elements = points.num_points();
  shape.dims = d;
  MLCLUST_RETURN_IF_ERROR(FitPlanToInput(*job.events, caps, shape, plan));
  StreamingLevelSink sink = MakeSink(job, plan, context, caps);
  JobOutcome outcome;
  const RunContext run = MakeRunContext(job, caps, context.devices, ran);
  if (plan.algorithm->hierarchy) {
    // Every level also goes to the BIC's bookkeeping (O(1) per moved point), so the summary
    // names the BIC's choice over the whole hierarchy, whatever range is sent.
    BicLevelRecorder bic;
    TeeSink both(sink, bic);
    absl::StatusOr<RunSummary> summary = plan.algorithm->run_points(points, plan, both, run);
    if (!summary.ok()) return summary.status();
    if (!sink.started()) {
      return absl::FailedPreconditionError(
          absl::StrCat("levels: no level has a cluster count in [", spec.levels_low(), ", ",
                       spec.levels_high(), "]; the hierarchy starts at ", summary->start_clusters,
                       " voxel clusters (option grid) and ends at ", summary->final_clusters));
    }
    MLCLUST_RETURN_IF_ERROR(sink.Flush());
    sink.ReportProgressDone();
    outcome.done.set_final_clusters(summary->final_clusters);
    AddElbows(sink, outcome.done, ElbowOptions::Rule::kAnyJump);
    absl::StatusOr<BicChoice> choice = ChooseByBic(bic.levels(), bic.num_points(), d);
    if (!choice.ok()) return choice.status();
    outcome.done.set_bic_best_cluster_count(choice->best_k);
    outcome.done.set_bic_first_decrease_cluster_count(choice->first_decrease_k);
    outcome.done.set_bic_merging_first_decrease_cluster_count(choice->merging_first_decrease_k);
    outcome.done.set_bic_best(choice->bic[choice->best_level]);
  } else {
    absl::StatusOr<RunSummary> summary = plan.algorithm->run_points(points, plan, sink, run);
    if (!summary.ok()) return summary.status();
    MLCLUST_RETURN_IF_ERROR(sink.Flush());
    sink.ReportProgressDone();
    outcome.done.set_final_clusters(summary->final_clusters);
  }
  ran.WriteTo(outcome.done);
  outcome.done.set_levels(sink.levels_sent());
  outcome.done.set_triplets(sink.triplets_sent());
  return outcome;
}

}  // namespace

absl::StatusOr<JobPlan> PlanJobOnDevice(const v1::JobSpec& spec, const DeviceCaps& device) {
  MLCLUST_ASSIGN_OR_RETURN(JobPlan plan, PlanWireJob(spec));
  InputShape shape;
  shape.polygons = spec.polygon_triangle_counts_size() > 0;
  if (spec.input_kind() == v1::INPUT_KIND_POINTS_F32 && spec.point_dims() > 0) {
    shape.dims = spec.point_dims();
    shape.elements = spec.input_bytes() / (uint64_t{4} * spec.point_dims());
  }
  MLCLUST_RETURN_IF_ERROR(PlanDevices(device, shape, plan));
  return plan;
}

void DescribeInput(const v1::JobSpec& spec, std::string_view input, v1::Accepted& accepted) {
  if (spec.input_kind() != v1::INPUT_KIND_DRACO_MESH) return;
  const DracoPayloadFacts facts = PeekDracoPayload(input);
  accepted.set_face_ids(facts.names_face_ids);
  accepted.set_face_order(DescribeFaceOrder(facts));
  accepted.set_draco_method(facts.method);
}

absl::Status CheckSpecIsConsistent(const v1::JobSpec& spec) {
  if (spec.input_kind() != v1::INPUT_KIND_POINTS_F32) return absl::OkStatus();
  if (spec.point_dims() == 0) {
    return absl::InvalidArgumentError(
        "spec.point_dims: d = 0 (float32 points need their dimension)");
  }
  const uint64_t point_bytes = uint64_t{4} * spec.point_dims();
  if (spec.input_bytes() % point_bytes != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "spec.input_bytes: ", spec.input_bytes(), " bytes are not a whole number of ",
        spec.point_dims(), "-dimensional float32 points (", point_bytes, " bytes each)"));
  }
  if (spec.has_preview()) {
    return absl::InvalidArgumentError("preview: only for meshes (a picture of the clusters)");
  }
  return absl::OkStatus();
}

absl::Status CheckPayloadAgainstSpec(const v1::JobSpec& spec, std::string_view input) {
  if (spec.input_kind() != v1::INPUT_KIND_DRACO_MESH) return absl::OkStatus();
  const DracoPayloadFacts facts = PeekDracoPayload(input);
  if (!facts.is_draco) {
    return absl::InvalidArgumentError(
        "input mesh: the payload does not start with a Draco header (\"DRACO\", bytes 0-4), "
        "and spec.input_kind is INPUT_KIND_DRACO_MESH");
  }
  if (!facts.is_mesh) {
    return absl::InvalidArgumentError(
        "input mesh: the Draco header (byte 7, the geometry type) says a point cloud, and "
        "spec.input_kind is INPUT_KIND_DRACO_MESH (a triangle mesh)");
  }
  if (facts.names_face_ids && facts.method == "sequential") {
    return absl::InvalidArgumentError(absl::StrCat(
        "input mesh: the Draco header (byte 8, the encoder method) says sequential and the "
        "metadata names the '",
        kDracoFaceIdAttributeName,
        "' attribute, which needs an edgebreaker payload; a sequential one keeps the face "
        "order without it (send it without the attribute)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<JobOutcome> RunJob(Job& job, const JobRunnerContext& context) {
  const v1::InputKind kind = job.spec.input_kind();
  if (kind != v1::INPUT_KIND_DRACO_MESH && kind != v1::INPUT_KIND_POINTS_F32) {
    return absl::InvalidArgumentError(
        "spec.input_kind: unspecified (a Draco mesh or float32 points)");
  }
  absl::StatusOr<JobPlan> plan =
      job.plan.has_value() ? *job.plan : PlanJobOnDevice(job.spec, context.device);
  if (!plan.ok()) return plan.status();
  if (job.spec.has_preview()) {
    // Refused before the job runs, not after.
    if (kind != v1::INPUT_KIND_DRACO_MESH) {
      return absl::InvalidArgumentError("preview: only for meshes (a picture of the clusters)");
    }
    MLCLUST_RETURN_IF_ERROR(CheckPreviewRequest(job.spec.preview()).status());
    if (context.gl == nullptr) {
      return absl::FailedPreconditionError(
          "preview: drawing needs the server's GL context, and this server has none (no EGL "
          "device or platform gave OpenGL 4.5, or the server runs with the GPU off)");
    }
  }
  if (UsesGpu(*plan) && context.devices == nullptr) {
    // The lane is the plan's (device_policy.h LaneFor): a worker without GPU stages never
    // takes a job planned for the GPU.
    return absl::FailedPreconditionError(
        "the plan puts a stage on the GPU but this worker has no GPU stages");
  }
  EmitPlanNotes(*job.events, *plan, context.device);
  if (kind == v1::INPUT_KIND_DRACO_MESH) return RunMeshJob(job, *plan, context);
  return RunPointsJob(job, *plan, context);
}

}  // namespace mlclust::server
