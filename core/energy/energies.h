// Mesh energies: every energy functional of chapter 3 in one place.
//
// The unifying idea: a face carries additive measures ("sums"); a cluster's sums are the
// sums of its faces; an energy maps a cluster's sums to a number. Every energy here has
//   - Sums           additive cluster data (operator+=, operator-=; zero by default),
//   - face_sums(f)   the sums of one face,
//   - Energy(s)      the cluster's energy from its sums alone (the incremental form),
//   - MergeCost(a,b) E(a u b) - E(a) - E(b) from the two sums (eq. 4.1),
//   - Proxy, FitProxy(s), FaceCost(f, proxy)  the best-fitting representative of a cluster
//     and the cost of one face against it; sum_f FaceCost(f, FitProxy(s)) == Energy(s).
// Drivers are templates over this interface (EMLO, BB, VSA, ML/HC); WithMeshEnergy turns
// runtime options into a concrete energy.
//
// Which algorithms accept which energy: all of them have an incremental form, so EMLO, ML,
// PML and HC accept every energy below; all of them have a proxy, so BB accepts every one
// too; VSA is defined for the planar (L2,1) energy only.
//
// Equation numbers and line numbers (l.) refer to the dissertation's text
// (shared/seed/000_a22f6fdceb60dfb0.txt). An energy named after the dissertation implements
// its definition; our own variants are named as ours.
#ifndef MLCLUST_CORE_ENERGY_ENERGIES_H_
#define MLCLUST_CORE_ENERGY_ENERGIES_H_

#include <algorithm>
#include <cmath>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/base/ids.h"
#include "core/base/vec3.h"
#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// ---------------------------------------------------------------------------------------
// CVD sums (eq. 3.7), shared by the CVD family.

struct CvdSums {
  double area = 0;                   // sum m_j (area, or density-weighted area)
  Vec3 weighted_centroid;            // sum m_j g_j
  double weighted_squared_norm = 0;  // sum m_j |g_j|^2

  CvdSums& operator+=(const CvdSums& o) {
    area += o.area;
    weighted_centroid += o.weighted_centroid;
    weighted_squared_norm += o.weighted_squared_norm;
    return *this;
  }
  CvdSums& operator-=(const CvdSums& o) {
    area -= o.area;
    weighted_centroid -= o.weighted_centroid;
    weighted_squared_norm -= o.weighted_squared_norm;
    return *this;
  }
  friend CvdSums operator+(CvdSums a, const CvdSums& b) { return a += b; }
};

// The sums of one face of mass `area` at `centroid`. `origin` is subtracted from the
// centroid first: energies are translation invariant, and an origin near the mesh keeps
// the difference of large terms in CvdEnergy accurate.
CvdSums CvdFaceSums(double area, const Vec3& centroid, const Vec3& origin);

// Eq. 3.7: E = sum m|g|^2 - |sum m g|^2 / sum m, clamped at 0 against rounding.
inline double CvdSumsEnergy(const CvdSums& sums) {
  if (sums.area <= 0) return 0;
  return std::max(0.0,
                  sums.weighted_squared_norm - SquaredNorm(sums.weighted_centroid) / sums.area);
}

// Eq. 4.3 for CVD, in the form (m_a m_b / (m_a + m_b)) |gbar_a - gbar_b|^2: equal to
// E(a u b) - E(a) - E(b), never negative, and free of cancellation (Ward's criterion).
inline double CvdMergeCost(const CvdSums& a, const CvdSums& b) {
  if (a.area <= 0 || b.area <= 0) return 0;  // a massless cluster adds no energy
  const Vec3 difference = a.weighted_centroid / a.area - b.weighted_centroid / b.area;
  return a.area * b.area / (a.area + b.area) * SquaredNorm(difference);
}

// The uniform CVD energy by its definition, in two passes (cluster centroids, then
// distances): sum_i sum_{j in C_i} A_j |g_j - gbar_i|^2. `labels` has one entry per face.
double CvdEnergyDirect(const FaceMeasures& measures, std::span<const ClusterId> labels);

// The centre of the bounding box of the face centroids: the origin energies use.
Vec3 CentroidBoxCentre(const FaceMeasures& measures);

// ---------------------------------------------------------------------------------------
// The energies by name.

enum class MeshEnergyKind {
  kCvd,            // eq. 3.7, uniform density
  kCvdAdaptive,    // eq. 3.7 with the face density of section 3.2.1
  kMwcvdArea,      // eq. 3.23 with w^A (eq. 3.24)
  kMwcvdVariance,  // eq. 3.23 with w^V (eq. 3.27)
  kMwcvdMax,       // eq. 3.23 with w^M (eq. 3.28)
  kPlanar,         // L2,1, eq. 3.38
  kSphere,         // sphere fit, eqs. 3.40-3.46 with the planar rule of l. 1333
  kSphereNormals,  // ours: normal-field least squares (SphereNormalFitEnergy)
};

// ---------------------------------------------------------------------------------------
// Face density for adaptive CVD and MWCVD (section 3.2.1).

struct DensityOptions {
  enum class Mapping {
    kDefault,  // the energy's own: kLinear for mwcvd-* (as the text's Fig. 3.13 and
               // Table 3.1), kPower for cvd-adaptive
    kPower,    // rho = (rho' + delta)^gamma (l. 931)
    kLinear,   // rho' mapped linearly from [min rho', max rho'] onto [1, rho^new] (l. 933)
  };
  Mapping mapping = Mapping::kDefault;
  double delta = 1e-2;  // > 0: keeps flat regions (rho' = 0) at a positive density (l. 931)
  double gamma = 2.0;   // > 0
  // rho^new, > 1; 0 picks the energy's default: the text's Table 3.1 uses 50 (w^A, w^M) and
  // 3 (w^V) on Fandisk, Cube and Bunny (also the Fandisk of Fig. 3.13), and 100 / 5 on the
  // larger Horse and Armadillo; we default to 50 (mwcvd-area, mwcvd-max) and 3
  // (mwcvd-variance), and 10 for cvd-adaptive's linear mapping.
  double rho_max = 0;
};

// `options` with kDefault and rho_max = 0 replaced by `kind`'s defaults (see above).
DensityOptions ResolveDensityOptions(MeshEnergyKind kind, const DensityOptions& options);

// Eq. 3.17: rho'_f = (1/n) sum_{i = 1..3} sum_{F_k adjacent to V_i} |n_f - n_k|, the mean
// over the (vertex, face) incidences of f's three vertices, f itself included (it adds 0
// to the sum and 1 to n) and a face sharing an edge with f counted twice; then the chosen
// mapping (kDefault reads as kPower, rho_max = 0 as 10: resolve the options first).
std::vector<double> ComputeFaceDensity(const TriangleMesh& mesh, const FaceMeasures& measures,
                                       const DensityOptions& options);

// ---------------------------------------------------------------------------------------
// The energies.

// CVD with a mass per face: m_j = A_j (uniform density, section 3.1.3) or m_j = rho_j A_j
// (adaptive CVD, section 3.2.1). E_i = sum_{j in C_i} m_j |g_j - gamma_i|^2 with gamma_i
// the mass-weighted centroid; proxy gamma_i.
class CvdEnergy {
 public:
  using Sums = CvdSums;
  using Proxy = Vec3;  // the cluster's centroid, relative to origin()

  // `density` empty: uniform; else one positive density per face.
  CvdEnergy(const FaceMeasures& measures, std::span<const double> density = {});

  const Sums& face_sums(uint32_t face) const { return face_sums_[face]; }
  double Energy(const Sums& sums) const { return CvdSumsEnergy(sums); }
  double MergeCost(const Sums& a, const Sums& b) const { return CvdMergeCost(a, b); }
  Proxy FitProxy(const Sums& sums) const;
  double FaceCost(uint32_t face, const Proxy& proxy) const {
    const Sums& s = face_sums_[face];
    if (s.area <= 0) return 0;
    return s.area * SquaredNorm(s.weighted_centroid / s.area - proxy);
  }
  size_t num_faces() const { return face_sums_.size(); }
  const Vec3& origin() const { return origin_; }

 private:
  Vec3 origin_;
  std::vector<Sums> face_sums_;
};

// Multiplicatively weighted CVD, eqs. 3.21-3.23:
//   E = sum_i w_i ( sum_{j in C_i} rho_j A_j |g_j|^2 - |sum rho_j A_j g_j|^2 / sum rho_j A_j )
// i.e. E_i = w_i sum_{j in C_i} rho_j A_j |g_j - gbar_i|^2 with the density-weighted
// centroid gbar_i = sum rho_j A_j g_j / sum rho_j A_j (eq. 3.22). The cluster weight w_i
// comes from the densities of the cluster's faces:
//   w^A = sum rho_j A_j                               (eq. 3.24, "area")
//   w^V = 1 + sum rho_j^2 - (sum rho_j)^2 / n_i       (eq. 3.27 = 3.25, "variance")
//   w^M = (sum rho_j^p)^(1/p), p = 10 by default      (eq. 3.28, the text's stand-in for
//                                                      max rho_j of eq. 3.26)
// Proxy: gbar_i and w_i; the cost of face f against it is w_i rho_f A_f |g_f - gbar_i|^2,
// the term of eq. 3.21 (l. 971 writes it per unit area).
class MwcvdEnergy {
 public:
  enum class Weight { kArea, kVariance, kMax };
  struct Sums {
    CvdSums cvd;  // with mass rho_j A_j: sum rho A, sum rho A g, sum rho A |g|^2
    double count = 0;
    double density = 0;          // sum rho
    double density_squared = 0;  // sum rho^2
    double density_power = 0;    // sum rho^p

    Sums& operator+=(const Sums& o);
    Sums& operator-=(const Sums& o);
    friend Sums operator+(Sums a, const Sums& b) { return a += b; }
  };
  struct Proxy {
    Vec3 centroid;  // gbar_i, relative to origin()
    double weight = 1;
  };

  // `density` empty: rho = 1 for every face; else one positive density per face.
  MwcvdEnergy(const FaceMeasures& measures, std::span<const double> density, Weight weight,
              double p = 10);

  const Sums& face_sums(uint32_t face) const { return face_sums_[face]; }
  double ClusterWeight(const Sums& sums) const;
  double Energy(const Sums& sums) const { return ClusterWeight(sums) * CvdSumsEnergy(sums.cvd); }
  double MergeCost(const Sums& a, const Sums& b) const {
    return Energy(a + b) - Energy(a) - Energy(b);
  }
  Proxy FitProxy(const Sums& sums) const;
  double FaceCost(uint32_t face, const Proxy& proxy) const {
    const CvdSums& s = face_sums_[face].cvd;
    if (s.area <= 0) return 0;
    return proxy.weight * s.area * SquaredNorm(s.weighted_centroid / s.area - proxy.centroid);
  }
  size_t num_faces() const { return face_sums_.size(); }
  const Vec3& origin() const { return origin_; }

 private:
  Weight weight_;
  double p_;
  Vec3 origin_;
  std::vector<Sums> face_sums_;
};

// Planar L2,1 (section 3.3.2): E_i = sum_{j in C_i} A_j |n_j - N_i|^2 with N_i the
// normalised area-weighted mean normal; with unit normals this is the incremental form
// E_i = 2 (sum A - |sum A n|) (eq. 3.38). Proxy N_i.
class PlanarEnergy {
 public:
  struct Sums {
    double area = 0;
    Vec3 weighted_normal;

    Sums& operator+=(const Sums& o) {
      area += o.area;
      weighted_normal += o.weighted_normal;
      return *this;
    }
    Sums& operator-=(const Sums& o) {
      area -= o.area;
      weighted_normal -= o.weighted_normal;
      return *this;
    }
    friend Sums operator+(Sums a, const Sums& b) { return a += b; }
  };
  using Proxy = Vec3;  // unit normal

  explicit PlanarEnergy(const FaceMeasures& measures);

  const Sums& face_sums(uint32_t face) const { return face_sums_[face]; }
  double Energy(const Sums& sums) const {
    return std::max(0.0, 2.0 * (sums.area - Norm(sums.weighted_normal)));
  }
  double MergeCost(const Sums& a, const Sums& b) const {
    // 2(|N_a| + |N_b| - |N_a + N_b|): the triangle inequality makes it >= 0.
    return std::max(0.0, 2.0 * (Norm(a.weighted_normal) + Norm(b.weighted_normal) -
                                Norm(a.weighted_normal + b.weighted_normal)));
  }
  Proxy FitProxy(const Sums& sums) const;
  double FaceCost(uint32_t face, const Proxy& proxy) const {
    const Sums& s = face_sums_[face];
    if (s.area <= 0) return 0;
    return s.area * SquaredNorm(s.weighted_normal / s.area - proxy);
  }
  size_t num_faces() const { return face_sums_.size(); }

 private:
  std::vector<Sums> face_sums_;
};

// Sphere fit, eqs. 3.40-3.46 (section 3.3.2): with p_j the centroid and n_j the unit normal
// of face j, and k_i the number of faces of cluster C_i (every face counts once, whatever
// its area),
//   E_i = sum_{j in C_i} |c_j - Cbar_i|^2,  c_j = p_j - R_i n_j,  Cbar_i = sum c_j / k_i,
// with the radius R_i that minimises it (eq. 3.45):
//   R_i = (k_i sum p.n - sum p . sum n) / (k_i^2 - |sum n|^2),
// which gives eq. 3.46:
//   E_i = sum |p|^2 - |sum p|^2 / k_i - (k_i sum p.n - sum p . sum n)^2 / (k_i (k_i^2 - |sum
//   n|^2)).
// Planar rule (l. 1333): when |k_i^2 - |sum n|^2| < Delta_zero (5e-5) the cluster is planar
// (R_i = infinity) and E_i = 0, so planar regions fit first: the text's reduced energy is
// -infinity there, and here a merge into a planar cluster costs -E(a) - E(b) <= 0 while every
// other merge costs >= 0. A single face is planar.
// Proxy (R_i, Cbar_i). For BB, a planar cluster's proxy is its plane (through sum p / k_i,
// normal sum n / |sum n|) and a face's cost against it the squared distance of its centroid
// to that plane: ours, as the text gives no face cost for R = infinity; it is 0 for the
// cluster's own coplanar faces, so sum_f FaceCost == Energy still holds.
class SphereEnergy {
 public:
  struct Sums {
    double count = 0;                // k_i
    Vec3 position;                   // sum p_j (relative to the energy's origin)
    Vec3 normal;                     // sum n_j
    double position_dot_normal = 0;  // sum p_j . n_j
    double position_squared = 0;     // sum |p_j|^2

    Sums& operator+=(const Sums& o);
    Sums& operator-=(const Sums& o);
    friend Sums operator+(Sums a, const Sums& b) { return a += b; }
  };
  struct Proxy {
    bool planar = true;
    double radius = 0;  // R_i (signed: > 0 when normals point away from the centre)
    Vec3 centre;        // Cbar_i, or a point of the plane when planar
    Vec3 plane_normal;  // unit normal of the plane when planar
  };

  explicit SphereEnergy(const FaceMeasures& measures, double zero_tolerance = 5e-5);

  const Sums& face_sums(uint32_t face) const { return face_sums_[face]; }
  bool IsPlanar(const Sums& sums) const;
  double Radius(const Sums& sums) const;  // eq. 3.45; 0 when planar or empty
  double Energy(const Sums& sums) const;  // eq. 3.46, or 0 when planar
  double MergeCost(const Sums& a, const Sums& b) const {
    return Energy(a + b) - Energy(a) - Energy(b);
  }
  Proxy FitProxy(const Sums& sums) const;
  double FaceCost(uint32_t face, const Proxy& proxy) const;
  size_t num_faces() const { return face_sums_.size(); }
  const Vec3& origin() const { return origin_; }

 private:
  Vec3 origin_;
  double zero_tolerance_;
  std::vector<Sums> face_sums_;
};

// Ours (not the dissertation's sphere fit): a sphere of centre c and curvature kappa = 1/r
// has normal n(x) = kappa (x - c) = kappa x + d at x. A cluster's energy is the area-weighted
// least-squares misfit of its face normals to the best sphere,
//   E_i = min_{kappa, d} sum_{j in C_i} A_j |n_j - kappa g_j - d|^2,
// linear in (kappa, d), so it follows from sums of A, A g, A n, A g.n, A |g|^2:
//   E_i = (W - |N|^2/W) - (P - X.N/W)^2 / (Q - |X|^2/W).
// Planes are the limit kappa -> 0: when |W^2 - |N|^2| < planar_tolerance * W^2 the
// cluster is planar and E_i = W - |N|^2/W (~0). Proxy (kappa, d). Scale-free in the
// normals and area-weighted, unlike the text's, which is in squared lengths per face.
class SphereNormalFitEnergy {
 public:
  struct Sums {
    double area = 0;             // W
    Vec3 weighted_centroid;      // X = sum A g
    Vec3 weighted_normal;        // N = sum A n
    double weighted_dot = 0;     // P = sum A g.n
    double weighted_square = 0;  // Q = sum A |g|^2

    Sums& operator+=(const Sums& o);
    Sums& operator-=(const Sums& o);
    friend Sums operator+(Sums a, const Sums& b) { return a += b; }
  };
  struct Proxy {
    double curvature = 0;  // kappa (signed: > 0 when normals point away from the centre)
    Vec3 offset;           // d
    Vec3 origin;           // positions are relative to this
  };

  explicit SphereNormalFitEnergy(const FaceMeasures& measures, double planar_tolerance = 1e-9);

  const Sums& face_sums(uint32_t face) const { return face_sums_[face]; }
  double Energy(const Sums& sums) const;
  double MergeCost(const Sums& a, const Sums& b) const {
    return Energy(a + b) - Energy(a) - Energy(b);
  }
  Proxy FitProxy(const Sums& sums) const;
  double FaceCost(uint32_t face, const Proxy& proxy) const;
  size_t num_faces() const { return face_sums_.size(); }

 private:
  Vec3 origin_;
  double planar_tolerance_;
  std::vector<Sums> face_sums_;
  std::vector<Vec3> centroid_, normal_;
  std::vector<double> area_;
};

// ---------------------------------------------------------------------------------------
// Choosing an energy at run time.

struct MeshEnergyOptions {
  MeshEnergyKind kind = MeshEnergyKind::kCvd;
  DensityOptions density;          // cvd-adaptive and mwcvd-*
  double mwcvd_p = 10;             // mwcvd-max: the p of eq. 3.28 (>= 1; the text uses 10)
  double planar_tolerance = 5e-5;  // sphere: Delta_zero of l. 1333, |k^2 - |sum n|^2| below it
                                   // is planar (sphere-normals keeps its own 1e-9 relative)
};

// "cvd", "cvd-adaptive", "mwcvd-area", "mwcvd-variance", "mwcvd-max", "planar", "sphere",
// "sphere-normals" (ours).
absl::StatusOr<MeshEnergyKind> ParseMeshEnergyKind(absl::string_view name);
const char* MeshEnergyName(MeshEnergyKind kind);

// INVALID_ARGUMENT naming the option that is out of range.
absl::Status ValidateMeshEnergyOptions(const MeshEnergyOptions& options);

// Builds the energy `options` names and calls f(energy) with it; returns what f returns.
template <typename F>
decltype(auto) WithMeshEnergy(const MeshEnergyOptions& options, const TriangleMesh& mesh,
                              const FaceMeasures& measures, F&& f) {
  auto density = [&] {
    return ComputeFaceDensity(mesh, measures, ResolveDensityOptions(options.kind, options.density));
  };
  switch (options.kind) {
    case MeshEnergyKind::kCvdAdaptive:
      return f(CvdEnergy(measures, density()));
    case MeshEnergyKind::kMwcvdArea:
      return f(MwcvdEnergy(measures, density(), MwcvdEnergy::Weight::kArea, options.mwcvd_p));
    case MeshEnergyKind::kMwcvdVariance:
      return f(MwcvdEnergy(measures, density(), MwcvdEnergy::Weight::kVariance, options.mwcvd_p));
    case MeshEnergyKind::kMwcvdMax:
      return f(MwcvdEnergy(measures, density(), MwcvdEnergy::Weight::kMax, options.mwcvd_p));
    case MeshEnergyKind::kPlanar:
      return f(PlanarEnergy(measures));
    case MeshEnergyKind::kSphere:
      return f(SphereEnergy(measures, options.planar_tolerance));
    case MeshEnergyKind::kSphereNormals:
      return f(SphereNormalFitEnergy(measures));
    case MeshEnergyKind::kCvd:
    default:
      return f(CvdEnergy(measures));
  }
}

// ---------------------------------------------------------------------------------------
// Energies of a labelling. Cluster ids may be any values below labels.size() + k; both
// functions accept any ids (they are compacted first).

// Sum over clusters of Energy(cluster sums): the incremental form.
template <typename Energy>
double EnergyFromSums(const Energy& energy, std::span<const ClusterId> labels);

// Sum over faces of FaceCost(face, FitProxy(its cluster's sums)): the definition.
template <typename Energy>
double EnergyFromProxies(const Energy& energy, std::span<const ClusterId> labels);

// The face densities `options` uses (cvd-adaptive, mwcvd-*), resolved as WithMeshEnergy
// does; empty for the energies without a density. Coarsening places vertices at the
// density-weighted centroids with them (l. 783, 937).
std::vector<double> EnergyFaceDensity(const MeshEnergyOptions& options, const TriangleMesh& mesh,
                                      const FaceMeasures& measures);

// The energy `options` names of a labelling of `mesh`, from sums.
double MeshEnergyOfLabels(const MeshEnergyOptions& options, const TriangleMesh& mesh,
                          std::span<const ClusterId> labels);

// Compact cluster ids: labels renumbered 0..k-1 in order of first appearance; returns k.
uint32_t CompactClusterIds(std::span<const ClusterId> labels, std::vector<uint32_t>& compact);

template <typename Energy>
std::vector<typename Energy::Sums> SumsPerCluster(const Energy& energy,
                                                  std::span<const uint32_t> compact,
                                                  uint32_t num_clusters) {
  std::vector<typename Energy::Sums> sums(num_clusters);
  for (size_t f = 0; f < compact.size(); ++f) sums[compact[f]] += energy.face_sums(f);
  return sums;
}

template <typename Energy>
double EnergyFromSums(const Energy& energy, std::span<const ClusterId> labels) {
  std::vector<uint32_t> compact;
  const uint32_t k = CompactClusterIds(labels, compact);
  double total = 0;
  for (const auto& sums : SumsPerCluster(energy, compact, k)) total += energy.Energy(sums);
  return total;
}

template <typename Energy>
double EnergyFromProxies(const Energy& energy, std::span<const ClusterId> labels) {
  std::vector<uint32_t> compact;
  const uint32_t k = CompactClusterIds(labels, compact);
  std::vector<typename Energy::Proxy> proxies;
  proxies.reserve(k);
  for (const auto& sums : SumsPerCluster(energy, compact, k)) {
    proxies.push_back(energy.FitProxy(sums));
  }
  double total = 0;
  for (size_t f = 0; f < compact.size(); ++f) total += energy.FaceCost(f, proxies[compact[f]]);
  return total;
}

}  // namespace mlclust

#endif  // MLCLUST_CORE_ENERGY_ENERGIES_H_
