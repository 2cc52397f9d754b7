#include "core/energy/energies.h"

#include <algorithm>
#include <numeric>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/base/renumber.h"

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

DensityOptions ResolveDensityOptions(MeshEnergyKind kind, const DensityOptions& options) {
  DensityOptions resolved = options;
  const bool mwcvd = kind == MeshEnergyKind::kMwcvdArea || kind == MeshEnergyKind::kMwcvdVariance ||
                     kind == MeshEnergyKind::kMwcvdMax;
  if (resolved.mapping == DensityOptions::Mapping::kDefault) {
    // Fig. 3.13 and Table 3.1 (MWCVD) use the linear mapping.
    resolved.mapping = mwcvd ? DensityOptions::Mapping::kLinear : DensityOptions::Mapping::kPower;
  }
  if (resolved.rho_max == 0) {
    // Table 3.1: rho^new = 50 for w^A and w^M, 3 for w^V (Fandisk, Cube, Bunny).
    resolved.rho_max = kind == MeshEnergyKind::kMwcvdVariance ? 3.0 : mwcvd ? 50.0 : 10.0;
  }
  return resolved;
}

std::vector<double> ComputeFaceDensity(const TriangleMesh& mesh, const FaceMeasures& measures,
                                       const DensityOptions& options) {
  const size_t num_faces = mesh.num_faces();
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  // Eq. 3.17: rho'_f, the mean |n_f - n_k| over the (vertex, face) incidences around f's
  // three vertices; f itself is among them (|n_f - n_f| = 0 counts towards n).
  std::vector<double> raw(num_faces, 0.0);
  for (uint32_t f = 0; f < num_faces; ++f) {
    double sum = 0;
    size_t incidences = 0;
    for (int c = 0; c < 3; ++c) {
      for (uint32_t k : table.faces_around(mesh.indices[3 * size_t{f} + c])) {
        sum += Norm(measures.unit_normal[f] - measures.unit_normal[k]);
        ++incidences;
      }
    }
    if (incidences > 0) raw[f] = sum / static_cast<double>(incidences);
  }
  std::vector<double> density(num_faces);
  if (options.mapping == DensityOptions::Mapping::kLinear) {
    // l. 933: [min rho', max rho'] onto [1, rho^new].
    const double rho_new = options.rho_max == 0 ? 10.0 : options.rho_max;
    const auto [lo, hi] = std::minmax_element(raw.begin(), raw.end());
    const double span = num_faces == 0 ? 0 : *hi - *lo;
    for (size_t f = 0; f < num_faces; ++f) {
      density[f] = span > 0 ? (*hi - raw[f]) / span + rho_new * (raw[f] - *lo) / span : 1.0;
    }
  } else {
    // l. 931: (rho' + Delta)^gamma.
    for (size_t f = 0; f < num_faces; ++f) {
      density[f] = std::pow(raw[f] + options.delta, options.gamma);
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
  density += o.density;
  density_squared += o.density_squared;
  density_power += o.density_power;
  return *this;
}

MwcvdEnergy::Sums& MwcvdEnergy::Sums::operator-=(const Sums& o) {
  cvd -= o.cvd;
  count -= o.count;
  density -= o.density;
  density_squared -= o.density_squared;
  density_power -= o.density_power;
  return *this;
}

MwcvdEnergy::MwcvdEnergy(const FaceMeasures& measures, std::span<const double> density,
                         Weight weight, double p)
    : weight_(weight), p_(p), origin_(CentroidBoxCentre(measures)) {
  face_sums_.resize(measures.num_faces());
  for (size_t f = 0; f < face_sums_.size(); ++f) {
    const double rho = density.empty() ? 1.0 : density[f];
    Sums& s = face_sums_[f];
    // Eq. 3.23: the density sits inside the sums, with the area.
    s.cvd = CvdFaceSums(rho * measures.area[f], measures.centroid[f], origin_);
    s.count = 1;
    s.density = rho;
    s.density_squared = rho * rho;
    s.density_power = std::pow(rho, p_);
  }
}

double MwcvdEnergy::ClusterWeight(const Sums& sums) const {
  switch (weight_) {
    case Weight::kArea:  // eq. 3.24: sum rho A, already the CVD mass
      return std::max(0.0, sums.cvd.area);
    case Weight::kVariance:  // eq. 3.27
      if (sums.count <= 0) return 1.0;
      return 1.0 + std::max(0.0, sums.density_squared - sums.density * sums.density / sums.count);
    case Weight::kMax:  // eq. 3.28
    default:
      return std::pow(std::max(0.0, sums.density_power), 1.0 / p_);
  }
}

MwcvdEnergy::Proxy MwcvdEnergy::FitProxy(const Sums& sums) const {
  Proxy proxy;
  // Eq. 3.22: the density-weighted centroid.
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
// Sphere fit (eqs. 3.40-3.46).

SphereEnergy::Sums& SphereEnergy::Sums::operator+=(const Sums& o) {
  count += o.count;
  position += o.position;
  normal += o.normal;
  position_dot_normal += o.position_dot_normal;
  position_squared += o.position_squared;
  return *this;
}

SphereEnergy::Sums& SphereEnergy::Sums::operator-=(const Sums& o) {
  count -= o.count;
  position -= o.position;
  normal -= o.normal;
  position_dot_normal -= o.position_dot_normal;
  position_squared -= o.position_squared;
  return *this;
}

SphereEnergy::SphereEnergy(const FaceMeasures& measures, double zero_tolerance)
    : origin_(CentroidBoxCentre(measures)), zero_tolerance_(zero_tolerance) {
  face_sums_.resize(measures.num_faces());
  for (size_t f = 0; f < face_sums_.size(); ++f) {
    // Positions relative to an origin near the mesh: E_i is translation invariant
    // (c_j - Cbar_i does not change) and the sums stay small.
    const Vec3 p = measures.centroid[f] - origin_;
    const Vec3& n = measures.unit_normal[f];
    face_sums_[f] = {1.0, p, n, Dot(p, n), SquaredNorm(p)};
  }
}

bool SphereEnergy::IsPlanar(const Sums& sums) const {
  // l. 1333: |k_i^2 - |sum n|^2| < Delta_zero.
  return sums.count <= 0 ||
         std::abs(sums.count * sums.count - SquaredNorm(sums.normal)) < zero_tolerance_;
}

double SphereEnergy::Radius(const Sums& sums) const {
  if (IsPlanar(sums)) return 0;
  // Eq. 3.45.
  const double k = sums.count;
  return (k * sums.position_dot_normal - Dot(sums.position, sums.normal)) /
         (k * k - SquaredNorm(sums.normal));
}

double SphereEnergy::Energy(const Sums& sums) const {
  if (IsPlanar(sums)) return 0;  // l. 1333: planar clusters fit at no cost
  // Eq. 3.46.
  const double k = sums.count;
  const double coupling = k * sums.position_dot_normal - Dot(sums.position, sums.normal);
  const double spread = k * k - SquaredNorm(sums.normal);
  const double energy =
      sums.position_squared - SquaredNorm(sums.position) / k - coupling * coupling / (k * spread);
  return std::max(0.0, energy);
}

SphereEnergy::Proxy SphereEnergy::FitProxy(const Sums& sums) const {
  Proxy proxy;
  if (sums.count <= 0) return proxy;
  if (IsPlanar(sums)) {
    proxy.planar = true;
    proxy.centre = sums.position / sums.count;
    const double length = Norm(sums.normal);
    proxy.plane_normal = length > 0 ? sums.normal / length : Vec3{};
    return proxy;
  }
  proxy.planar = false;
  proxy.radius = Radius(sums);
  proxy.centre = (sums.position - sums.normal * proxy.radius) / sums.count;  // eq. 3.42
  return proxy;
}

double SphereEnergy::FaceCost(uint32_t face, const Proxy& proxy) const {
  const Sums& s = face_sums_[face];
  if (proxy.planar) {
    // Ours (see the header): squared distance of p_j to the cluster's plane.
    const double distance = Dot(s.position - proxy.centre, proxy.plane_normal);
    return distance * distance;
  }
  // Eq. 3.40 with eq. 3.41: |p_j - R_i n_j - Cbar_i|^2.
  return SquaredNorm(s.position - s.normal * proxy.radius - proxy.centre);
}

// ---------------------------------------------------------------------------------------
// Sphere normal fit (ours).

SphereNormalFitEnergy::Sums& SphereNormalFitEnergy::Sums::operator+=(const Sums& o) {
  area += o.area;
  weighted_centroid += o.weighted_centroid;
  weighted_normal += o.weighted_normal;
  weighted_dot += o.weighted_dot;
  weighted_square += o.weighted_square;
  return *this;
}

SphereNormalFitEnergy::Sums& SphereNormalFitEnergy::Sums::operator-=(const Sums& o) {
  area -= o.area;
  weighted_centroid -= o.weighted_centroid;
  weighted_normal -= o.weighted_normal;
  weighted_dot -= o.weighted_dot;
  weighted_square -= o.weighted_square;
  return *this;
}

SphereNormalFitEnergy::SphereNormalFitEnergy(const FaceMeasures& measures, double planar_tolerance)
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

SphereTerms Terms(const SphereNormalFitEnergy::Sums& s, double planar_tolerance) {
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

double SphereNormalFitEnergy::Energy(const Sums& sums) const {
  const SphereTerms t = Terms(sums, planar_tolerance_);
  if (t.planar) return t.spread;
  return std::max(0.0, t.spread - t.coupling * t.coupling / t.scatter);
}

SphereNormalFitEnergy::Proxy SphereNormalFitEnergy::FitProxy(const Sums& sums) const {
  Proxy proxy;
  proxy.origin = origin_;
  if (sums.area <= 0) return proxy;
  const SphereTerms t = Terms(sums, planar_tolerance_);
  proxy.curvature = t.planar ? 0.0 : t.coupling / t.scatter;
  proxy.offset = (sums.weighted_normal - sums.weighted_centroid * proxy.curvature) / sums.area;
  return proxy;
}

double SphereNormalFitEnergy::FaceCost(uint32_t face, const Proxy& proxy) const {
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
    {MeshEnergyKind::kSphereNormals, "sphere-normals"},
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
  if (d.rho_max != 0 && (!(d.rho_max > 1) || !std::isfinite(d.rho_max))) {
    return absl::InvalidArgumentError(
        absl::StrCat("rho-max: ", d.rho_max, " must be > 1 (or 0 for the energy's default)"));
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
  Renumbering<ClusterId> renumbered = RenumberByFirstAppearance(labels);
  compact = std::move(renumbered.dense);
  return renumbered.size();
}

std::vector<double> EnergyFaceDensity(const MeshEnergyOptions& options, const TriangleMesh& mesh,
                                      const FaceMeasures& measures) {
  switch (options.kind) {
    case MeshEnergyKind::kCvdAdaptive:
    case MeshEnergyKind::kMwcvdArea:
    case MeshEnergyKind::kMwcvdVariance:
    case MeshEnergyKind::kMwcvdMax:
      return ComputeFaceDensity(mesh, measures,
                                ResolveDensityOptions(options.kind, options.density));
    default:
      return {};
  }
}

double MeshEnergyOfLabels(const MeshEnergyOptions& options, const TriangleMesh& mesh,
                          std::span<const ClusterId> labels) {
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  return WithMeshEnergy(options, mesh, measures,
                        [&](const auto& energy) { return EnergyFromSums(energy, labels); });
}

}  // namespace mlclust
