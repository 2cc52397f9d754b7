// `mlclust mesh`: reads a mesh, sends it (Draco), receives every level and writes the
// outputs of the level chosen (labels, PLY, coarse mesh, preview, plot, JSON summary).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/clustered_mesh_file.h"
#include "client/commands.h"
#include "client/job_cli.h"
#include "client/meshlets_command.h"
#include "client/polygons.h"
#include "core/base/status_macros.h"
#include "core/cluster/planar_merging.h"
#include "core/coarsening/coarsening.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"
#include "core/io/prepare_mesh.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/repair.h"
#include "server/preview.h"

namespace mlclust::cli {
namespace {

// Exit code of a mesh job whose other outputs were written but whose --coarse failed.
constexpr int kExitCoarseFailed = 3;

// The outputs given on the command line, as "--labels L.txt, --ply P.ply" (those in `names`).
std::string OutputList(const Arguments& args, std::initializer_list<const char*> names) {
  std::vector<std::string> given;
  for (const char* name : names) {
    if (args.has(name)) given.push_back(absl::StrCat("--", name, " ", args.get(name)));
  }
  return given.empty() ? "none" : absl::StrJoin(given, ", ");
}

// The level nearest to `level` (by cluster count; the larger count on a tie) whose labels
// coarsen, among the levels of other counts, trying at most `max_tries`; nullopt if none.
std::optional<uint32_t> NearestCoarsening(const HierarchyLog& log, size_t level,
                                          const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                          const CoarseningOptions& options, int max_tries) {
  const int64_t k = log.cluster_count(level);
  std::map<uint32_t, size_t> last_with;  // count -> the last level with it
  for (size_t l = 0; l < log.num_levels(); ++l) last_with[log.cluster_count(l)] = l;
  std::vector<std::pair<uint32_t, size_t>> candidates(last_with.begin(), last_with.end());
  std::sort(candidates.begin(), candidates.end(), [k](const auto& a, const auto& b) {
    const int64_t da = std::abs(static_cast<int64_t>(a.first) - k);
    const int64_t db = std::abs(static_cast<int64_t>(b.first) - k);
    return da != db ? da < db : a.first > b.first;
  });
  int tries = 0;
  for (const auto& [count, candidate] : candidates) {
    if (count == k) continue;
    if (++tries > max_tries) break;
    absl::StatusOr<std::vector<ClusterId>> labels = log.LabelsAt(candidate);
    if (labels.ok() && CoarsenMesh(mesh, adjacency, *labels, options).ok()) return count;
  }
  return std::nullopt;
}

// --preview FILE.png [--preview-size WxH]: the server draws the level --clusters K chooses
// (the last level without K) and sends it as a Preview event.
absl::Status SetPreview(const Arguments& args, uint32_t clusters, v1::JobSpec& spec) {
  if (!args.has("preview")) {
    for (const char* name : {"preview-size", "preview-view"}) {
      if (args.has(name)) {
        return absl::InvalidArgumentError(absl::StrCat("--", name, " needs --preview FILE.png"));
      }
    }
    return absl::OkStatus();
  }
  if (args.get("preview").empty()) return absl::InvalidArgumentError("--preview: no file name");
  v1::PreviewRequest* preview = spec.mutable_preview();
  preview->set_cluster_count(clusters);
  if (args.has("preview-size")) {
    MLCLUST_ASSIGN_OR_RETURN(const auto size,
                             server::ParsePreviewSize(args.get("preview-size"), "--preview-size"));
    preview->set_width(size.first);
    preview->set_height(size.second);
  }
  if (args.has("preview-view")) {
    MLCLUST_ASSIGN_OR_RETURN(const auto view,
                             server::ParsePreviewView(args.get("preview-view"), "--preview-view"));
    preview->set_azimuth_degrees(view.first);
    preview->set_elevation_degrees(view.second);
  }
  return absl::OkStatus();
}

absl::Status WritePreview(const std::string& path, const v1::Preview& preview) {
  if (preview.png().empty()) {
    return absl::DataLossError("--preview: the server sent no preview");
  }
  std::ofstream out(path, std::ios::binary);
  out.write(preview.png().data(), static_cast<std::streamsize>(preview.png().size()));
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("--preview: cannot write ", path));
  return absl::OkStatus();
}

int RunMesh(const Arguments& args) {
  if (args.has("meshlets")) return RunMeshMeshlets(args);  // client/meshlets_command.h
  if (args.positional().size() != 1) {
    return Fail(absl::InvalidArgumentError("mesh: give exactly one INPUT file"));
  }
  const std::string& input_path = args.positional()[0];
  absl::StatusOr<uint64_t> clusters = args.GetUint("clusters", 0, UINT32_MAX);
  if (!clusters.ok()) return Fail(clusters.status());
  // --auto-k elbow: the level K is the first elbow of the energy curve (section 4.4).
  const std::string auto_k = args.get("auto-k", "");
  if (!auto_k.empty() && auto_k != "elbow") {
    return Fail(absl::InvalidArgumentError(
        "--auto-k for meshes must be elbow (section 4.4; the BIC is for points)"));
  }
  if (!auto_k.empty() && *clusters > 0) {
    return Fail(absl::InvalidArgumentError("give --clusters K or --auto-k elbow, not both"));
  }
  if (!auto_k.empty() && args.has("preview")) {
    return Fail(absl::InvalidArgumentError(
        "--preview needs --clusters K: the server draws the level before --auto-k chooses it"));
  }
  if ((args.has("labels") || args.has("ply") || args.has("out")) && *clusters == 0 &&
      auto_k.empty()) {
    return Fail(absl::InvalidArgumentError(
        "--labels, --ply and --out need --clusters K (K >= 1) or --auto-k elbow"));
  }
  if (absl::Status s = client::CheckClusteredMeshOutputs(args.value("out"), args.value("ply"));
      !s.ok()) {
    return Fail(s);
  }
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  absl::StatusOr<const AlgorithmInfo*> algorithm = GetAlgorithm(args, InputKind::kMesh);
  if (!algorithm.ok()) return Fail(algorithm.status());
  const std::string algo = (*algorithm)->name;
  const bool hierarchy = (*algorithm)->hierarchy;
  spec.set_algorithm(static_cast<v1::Algorithm>((*algorithm)->wire));
  if (absl::Status status = SetEnergy(args, InputKind::kMesh, spec); !status.ok()) {
    return Fail(status);
  }
  if (!hierarchy && *clusters == 0) {
    return Fail(absl::InvalidArgumentError(absl::StrCat("--clusters: ", algo, " needs K >= 1")));
  }
  if (!auto_k.empty() && !hierarchy) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--auto-k needs a hierarchy (--algo ml, pml or hc), not ", algo)));
  }
  if (!hierarchy) spec.set_clusters(static_cast<uint32_t>(*clusters));
  if (absl::Status status = SetLevels(args, hierarchy, spec); !status.ok()) return Fail(status);
  absl::StatusOr<uint64_t> seed = args.GetUint("seed", 1);
  if (!seed.ok()) return Fail(seed.status());
  spec.set_seed(*seed);
  SetOptions(args, InputKind::kMesh, spec);
  const std::string placement = args.get("coarse-placement", "centroid");
  if (placement != "centroid" && placement != "qem") {
    return Fail(absl::InvalidArgumentError("--coarse-placement must be centroid or qem"));
  }
  if (args.has("coarse") && *clusters == 0 && auto_k.empty()) {
    return Fail(absl::InvalidArgumentError("--coarse needs --clusters K (K >= 1) or --auto-k"));
  }
  // --planar-merge DEG: a post-pass over the level written, for a planar clustering.
  double planar_merge_degrees = -1;
  if (args.has("planar-merge")) {
    if (!absl::SimpleAtod(args.get("planar-merge"), &planar_merge_degrees) ||
        !(planar_merge_degrees >= 0 && planar_merge_degrees <= 180)) {
      return Fail(absl::InvalidArgumentError(absl::StrCat(
          "--planar-merge: '", args.get("planar-merge"), "' is not an angle in [0, 180] degrees")));
    }
    const EnergyInfo* energy = FindEnergyByWire(InputKind::kMesh, spec.energy());
    const std::string energy_name = energy != nullptr ? energy->name : (*algorithm)->energies[0];
    if (energy_name != "planar") {
      return Fail(absl::InvalidArgumentError(
          absl::StrCat("--planar-merge merges the clusters of a planar clustering (--energy "
                       "planar, or --algo vsa); this job's energy is ",
                       energy_name)));
    }
    if (*clusters == 0) {
      return Fail(absl::InvalidArgumentError("--planar-merge needs --clusters K (K >= 1)"));
    }
  }
  if (args.has("per-polygon") && *clusters == 0) {
    return Fail(absl::InvalidArgumentError("--per-polygon needs --clusters K (K >= 1)"));
  }
  const std::string upload = args.get("upload", "sequential");
  if (upload != "auto" && upload != "sequential" && upload != "edgebreaker") {
    return Fail(absl::InvalidArgumentError("--upload must be auto, sequential or edgebreaker"));
  }
  absl::StatusOr<uint64_t> quantize = args.GetUint("quantize", 0, 30);
  if (!quantize.ok()) return Fail(quantize.status());
  spec.set_device(args.get("device", "auto"));
  spec.set_label(input_path);
  if (absl::Status status = SetPreview(args, static_cast<uint32_t>(*clusters), spec);
      !status.ok()) {
    return Fail(status);
  }

  // The mesh is read locally (its faces are the ids of every output) and sent compressed;
  // a .drc file is sent as it is.
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(input_path);
  if (!mesh.ok()) return Fail(mesh.status());
  if (*clusters > mesh->num_faces()) {
    return Fail(absl::InvalidArgumentError(absl::StrCat(
        "--clusters: ", *clusters, " is more than the mesh's ", mesh->num_faces(), " faces")));
  }
  std::vector<uint32_t> polygon_triangles;  // --per-polygon: triangles of each polygon
  bool polygons_sent = false;               // --per-polygon: the server clusters whole polygons
  if (args.has("per-polygon")) {
    absl::StatusOr<std::vector<uint32_t>> counts = client::ReadPolygonTriangleCounts(input_path);
    if (!counts.ok()) return Fail(counts.status());
    polygon_triangles = *std::move(counts);
    polygons_sent = client::ServerClustersPolygons((*algorithm)->name);
    if (polygons_sent) {
      for (uint32_t count : polygon_triangles) spec.add_polygon_triangle_counts(count);
    }
  }
  // --repair: the mesh sent (and coarsened) has its non-manifold edges and vertices split;
  // faces keep their ids, so labels, --ply (the input's vertices) and --plot are unchanged.
  std::optional<TriangleMesh> repaired;
  if (args.has("repair")) {
    absl::StatusOr<MeshRepairResult> repair = RepairNonManifold(*mesh);
    if (!repair.ok()) {
      return Fail(absl::Status(repair.status().code(),
                               absl::StrCat("--repair: ", repair.status().message())));
    }
    std::fprintf(stderr, "mlclust: --repair: %s\n", repair->report.Summary().c_str());
    if (repair->report.changed()) repaired = std::move(repair->mesh);
  }
  const TriangleMesh& sent = repaired.has_value() ? *repaired : *mesh;
  // The upload: a .drc file as it is (unless repaired); otherwise Draco: sequential (the
  // default: the server sees the mesh exactly as read), or edgebreaker with the per-face id
  // attribute (--upload edgebreaker; auto: where the mesh passes the server's checks, so
  // that sequential lets the server name what is wrong).
  std::string upload_method = "file";
  absl::StatusOr<std::string> payload;
  if (absl::EndsWithIgnoreCase(input_path, ".drc") && !repaired.has_value()) {
    payload = ReadFileBytes(input_path);
  } else {
    DracoEncodeOptions encode;
    encode.position_quantization_bits = static_cast<int>(*quantize);
    const bool edgebreaker =
        upload == "edgebreaker" || (upload == "auto" && ValidateMesh(sent).ok());
    if (edgebreaker) {
      encode.method = DracoMethod::kEdgebreaker;
      encode.write_face_ids = true;
    }
    upload_method = edgebreaker ? "edgebreaker+face-ids" : "sequential";
    payload = EncodeMeshToDraco(sent, encode);
  }
  if (!payload.ok()) return Fail(payload.status());
  if (args.has("detach")) return Detach(args, spec, *payload);

  double seconds = 0;
  v1::Accepted accepted;
  absl::StatusOr<client::JobResult> result =
      RunOnServer(args, spec, *payload, &seconds, &accepted,
                  auto_k.empty() ? static_cast<uint32_t>(*clusters) : 0);
  if (!result.ok()) return Fail(result.status());
  const HierarchyLog& log = result->hierarchy;
  const EnergyInfo* job_energy = FindEnergyByWire(InputKind::kMesh, spec.energy());
  const std::string energy_name =
      job_energy != nullptr ? job_energy->name : (*algorithm)->energies[0];
  if (absl::Status s =
          WriteLevelOutputs(args, *result, mesh->num_faces(), "faces",
                            absl::StrCat(std::filesystem::path(input_path).filename().string(),
                                         ": ", algo, ", ", energy_name, " energy"));
      !s.ok()) {
    return Fail(s);
  }
  std::string elbow_note;
  if (auto_k == "elbow") {
    if (result->done.elbow_cluster_counts().empty()) {
      return Fail(absl::NotFoundError(
          "--auto-k elbow: the energy curve has no elbow by section 4.4's definition (the "
          "energy stays near zero up to the true number of shapes, then jumps); this one "
          "rises steadily, as when the energy does not fit the model's shapes exactly: choose "
          "--clusters K (--plot FILE.png shows the curve)"));
    }
    clusters = result->done.elbow_cluster_counts(0);
    elbow_note = absl::StrCat("; --auto-k: the first elbow, ", *clusters, " clusters");
  }
  std::string level_note;
  std::optional<size_t> chosen_level;
  std::string coarse_error;
  std::optional<uint32_t> coarse_nearest;
  std::string post_pass_json;  // --planar-merge and --per-polygon in the JSON summary
  if (*clusters > 0) {
    absl::StatusOr<size_t> level = ChooseLevel(log, static_cast<uint32_t>(*clusters));
    if (!level.ok()) return Fail(level.status());
    absl::StatusOr<std::vector<ClusterId>> labels = LabelsOfLevel(*result, *level);
    if (!labels.ok()) return Fail(labels.status());
    std::vector<uint32_t> compact = client::CompactLabels(*labels);
    std::string merge_note;
    if (planar_merge_degrees >= 0) {
      std::vector<ClusterId> level_ids(compact.begin(), compact.end());
      PlanarMergingOptions merging;
      merging.max_angle_degrees = planar_merge_degrees;
      absl::StatusOr<PlanarMergingResult> merged = MergePlanarClusters(sent, level_ids, merging);
      if (!merged.ok()) {
        return Fail(absl::Status(merged.status().code(),
                                 absl::StrCat("--planar-merge: ", merged.status().message())));
      }
      compact = client::CompactLabels(merged->labels);
      merge_note =
          absl::StrFormat("; planar merge (Delta_merging %g deg): %u -> %u clusters",
                          planar_merge_degrees, merged->input_clusters, merged->output_clusters);
      absl::StrAppend(&post_pass_json, R"(, "planar_merge": {"degrees": )",
                      JsonNumber(planar_merge_degrees),
                      ", \"clusters_before\": ", merged->input_clusters,
                      ", \"clusters_after\": ", merged->output_clusters, "}");
    }
    std::vector<uint32_t> written = compact;  // what --labels writes
    if (args.has("per-polygon")) {
      std::vector<ClusterId> face_ids(compact.begin(), compact.end());
      absl::StatusOr<client::PolygonLabels> polygons =
          client::LabelsPerPolygon(*mesh, polygon_triangles, face_ids);
      if (!polygons.ok()) return Fail(polygons.status());
      compact = client::CompactLabels(polygons->per_face);
      written.clear();
      size_t first = 0;
      for (uint32_t count : polygon_triangles) {
        written.push_back(compact[first]);
        first += count;
      }
      // The energy of the labels written, from its definition (as `mlclust energy`).
      absl::StatusOr<MeshEnergyOptions> energy_options = EnergyFromArguments(args, energy_name);
      if (!energy_options.ok()) return Fail(energy_options.status());
      absl::StatusOr<PreparedMesh> prepared = PrepareMesh(sent);
      if (!prepared.ok()) return Fail(prepared.status());
      std::vector<ClusterId> labels_now(compact.begin(), compact.end());
      const double energy =
          WithMeshEnergy(*energy_options, prepared->mesh, prepared->measures,
                         [&](const auto& e) { return EnergyFromProxies(e, labels_now); });
      // No polygon split: the server clustered whole polygons; otherwise this was the
      // post-pass (an algorithm the server runs per triangle only, or an older server).
      const bool in_algorithms = polygons_sent && polygons->split_polygons == 0;
      if (polygons_sent && !in_algorithms) {
        std::fprintf(stderr,
                     "mlclust: --per-polygon: the server split %u polygons (it predates "
                     "JobSpec.polygon_triangle_counts); each went to the cluster of most of "
                     "its area instead\n",
                     polygons->split_polygons);
      }
      absl::StrAppend(&post_pass_json, R"(, "per_polygon": {"polygons": )",
                      polygon_triangles.size(),
                      ", \"in_algorithms\": ", in_algorithms ? "true" : "false",
                      ", \"split_polygons\": ", polygons->split_polygons,
                      ", \"clusters\": ", *std::max_element(compact.begin(), compact.end()) + 1,
                      ", \"energy\": ", JsonNumber(energy), "}");
      const uint32_t polygon_clusters = *std::max_element(compact.begin(), compact.end()) + 1;
      merge_note = absl::StrCat(
          merge_note,
          in_algorithms
              ? absl::StrFormat("; per polygon: %zu polygons, each one element of the "
                                "clustering (none split): %u clusters, energy %.10g",
                                polygon_triangles.size(), polygon_clusters, energy)
              : absl::StrFormat("; per polygon: %zu polygons, %u were split and went to the "
                                "cluster of most of their area: %u clusters, energy %.10g",
                                polygon_triangles.size(), polygons->split_polygons,
                                polygon_clusters, energy));
    }
    if (args.has("labels")) {
      if (absl::Status s = WriteLabels(args.get("labels"), written); !s.ok()) return Fail(s);
    }
    std::vector<ClusterId> ids(compact.size());
    for (size_t i = 0; i < compact.size(); ++i) ids[i] = ClusterId(compact[i]);
    if (args.has("ply")) {
      if (absl::Status s = WriteClusteredPly(args.get("ply"), *mesh, ids); !s.ok()) {
        return Fail(s);
      }
    }
    if (args.has("out")) {
      if (absl::Status s = client::WriteClusteredMesh(args.get("out"), *mesh, ids); !s.ok()) {
        return Fail(s);
      }
    }
    if (args.has("coarse")) {
      CoarseningOptions options;
      options.placement = placement == "qem" ? CoarseningOptions::Placement::kQuadric
                                             : CoarseningOptions::Placement::kCentroid;
      // Adaptive CVD and MWCVD place a cluster's vertex at its density-weighted centroid
      // sum rho A g / sum rho A (l. 783, 937), with the densities the job's energy used;
      // the other energies (uniform CVD: l. 715) at sum A g / sum A (empty density).
      absl::StatusOr<MeshEnergyOptions> energy_options = EnergyFromArguments(args, energy_name);
      if (!energy_options.ok()) return Fail(energy_options.status());
      const std::vector<double> face_density =
          EnergyFaceDensity(*energy_options, sent, ComputeFaceMeasures(sent));
      options.face_density = face_density;
      absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(sent);
      if (!adjacency.ok()) return Fail(adjacency.status());
      absl::StatusOr<TriangleMesh> coarse = CoarsenMesh(sent, *adjacency, ids, options);
      if (coarse.status().code() == absl::StatusCode::kFailedPrecondition) {
        // This level has no coarse mesh (small K): the other outputs stand; say which, and
        // the nearest level that coarsens (among the levels received, without a merge).
        coarse_error = std::string(coarse.status().message());
        if (planar_merge_degrees < 0) {
          coarse_nearest = NearestCoarsening(log, *level, sent, *adjacency, options, 32);
        }
      } else if (!coarse.ok()) {
        return Fail(coarse.status());
      } else if (absl::Status s = WriteMeshFile(args.get("coarse"), *coarse); !s.ok()) {
        return Fail(s);
      }
    }
    level_note = absl::StrFormat("%s; level %zu: %u clusters, energy %.10g%s", elbow_note, *level,
                                 log.cluster_count(*level), log.energy(*level), merge_note);
    chosen_level = *level;
  }
  std::string preview_note;
  if (args.has("preview")) {
    const v1::Preview& preview = result->preview;
    if (absl::Status s = WritePreview(args.get("preview"), preview); !s.ok()) return Fail(s);
    preview_note = absl::StrFormat("; preview %ux%u of %u clusters in %.3f s: %s", preview.width(),
                                   preview.height(), preview.cluster_count(),
                                   result->done.seconds_preview(), args.get("preview"));
  }
  if (args.has("json")) {
    std::string json = SummaryJson(
        args, input_path, "faces", mesh->num_faces(), **algorithm, spec, log, seconds, result->done,
        chosen_level, auto_k,
        coarse_error.empty() ? std::set<std::string>{} : std::set<std::string>{"coarse"});
    // The upload, and --coarse's failure (its file is then not among the outputs).
    json.pop_back();
    absl::StrAppend(&json, R"(, "upload": {"method": )", JsonString(upload_method),
                    ", \"bytes\": ", payload->size(), ", \"quantization_bits\": ", *quantize,
                    ", \"face_ids\": ", accepted.face_ids() ? "true" : "false",
                    ", \"face_order\": ", JsonString(accepted.face_order()), "}");
    absl::StrAppend(&json, post_pass_json);
    if (!coarse_error.empty()) {
      absl::StrAppend(&json, ", \"coarse_error\": ", JsonString(coarse_error),
                      ", \"coarse_nearest_clusters\": ",
                      coarse_nearest.has_value() ? absl::StrCat(*coarse_nearest) : "null");
    }
    std::printf("%s}\n", json.c_str());
  } else {
    std::printf("%s: %zu faces, %zu levels, %zu triplets in %.3f s %s (%s)%s%s%s\n",
                input_path.c_str(), mesh->num_faces(), log.num_levels(), log.num_moves(), seconds,
                DevicesSummary(result->done).c_str(), args.has("server") ? "remote" : "embedded",
                level_note.c_str(), ElbowNote(result->done).c_str(), preview_note.c_str());
  }
  if (!coarse_error.empty()) {
    std::fprintf(
        stderr,
        "mlclust: --coarse %s: not written: this level has no coarse mesh: %s\n"
        "  written: %s\n  %s\n",
        args.get("coarse").c_str(), coarse_error.c_str(),
        OutputList(args, {"labels", "levels-csv", "ply", "out", "plot", "preview"}).c_str(),
        coarse_nearest.has_value()
            ? absl::StrCat("the nearest level that coarsens has ", *coarse_nearest,
                           " clusters: --clusters ", *coarse_nearest)
                  .c_str()
            : (hierarchy ? "no level near it coarsens (32 tried): try a larger --clusters"
                         : "try a larger --clusters"));
    return kExitCoarseFailed;
  }
  return 0;
}

}  // namespace

Command MeshCommand() {
  std::vector<Flag> own = {
      EnergyFlag(InputKind::kMesh, "the algorithm's first below", /*wire_only=*/true),
      {"clusters", "K",
       "the level written by --labels, --out, --ply and --coarse (for single-level algorithms the "
       "number of clusters to compute); at most the mesh's faces",
       'k'},
      {"auto-k", "elbow",
       "instead of --clusters, for hierarchies: the level at the first elbow of the energy "
       "curve (section 4.4: the end of a near-zero plateau, e.g. a cube's 6 sides with --energy "
       "planar); an error where the curve has none"},
      {"labels", "FILE", "one line per input face: its cluster (0..K-1) at that level", 'o'},
      {"levels-csv", "FILE", "a row \"clusters,energy\" per level received"},
      {"out", "FILE",
       "the mesh with the clusters of that level, the format by FILE's extension: .ply (an "
       "integer `cluster` face property and a colour per face), .glb or .gltf (the `_CLUSTER` "
       "vertex attribute and COLOR_0), .obj (a group `g cluster_K` per run of faces of one "
       "cluster); another extension is refused before the job runs"},
      {"ply", "FILE",
       "the mesh with one colour per cluster at that level and an integer `cluster` face "
       "property (a .ply name: --out chooses the format by extension)"},
      {"coarse", "FILE",
       "the coarse mesh of that level: one vertex per cluster, a triangle where three clusters "
       "meet (format by extension: .ply, .obj, .off). A level that has no coarse mesh (small "
       "K: a cluster that is not a disc, too few clusters around a handle) ends with exit code "
       "3, after the other outputs are written; the message names them and the nearest K whose "
       "level coarsens."},
      {"coarse-placement", "centroid|qem", "where coarse vertices go (default centroid)"},
      {"planar-merge", "DEG",
       "after a planar clustering (--energy planar, --algo vsa): merge neighbouring clusters "
       "whose normals (eq. 3.37) differ by less than DEG degrees, Delta_merging of section 3.3.2 "
       "(l. 1285, Fig. 3.17c: 1); the smallest angle first, normals recomputed after each merge "
       "(ours: the text gives no order). --labels, --ply and --coarse get the merged clusters."},
      {"repair", "",
       "split non-manifold edges and vertices before sending (say what was changed); face ids "
       "stay the input's"},
      {"plot", "FILE.png",
       "the energy of every level received against its clusters (log axes; the energy's linear "
       "where it spans under three decades), the elbows (section 4.4) and the level written "
       "marked, the input's file name as title"},
      {"per-polygon", "",
       "OFF/OBJ input with quads or n-gons: a polygon's triangles stay in one cluster and "
       "--labels writes one line per polygon. ml, hc, pml, emlo and bb cluster whole polygons "
       "on the server (ours: JobSpec.polygon_triangle_counts, on the CPU); other algorithms, or "
       "a server that splits polygons (one older than that field), get a post-pass: each "
       "polygon to the cluster of most of its area, the energy recomputed"},
      {"upload", "sequential|edgebreaker|auto",
       "how the mesh travels (Draco). sequential (default) keeps the face order by itself. "
       "edgebreaker carries a per-face id attribute, by which the server puts the faces back in "
       "the input's order (fandisk: 87,751 bytes lossless against 112,679; 25,933 with "
       "--quantize 14): labels map back exactly and HC's levels are the same, but a face's "
       "corners may come back rotated and the vertices renumbered, which changes the order "
       "EMLO, BB and ML visit neighbours, so their results differ from a sequential upload's "
       "(the same algorithm on a renumbered mesh: not the same labels). auto: edgebreaker where "
       "the mesh passes the server's checks (edgebreaker would drop degenerate faces and split "
       "non-manifold vertices unseen), else sequential"},
      {"quantize", "BITS",
       "Draco position quantisation (0 = lossless float32, the default: the server's energies "
       "are those of the input; 11-14 make uploads several times smaller, at positions moved "
       "by up to 2^-BITS of the box)"},
      {"preview", "FILE.png",
       "a picture of that level (without --clusters: the last level; the server's level, "
       "before --planar-merge), drawn by the server's GL context: a three-quarter view, one "
       "colour per cluster, dark lines between clusters"},
      {"preview-size", "WxH", "its size in pixels (default 1024x768; each side 16 to 4096)"},
      {"preview-view", "AZ,EL",
       "the camera in degrees (default 35,25: from the right of +z, above; 215,25 looks from "
       "the other side)"}};
  for (Flag& flag : MeshletFlags()) own.push_back(std::move(flag));
  return {
      {"mesh",
       "INPUT [--server ADDR] [--algo ALGO] [--energy E] [--clusters K]\n"
       "                     [--labels FILE] [--levels-csv FILE] [--out FILE.ply|glb|gltf|obj]\n"
       "                     [--coarse FILE]\n"
       "                     [--preview FILE.png [--preview-size WxH] [--preview-view AZ,EL]]\n"
       "                     [--device auto|gpu|cpu] [--quiet] [--json] [algorithm and energy "
       "options]\n"
       "  mlclust mesh INPUT --meshlets FILE [--max-vertices 64] [--max-triangles 124] "
       "[--labels FILE]",
       "Clusters the mesh INPUT (OBJ, PLY, OFF, STL, glTF/GLB, ... or a .drc sent as is) and "
       "receives every level. Without --server the server runs inside this process.",
       JobFlagGroups(InputKind::kMesh, own)},
      RunMesh};
}

}  // namespace mlclust::cli
