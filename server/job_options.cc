#include "server/job_options.h"

#include <algorithm>
#include <set>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/base/status_macros.h"

namespace mlclust::server {
namespace {

// Reads typed values from JobSpec.options and remembers which names were used, so that
// unknown names can be refused instead of silently ignored.
class OptionReader {
 public:
  explicit OptionReader(const google::protobuf::Map<std::string, std::string>& options)
      : options_(options) {}

  absl::Status Double(const std::string& name, double& value, double low, double high) {
    const std::string* text = Find(name);
    if (text == nullptr) return absl::OkStatus();
    double parsed;
    if (!absl::SimpleAtod(*text, &parsed) || !(parsed >= low && parsed <= high)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "option ", name, ": '", *text, "' is not a number in [", low, ", ", high, "]"));
    }
    value = parsed;
    return absl::OkStatus();
  }

  template <typename Int>
  absl::Status Integer(const std::string& name, Int& value, Int low, Int high) {
    const std::string* text = Find(name);
    if (text == nullptr) return absl::OkStatus();
    int64_t parsed;
    if (!absl::SimpleAtoi(*text, &parsed) || parsed < static_cast<int64_t>(low) ||
        parsed > static_cast<int64_t>(high)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "option ", name, ": '", *text, "' is not an integer in [", low, ", ", high, "]"));
    }
    value = static_cast<Int>(parsed);
    return absl::OkStatus();
  }

  absl::Status Choice(const std::string& name, const std::vector<std::string>& choices,
                      std::string& value) {
    const std::string* text = Find(name);
    if (text == nullptr) return absl::OkStatus();
    for (const std::string& choice : choices) {
      if (*text == choice) {
        value = choice;
        return absl::OkStatus();
      }
    }
    return absl::InvalidArgumentError(absl::StrCat(
        "option ", name, ": '", *text, "' is not one of ", absl::StrJoin(choices, ", ")));
  }

  // INVALID_ARGUMENT for names no reader asked for.
  absl::Status CheckAllUsed(absl::string_view algorithm) const {
    for (const auto& [name, value] : options_) {
      if (used_.count(name) == 0) {
        return absl::InvalidArgumentError(
            absl::StrCat("option ", name, " is not known for ", algorithm));
      }
    }
    return absl::OkStatus();
  }

 private:
  const std::string* Find(const std::string& name) {
    used_.insert(name);
    auto it = options_.find(name);
    return it == options_.end() ? nullptr : &it->second;
  }

  const google::protobuf::Map<std::string, std::string>& options_;
  std::set<std::string> used_;
};

}  // namespace

absl::StatusOr<MeshEnergyKind> MeshEnergyFromWire(v1::Energy energy) {
  switch (energy) {
    case v1::ENERGY_UNSPECIFIED:
    case v1::ENERGY_CVD:
      return MeshEnergyKind::kCvd;
    case v1::ENERGY_CVD_ADAPTIVE:
      return MeshEnergyKind::kCvdAdaptive;
    case v1::ENERGY_MWCVD_AREA:
      return MeshEnergyKind::kMwcvdArea;
    case v1::ENERGY_MWCVD_VARIANCE:
      return MeshEnergyKind::kMwcvdVariance;
    case v1::ENERGY_MWCVD_MAX:
      return MeshEnergyKind::kMwcvdMax;
    case v1::ENERGY_PLANAR:
      return MeshEnergyKind::kPlanar;
    case v1::ENERGY_SPHERE:
      return MeshEnergyKind::kSphere;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("energy: ", v1::Energy_Name(energy), " is not a mesh energy"));
  }
}

namespace {

absl::StatusOr<MeshEnergyOptions> ReadEnergyOptions(const v1::JobSpec& spec, OptionReader& reader) {
  MeshEnergyOptions energy;
  absl::StatusOr<MeshEnergyKind> kind = MeshEnergyFromWire(spec.energy());
  if (!kind.ok()) return kind.status();
  energy.kind = *kind;
  std::string density;  // not given: the energy's own (ResolveDensityOptions)
  if (absl::Status s = reader.Choice("density", {"power", "linear"}, density); !s.ok()) return s;
  if (!density.empty()) {
    energy.density.mapping =
        density == "linear" ? DensityOptions::Mapping::kLinear : DensityOptions::Mapping::kPower;
  }
  for (absl::Status s : {
           reader.Double("gamma", energy.density.gamma, 1e-6, 100),
           reader.Double("delta", energy.density.delta, 1e-12, 100),
           reader.Double("rho-max", energy.density.rho_max, 1.000001, 1e6),
           reader.Double("mwcvd-p", energy.mwcvd_p, 1, 64),
           reader.Double("planar-tolerance", energy.planar_tolerance, 0, 0.5),
       }) {
    if (!s.ok()) return s;
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(energy));
  return energy;
}

}  // namespace

absl::StatusOr<MeshEnergyOptions> PlanMeshEnergy(const v1::JobSpec& spec) {
  OptionReader reader(spec.options());
  return ReadEnergyOptions(spec, reader);
}

absl::StatusOr<MeshJobPlan> PlanMeshJob(const v1::JobSpec& spec) {
  MeshJobPlan plan;
  plan.algorithm =
      spec.algorithm() == v1::ALGORITHM_UNSPECIFIED ? v1::ALGORITHM_HC : spec.algorithm();
  const std::string algorithm_name = v1::Algorithm_Name(plan.algorithm);
  OptionReader reader(spec.options());
  absl::StatusOr<MeshEnergyOptions> energy = ReadEnergyOptions(spec, reader);
  if (!energy.ok()) return energy.status();
  plan.energy = *energy;

  switch (plan.algorithm) {
    case v1::ALGORITHM_HC:
    case v1::ALGORITHM_ML:
    case v1::ALGORITHM_PML: {
      MultilevelOptions& ml = plan.multilevel;
      ml.min_clusters = std::max<uint32_t>({1, spec.clusters(), spec.levels_low()});
      if (plan.algorithm == v1::ALGORITHM_HC) {
        ml.optimizer = MultilevelOptions::Optimizer::kNone;
      } else {
        std::string optimizer = "emlo";
        if (absl::Status s = reader.Choice("optimizer", {"emlo", "bb", "none"}, optimizer);
            !s.ok()) {
          return s;
        }
        ml.optimizer = optimizer == "bb"     ? MultilevelOptions::Optimizer::kBoundaryBased
                       : optimizer == "none" ? MultilevelOptions::Optimizer::kNone
                                             : MultilevelOptions::Optimizer::kEmlo;
        std::string guard = "on";
        if (absl::Status s = reader.Choice("guard", {"on", "off"}, guard); !s.ok()) return s;
        ml.connectivity_guard = guard == "on";
        MLCLUST_RETURN_IF_ERROR(reader.Double("p-percent", ml.p_percent, 0, 100));
      }
      if (plan.algorithm == v1::ALGORITHM_PML) {
        ml.parallel = true;
        MLCLUST_RETURN_IF_ERROR(reader.Integer<uint32_t>("pml-until", ml.pml_until, 0, 1u << 31));
        MLCLUST_RETURN_IF_ERROR(reader.Integer<int>("threads", ml.threads, 0, 1024));
      }
      if (spec.levels_high() != 0 && spec.levels_high() < spec.levels_low()) {
        return absl::InvalidArgumentError(absl::StrCat("levels: the high end ", spec.levels_high(),
                                                       " is below the low end ",
                                                       spec.levels_low()));
      }
      break;
    }
    case v1::ALGORITHM_EMLO:
    case v1::ALGORITHM_BB: {
      if (spec.clusters() < 1) {
        return absl::InvalidArgumentError(
            absl::StrCat("clusters: ", algorithm_name, " needs k >= 1 clusters"));
      }
      plan.seeds.clusters = spec.clusters();
      plan.seeds.seed = spec.seed();
      std::string init = "lneigh";
      if (absl::Status s = reader.Choice("init", {"lneigh", "random"}, init); !s.ok()) return s;
      plan.seeds.method =
          init == "random" ? SeedOptions::Method::kRandom : SeedOptions::Method::kLNeighbourhood;
      MLCLUST_RETURN_IF_ERROR(reader.Integer<uint32_t>("level", plan.seeds.level, 0, 1u << 20));
      std::string guard = "on";
      if (absl::Status s = reader.Choice("guard", {"on", "off"}, guard); !s.ok()) return s;
      plan.emlo.connectivity_guard = guard == "on";
      plan.boundary_based.connectivity_guard = guard == "on";
      if (plan.algorithm == v1::ALGORITHM_BB) {
        MLCLUST_RETURN_IF_ERROR(
            reader.Integer<int>("threads", plan.boundary_based.threads, 0, 1024));
        MLCLUST_RETURN_IF_ERROR(reader.Integer<uint32_t>(
            "max-iterations", plan.boundary_based.max_iterations, 1, 1000000));
      }
      break;
    }
    default:
      return absl::UnimplementedError(
          absl::StrCat("algorithm ", algorithm_name,
                       " is not available for meshes on this server yet (available: ALGORITHM_HC, "
                       "ALGORITHM_EMLO, ALGORITHM_BB)"));
  }
  MLCLUST_RETURN_IF_ERROR(reader.CheckAllUsed(algorithm_name));
  return plan;
}

absl::StatusOr<PointJobPlan> PlanPointJob(const v1::JobSpec& spec) {
  PointJobPlan plan;
  plan.algorithm =
      spec.algorithm() == v1::ALGORITHM_UNSPECIFIED ? v1::ALGORITHM_ML : spec.algorithm();
  const std::string algorithm_name = v1::Algorithm_Name(plan.algorithm);
  if (spec.energy() != v1::ENERGY_UNSPECIFIED && spec.energy() != v1::ENERGY_VARIANCE) {
    return absl::InvalidArgumentError(absl::StrCat(
        "energy: ", v1::Energy_Name(spec.energy()),
        " is a mesh energy; points use the within-cluster variance (ENERGY_VARIANCE)"));
  }
  OptionReader reader(spec.options());
  plan.seed = spec.seed();
  switch (plan.algorithm) {
    case v1::ALGORITHM_HC:
    case v1::ALGORITHM_ML:
    case v1::ALGORITHM_PML: {
      PointMultilevelOptions& ml = plan.multilevel;
      ml.min_clusters = std::max<uint32_t>({1, spec.clusters(), spec.levels_low()});
      MLCLUST_RETURN_IF_ERROR(reader.Integer<uint32_t>("grid", ml.grid, 0, 1u << 20));
      MLCLUST_RETURN_IF_ERROR(reader.Integer<int>("threads", ml.threads, 0, 1024));
      if (plan.algorithm == v1::ALGORITHM_HC) {
        ml.optimizer = PointMultilevelOptions::Optimizer::kNone;
      } else {
        std::string optimizer = "lnkmeans";
        if (absl::Status s = reader.Choice("optimizer", {"lnkmeans", "none"}, optimizer); !s.ok()) {
          return s;
        }
        ml.optimizer = optimizer == "none" ? PointMultilevelOptions::Optimizer::kNone
                                           : PointMultilevelOptions::Optimizer::kLnKmeans;
      }
      if (plan.algorithm == v1::ALGORITHM_PML) {
        ml.parallel = true;
        MLCLUST_RETURN_IF_ERROR(reader.Integer<uint32_t>("pml-until", ml.pml_until, 0, 1u << 31));
        std::string pairs = "cheaper-half";
        if (absl::Status s = reader.Choice("pml-pairs", {"cheaper-half", "all"}, pairs); !s.ok()) {
          return s;
        }
        ml.pml_pairs = pairs == "all" ? PointMultilevelOptions::PmlPairs::kAll
                                      : PointMultilevelOptions::PmlPairs::kCheaperHalf;
      }
      if (spec.levels_high() != 0 && spec.levels_high() < spec.levels_low()) {
        return absl::InvalidArgumentError(absl::StrCat("levels: the high end ", spec.levels_high(),
                                                       " is below the low end ",
                                                       spec.levels_low()));
      }
      break;
    }
    case v1::ALGORITHM_KMEANS:
    case v1::ALGORITHM_LN_KMEANS: {
      std::string init = "kmeans++";
      const bool ln = plan.algorithm == v1::ALGORITHM_LN_KMEANS;
      if (absl::Status s = reader.Choice("init",
                                         ln ? std::vector<std::string>{"kmeans++", "random", "grid"}
                                            : std::vector<std::string>{"kmeans++", "random"},
                                         init);
          !s.ok()) {
        return s;
      }
      plan.kmeans_plus_plus = init == "kmeans++";
      plan.grid_start = init == "grid";
      MLCLUST_RETURN_IF_ERROR(reader.Integer<uint32_t>("grid", plan.grid, 0, 1u << 20));
      if (plan.grid_start && spec.clusters() != 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "clusters: init grid starts from one cluster per occupied voxel (option grid); ",
            spec.clusters(), " clusters cannot be asked for with it"));
      }
      if (!plan.grid_start && spec.clusters() < 1) {
        return absl::InvalidArgumentError(
            absl::StrCat("clusters: ", algorithm_name, " needs k >= 1 clusters"));
      }
      if (!plan.grid_start && plan.grid != 0) {
        return absl::InvalidArgumentError("grid: applies to init grid (and the hierarchies)");
      }
      plan.clusters = spec.clusters();
      MLCLUST_RETURN_IF_ERROR(reader.Integer<int>("threads", plan.ln_kmeans.threads, 0, 1024));
      MLCLUST_RETURN_IF_ERROR(
          reader.Integer<uint32_t>("max-iterations", plan.ln_kmeans.max_iterations, 1, 1000000));
      break;
    }
    default:
      return absl::UnimplementedError(
          absl::StrCat("algorithm ", algorithm_name,
                       " is not available for points on this server yet (available: ALGORITHM_HC, "
                       "ALGORITHM_ML, ALGORITHM_PML, ALGORITHM_LN_KMEANS)"));
  }
  MLCLUST_RETURN_IF_ERROR(reader.CheckAllUsed(algorithm_name));
  return plan;
}

}  // namespace mlclust::server
