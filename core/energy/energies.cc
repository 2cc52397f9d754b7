#include "core/energy/energies.h"

#include <algorithm>
#include <numeric>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"

namespace mlclust {

// ---------------------------------------------------------------------------------------
// CVD sums.

CvdSums CvdFaceSums(double area, const Vec3& centroid, const Vec3& origin) {
  const Vec3 g = centroid - origin;
  return {area, g * area, area * SquaredNorm(g)};
}

double CvdEnergyDirect(const FaceMeasures& measures, std::span<const ClusterId> labels) {
  struct Accumulator {
    double area = 0;
    Vec3 weighted_centroid;
  };
  absl::flat_hash_map<ClusterId, Accumulator> clusters;
  for (size_t j = 0; j < labels.size(); ++j) {
    Accumulator& c = clusters[labels[j]];
    c.area += measures.area[j];
    c.weighted_centroid += measures.centroid[j] * measures.area[j];
  }
  double energy = 0;
  for (size_t j = 0; j < labels.size(); ++j) {
    const Accumulator& c = clusters[labels[j]];
    if (c.area <= 0) continue;
    energy += measures.area[j] * SquaredNorm(measures.centroid[j] - c.weighted_centroid / c.area);
  }
  return energy;
}

Vec3 CentroidBoxCentre(const FaceMeasures& measures) {
  if (measures.num_faces() == 0) return {};
  Vec3 lo = measures.centroid[0], hi = lo;
  for (const Vec3& g : measures.centroid) {
    lo = {std::min(lo.x, g.x), std::min(lo.y, g.y), std::min(lo.z, g.z)};
    hi = {std::max(hi.x, g.x), std::max(hi.y, g.y), std::max(hi.z, g.z)};
  }
  return (lo + hi) * 0.5;
}

// ---------------------------------------------------------------------------------------
// Density.

std::vector<double> ComputeFaceDensity(const TriangleMesh& mesh, const FaceMeasures& measures,
                                       const DensityOptions& options) {
  const size_t num_faces = mesh.num_faces();
  const size_t num_vertices = mesh.num_vertices();
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  // rho'_f: mean |n_f - n_g| over the distinct faces g != f around f's three vertices.
  std::vector<double> raw(num_faces, 0.0);
  std::vector<uint32_t> ring;
  for (uint32_t f = 0; f < num_faces; ++f) {
    ring.clear();
    for (int c = 0; c < 3; ++c) {
      for (uint32_t g : table.faces_around(mesh.indices[3 * size_t{f} + c])) {
        if (g != f) ring.push_back(g);
      }
    }
    std::sort(ring.begin(), ring.end());
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
    if (ring.empty()) continue;
    double sum = 0;
    for (uint32_t g : ring) sum += Norm(measures.unit_normal[f] - measures.unit_normal[g]);
    raw[f] = sum / static_cast<double>(ring.size());
  }
  std::vector<double> density(num_faces);
  if (options.mapping == DensityOptions::Mapping::kPower) {
    for (size_t f = 0; f < num_faces; ++f) {
      density[f] = std::pow(raw[f] + options.delta, options.gamma);
    }
  } else {
    const auto [lo, hi] = std::minmax_element(raw.begin(), raw.end());
    const double span = num_faces == 0 ? 0 : *hi - *lo;
    for (size_t f = 0; f < num_faces; ++f) {
      density[f] = span > 0 ? 1.0 + (raw[f] - *lo) / span * (options.rho_max - 1.0) : 1.0;
    }
  }
  return density;
}

// ---------------------------------------------------------------------------------------
// CVD.

CvdEnergy::CvdEnergy(const FaceMeasures& measures, std::span<const double> density)
    : origin_(CentroidBoxCentre(measures)) {
  face_sums_.resize(measures.num_faces());
  for (size_t f = 0; f < face_sums_.size(); ++f) {
    const double mass = measures.area[f] * (density.empty() ? 1.0 : density[f]);
    face_sums_[f] = CvdFaceSums(mass, measures.centroid[f], origin_);
  }
}

CvdEnergy::Proxy CvdEnergy::FitProxy(const Sums& sums) const {
  return sums.area > 0 ? sums.weighted_centroid / sums.area : Vec3{};
}

// ---------------------------------------------------------------------------------------
// MWCVD.

MwcvdEnergy::Sums& MwcvdEnergy::Sums::operator+=(const Sums& o) {
  cvd += o.cvd;
  count += o.count;
  density_area += o.density_area;
  density += o.density;
  density_squared += o.density_squared;
  density_power += o.density_power;
  return *this;
}

MwcvdEnergy::Sums& MwcvdEnergy::Sums::operator-=(const Sums& o) {
  cvd -= o.cvd;
  count -= o.count;
  density_area -= o.density_area;
  density -= o.density;
  density_squared -= o.density_squared;
  density_power -= o.density_power;
  return *this;
}

MwcvdEnergy::MwcvdEnergy(const FaceMeasures& measures, std::span<const double> density,
                         Weight weight, double p)
    : weight_(weight), p_(p) {
  const Vec3 origin = CentroidBoxCentre(measures);
  face_sums_.resize(measures.num_faces());
  for (size_t f = 0; f < face_sums_.size(); ++f) {
    const double rho = density.empty() ? 1.0 : density[f];
    Sums& s = face_sums_[f];
    s.cvd = CvdFaceSums(measures.area[f], measures.centroid[f], origin);
    s.count = 1;
    s.density_area = rho * measures.area[f];
    s.density = rho;
    s.density_squared = rho * rho;
    s.density_power = std::pow(rho, p_);
  }
}

double MwcvdEnergy::ClusterWeight(const Sums& sums) const {
  switch (weight_) {
    case Weight::kArea:
      return std::max(0.0, sums.density_area);
    case Weight::kVariance:
      if (sums.count <= 0) return 1.0;
      return 1.0 + std::max(0.0, sums.density_squared - sums.density * sums.density / sums.count);
    case Weight::kMax:
    default:
      return std::pow(std::max(0.0, sums.density_power), 1.0 / p_);
  }
}

MwcvdEnergy::Proxy MwcvdEnergy::FitProxy(const Sums& sums) const {
  Proxy proxy;
  proxy.centroid = sums.cvd.area > 0 ? sums.cvd.weighted_centroid / sums.cvd.area : Vec3{};
  proxy.weight = ClusterWeight(sums);
  return proxy;
}

// ---------------------------------------------------------------------------------------
// Planar.

PlanarEnergy::PlanarEnergy(const FaceMeasures& measures) {
  face_sums_.resize(measures.num_faces());
  for (size_t f = 0; f < face_sums_.size(); ++f) {
    face_sums_[f] = {measures.area[f], measures.unit_normal[f] * measures.area[f]};
  }
}

PlanarEnergy::Proxy PlanarEnergy::FitProxy(const Sums& sums) const {
  const double length = Norm(sums.weighted_normal);
  return length > 0 ? sums.weighted_normal / length : Vec3{0, 0, 1};
}

// ---------------------------------------------------------------------------------------
// Sphere.

SphereEnergy::Sums& SphereEnergy::Sums::operator+=(const Sums& o) {
  area += o.area;
  weighted_centroid += o.weighted_centroid;
  weighted_normal += o.weighted_normal;
  weighted_dot += o.weighted_dot;
  weighted_square += o.weighted_square;
  return *this;
}

SphereEnergy::Sums& SphereEnergy::Sums::operator-=(const Sums& o) {
  area -= o.area;
  weighted_centroid -= o.weighted_centroid;
  weighted_normal -= o.weighted_normal;
  weighted_dot -= o.weighted_dot;
  weighted_square -= o.weighted_square;
  return *this;
}

SphereEnergy::SphereEnergy(const FaceMeasures& measures, double planar_tolerance)
    : origin_(CentroidBoxCentre(measures)), planar_tolerance_(planar_tolerance) {
  const size_t n = measures.num_faces();
  face_sums_.resize(n);
  centroid_.resize(n);
  normal_ = measures.unit_normal;
  area_ = measures.area;
  for (size_t f = 0; f < n; ++f) {
    const Vec3 g = measures.centroid[f] - origin_;
    const Vec3& normal = measures.unit_normal[f];
    const double a = measures.area[f];
    centroid_[f] = g;
    face_sums_[f] = {a, g * a, normal * a, a * Dot(g, normal), a * SquaredNorm(g)};
  }
}

namespace {

// The two parts of the sphere energy: the normal spread (W - |N|^2/W), and the
// numerator and denominator of what the best curvature removes from it.
struct SphereTerms {
  bool planar;
  double spread;
  double coupling;  // P - X.N/W
  double scatter;   // Q - |X|^2/W
};

SphereTerms Terms(const SphereEnergy::Sums& s, double planar_tolerance) {
  SphereTerms t{true, 0, 0, 0};
  if (s.area <= 0) return t;
  const double w = s.area;
  const double normal_length2 = SquaredNorm(s.weighted_normal);
  t.spread = std::max(0.0, w - normal_length2 / w);
  t.coupling = s.weighted_dot - Dot(s.weighted_centroid, s.weighted_normal) / w;
  t.scatter = s.weighted_square - SquaredNorm(s.weighted_centroid) / w;
  t.planar = std::abs(w * w - normal_length2) < planar_tolerance * w * w || t.scatter <= 0;
  return t;
}

}  // namespace

double SphereEnergy::Energy(const Sums& sums) const {
  const SphereTerms t = Terms(sums, planar_tolerance_);
  if (t.planar) return t.spread;
  return std::max(0.0, t.spread - t.coupling * t.coupling / t.scatter);
}

SphereEnergy::Proxy SphereEnergy::FitProxy(const Sums& sums) const {
  Proxy proxy;
  proxy.origin = origin_;
  if (sums.area <= 0) return proxy;
  const SphereTerms t = Terms(sums, planar_tolerance_);
  proxy.curvature = t.planar ? 0.0 : t.coupling / t.scatter;
  proxy.offset = (sums.weighted_normal - sums.weighted_centroid * proxy.curvature) / sums.area;
  return proxy;
}

double SphereEnergy::FaceCost(uint32_t face, const Proxy& proxy) const {
  return area_[face] *
         SquaredNorm(normal_[face] - centroid_[face] * proxy.curvature - proxy.offset);
}

// ---------------------------------------------------------------------------------------
// Options.

namespace {
constexpr struct {
  MeshEnergyKind kind;
  const char* name;
} kEnergyNames[] = {
    {MeshEnergyKind::kCvd, "cvd"},
    {MeshEnergyKind::kCvdAdaptive, "cvd-adaptive"},
    {MeshEnergyKind::kMwcvdArea, "mwcvd-area"},
    {MeshEnergyKind::kMwcvdVariance, "mwcvd-variance"},
    {MeshEnergyKind::kMwcvdMax, "mwcvd-max"},
    {MeshEnergyKind::kPlanar, "planar"},
    {MeshEnergyKind::kSphere, "sphere"},
};
}  // namespace

absl::StatusOr<MeshEnergyKind> ParseMeshEnergyKind(absl::string_view name) {
  std::string known;
  for (const auto& entry : kEnergyNames) {
    if (name == entry.name) return entry.kind;
    absl::StrAppend(&known, known.empty() ? "" : ", ", entry.name);
  }
  return absl::InvalidArgumentError(absl::StrCat("energy: '", name, "' is not one of ", known));
}

const char* MeshEnergyName(MeshEnergyKind kind) {
  for (const auto& entry : kEnergyNames) {
    if (entry.kind == kind) return entry.name;
  }
  return "unknown";
}

absl::Status ValidateMeshEnergyOptions(const MeshEnergyOptions& options) {
  const DensityOptions& d = options.density;
  if (!(d.delta > 0) || !std::isfinite(d.delta)) {
    return absl::InvalidArgumentError(absl::StrCat("delta: ", d.delta, " must be > 0"));
  }
  if (!(d.gamma > 0) || !std::isfinite(d.gamma)) {
    return absl::InvalidArgumentError(absl::StrCat("gamma: ", d.gamma, " must be > 0"));
  }
  if (!(d.rho_max > 1) || !std::isfinite(d.rho_max)) {
    return absl::InvalidArgumentError(absl::StrCat("rho-max: ", d.rho_max, " must be > 1"));
  }
  if (!(options.mwcvd_p >= 1) || !std::isfinite(options.mwcvd_p) || options.mwcvd_p > 64) {
    return absl::InvalidArgumentError(
        absl::StrCat("mwcvd-p: ", options.mwcvd_p, " must be in [1, 64]"));
  }
  if (!(options.planar_tolerance >= 0) || !(options.planar_tolerance < 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("planar-tolerance: ", options.planar_tolerance, " must be in [0, 1)"));
  }
  return absl::OkStatus();
}

uint32_t CompactClusterIds(std::span<const ClusterId> labels, std::vector<uint32_t>& compact) {
  absl::flat_hash_map<uint32_t, uint32_t> ids;
  compact.resize(labels.size());
  for (size_t f = 0; f < labels.size(); ++f) {
    auto [it, inserted] = ids.try_emplace(labels[f].value(), static_cast<uint32_t>(ids.size()));
    compact[f] = it->second;
  }
  return static_cast<uint32_t>(ids.size());
}

double MeshEnergyOfLabels(const MeshEnergyOptions& options, const TriangleMesh& mesh,
                          std::span<const ClusterId> labels) {
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  return WithMeshEnergy(options, mesh, measures,
                        [&](const auto& energy) { return EnergyFromSums(energy, labels); });
}

}  // namespace mlclust
