#include "core/cluster/vsa.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/random.h"
#include "core/base/status_macros.h"

namespace mlclust {
namespace {

// "No region" (regions are cluster ids) and "no face": the id types' own sentinels.
constexpr uint32_t kNoRegion = ClusterId::kInvalidValue;
constexpr uint32_t kNoFace = FaceId::kInvalidValue;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
// The flood looks at the cancel flag once per this many heap entries (about a millisecond).
constexpr uint32_t kFacesPerCancelCheck = 16384;

// Per face, what the L2,1 cost needs, packed into one 32-byte record: the unit normal n_j
// (zero for a face of zero area) and the area A_j.
struct FaceRecord {
  double x, y, z, area;
};

// A pending claim of `face` by `region` at `cost` in the flood of Alg. 2.2.
struct Claim {
  double cost;
  uint32_t face;
  uint32_t region;
};

// A 4-ary min-heap of claims: the cheapest on top, ties to the smaller face id, so the
// flood does not depend on the heap's internals (a face holds at most one claim per cost
// value; see Vsa::ClaimNeighbours). Four children per node halve the depth of a binary
// heap; the four 16-byte children lie within two cache lines.
class ClaimHeap {
 public:
  bool empty() const { return claims_.empty(); }
  size_t size() const { return claims_.size(); }
  void clear() { claims_.clear(); }
  void reserve(size_t n) { claims_.reserve(n); }

  void Push(const Claim& claim) {
    size_t i = claims_.size();
    claims_.push_back(claim);
    while (i > 0) {
      const size_t parent = (i - 1) / 4;
      if (!Before(claim, claims_[parent])) break;
      claims_[i] = claims_[parent];
      i = parent;
    }
    claims_[i] = claim;
  }

  const Claim& Top() const { return claims_[0]; }

  void Pop() {
    const Claim last = claims_.back();
    claims_.pop_back();
    if (!claims_.empty()) SiftDown(last);
  }

  // Pop() then Push(claim) in one sift from the root: cheap when `claim` is among the
  // cheapest, as a flood's next claims mostly are.
  void ReplaceTop(const Claim& claim) { SiftDown(claim); }

 private:
  // Puts `claim` at the root's place and sifts it down.
  void SiftDown(const Claim& claim) {
    const size_t n = claims_.size();
    size_t i = 0;
    while (true) {
      const size_t first = 4 * i + 1;
      if (first >= n) break;
      const size_t end = std::min(first + 4, n);
      size_t best = first;
      for (size_t j = first + 1; j < end; ++j) {
        if (Before(claims_[j], claims_[best])) best = j;
      }
      if (!Before(claims_[best], claim)) break;
      claims_[i] = claims_[best];
      i = best;
    }
    claims_[i] = claim;
  }

  static bool Before(const Claim& a, const Claim& b) {
    return a.cost < b.cost || (a.cost == b.cost && a.face < b.face);
  }

  std::vector<Claim> claims_;
};

// The state of one VSA run: regions (proxy, seed, error, size) and the face labels, with
// every buffer sized once so that Lloyd iterations allocate nothing.
class Vsa {
 public:
  Vsa(const FaceAdjacency& adjacency, const FaceMeasures& measures)
      : adjacency_(adjacency), num_faces_(static_cast<uint32_t>(measures.num_faces())) {
    faces_.resize(num_faces_);
    for (uint32_t f = 0; f < num_faces_; ++f) {
      const Vec3& n = measures.unit_normal[f];
      faces_[f] = {n.x, n.y, n.z, measures.area[f]};
    }
    labels_.assign(num_faces_, kNoRegion);
    previous_labels_.assign(num_faces_, kNoRegion);
    best_cost_.assign(num_faces_, kInfinity);
    face_cost_.assign(num_faces_, 0.0);
    heap_.reserve(1024);
  }

  // The flag Flood looks at every kFacesPerCancelCheck faces; once seen set, cancelled()
  // is true, the flood stops where it is (labels incomplete) and nothing is fitted.
  void SetCancel(const std::atomic<bool>* cancel) { cancel_ = cancel; }
  bool cancelled() const { return cancelled_; }

  uint32_t num_faces() const { return num_faces_; }
  uint32_t num_regions() const { return static_cast<uint32_t>(proxies_.size()); }
  const std::vector<uint32_t>& labels() const { return labels_; }
  const std::vector<Vec3>& proxies() const { return proxies_; }
  const std::vector<uint32_t>& seeds() const { return seeds_; }
  const std::vector<double>& errors() const { return errors_; }
  const std::vector<uint32_t>& sizes() const { return sizes_; }
  const std::vector<double>& face_costs() const { return face_cost_; }
  double energy() const { return energy_; }
  void Reserve(uint32_t regions) {
    proxies_.reserve(regions);
    seeds_.reserve(regions);
    errors_.reserve(regions);
    sizes_.reserve(regions);
    normal_sums_.reserve(regions);
    smallest_cost_.reserve(regions);
  }

  // A face's L2,1 cost against a proxy: A_j |n_j - N|^2.
  double Cost(uint32_t face, const Vec3& proxy) const {
    const FaceRecord& r = faces_[face];
    const double dx = r.x - proxy.x, dy = r.y - proxy.y, dz = r.z - proxy.z;
    return r.area * (dx * dx + dy * dy + dz * dz);
  }

  // The proxy fitted to one face: its normal (+z for a face of zero area).
  Vec3 FaceProxy(uint32_t face) const {
    const FaceRecord& r = faces_[face];
    return r.area > 0 ? Vec3{r.x, r.y, r.z} : Vec3{0, 0, 1};
  }

  // CGAL's bootstrap: one region per edge-connected component, fitted to it. Returns the
  // number of components.
  uint32_t StartFromComponents() {
    const uint32_t count = LabelFaceComponents(adjacency_, labels_);
    Resize(count);
    Fit();
    return count;
  }

  // Alg. 2.1's region insertion: a new region whose proxy is `face`'s normal and whose seed
  // is `face`, which leaves its region (that region's error drops by the face's cost; its
  // proxy is not refitted until the next Fit). `face` must not be a seed.
  void AddRegionAt(uint32_t face) {
    const uint32_t from = labels_[face];
    const uint32_t region = num_regions();
    Resize(region + 1);
    proxies_[region] = FaceProxy(face);
    seeds_[region] = face;
    errors_[region] = Cost(face, proxies_[region]);
    sizes_[region] = 1;
    errors_[from] = std::max(0.0, errors_[from] - face_cost_[face]);
    --sizes_[from];
    energy_ += errors_[region] - face_cost_[face];
    face_cost_[face] = errors_[region];
    labels_[face] = region;
    fitted_ = false;  // `from` lost a face: its proxy is refitted by the next Fit
  }

  // `count` Lloyd iterations (partition, then fit), stopping early at a fixed point; a
  // count of 0 only refits. Returns the number of iterations run.
  uint32_t Relax(uint32_t count) {
    if (count == 0) {
      Fit();
      return 0;
    }
    for (uint32_t i = 0; i < count; ++i) {
      if (Iterate() == 0) return i + 1;  // a fixed point, or cancelled
    }
    return count;
  }

  // One Lloyd iteration; returns the number of faces whose region changed. With none (and
  // a state fitted to the labels before), the partition is a fixed point: proxies, seeds
  // and every later partition stay the same.
  uint32_t Iterate() {
    Flood();
    if (cancelled_) return 0;
    const uint32_t changed = CountChanged();
    if (changed > 0 || !fitted_) Fit();
    return changed;
  }

  // Region teleportation (Cohen-Steiner et al. 2004; CGAL's teleport_proxies):
  // merge the two adjacent regions whose union costs the least extra error and reuse the
  // freed region for a seed at the costliest face of the region of the largest error.
  // Done only if the merge costs less than half that region's error and the worst region
  // is not one of the pair; returns whether it was done. The state is refitted after.
  bool Teleport() {
    const uint32_t k = num_regions();
    uint32_t worst = kNoRegion;
    for (uint32_t r = 0; r < k; ++r) {
      if (sizes_[r] > 1 && (worst == kNoRegion || errors_[r] > errors_[worst])) worst = r;
    }
    if (worst == kNoRegion) return false;
    // The cheapest merge of regions that share an edge, from the sums alone (eq. 3.38:
    // E = 2 (sum A - |sum A n|), so the merge adds 2 (|S_a| + |S_b| - |S_a + S_b|)).
    double best_cost = kInfinity;
    uint32_t keep = kNoRegion, gone = kNoRegion;
    for (uint32_t f = 0; f < num_faces_; ++f) {
      const uint32_t a = labels_[f];
      for (FaceId g : adjacency_.neighbours[f]) {
        if (!g.valid()) continue;
        const uint32_t b = labels_[g.value()];
        if (b <= a) continue;  // each pair once, from its smaller id
        const double cost = 2.0 * (Norm(normal_sums_[a]) + Norm(normal_sums_[b]) -
                                   Norm(normal_sums_[a] + normal_sums_[b]));
        if (cost < best_cost || (cost == best_cost && (a < keep || (a == keep && b < gone)))) {
          best_cost = cost;
          keep = a;
          gone = b;
        }
      }
    }
    if (keep == kNoRegion || keep == worst || gone == worst) return false;
    if (!(best_cost < 0.5 * errors_[worst])) return false;
    uint32_t target = kNoFace;
    for (uint32_t f = 0; f < num_faces_; ++f) {
      if (labels_[f] != worst || seeds_[worst] == f) continue;
      if (target == kNoFace || face_cost_[f] > face_cost_[target]) target = f;
    }
    for (uint32_t f = 0; f < num_faces_; ++f) {
      if (labels_[f] == gone) labels_[f] = keep;
    }
    labels_[target] = gone;
    Fit();
    return true;
  }

 private:
  void Resize(uint32_t regions) {
    proxies_.resize(regions);
    seeds_.resize(regions, kNoFace);
    errors_.resize(regions, 0.0);
    sizes_.resize(regions, 0);
    normal_sums_.resize(regions);
    smallest_cost_.resize(regions, kInfinity);
  }

  // Claims every face of a neighbour of `face` that is still free for `region`. A claim
  // is only queued if it is cheaper than every earlier claim on that face: a dearer one
  // could only be popped after the face is taken, so it would be skipped anyway (lazy
  // deletion). Hence a face's claims in the heap have distinct costs, (cost, face) orders
  // all claims, and the flood's result does not depend on how the heap is operated. With
  // `replace_top`, the first claim takes the top's place (the caller has consumed the top);
  // returns whether it did.
  bool ClaimNeighbours(uint32_t face, uint32_t region, bool replace_top) {
    const Vec3 proxy = proxies_[region];
    for (FaceId g : adjacency_.neighbours[face]) {
      if (!g.valid()) continue;
      const uint32_t neighbour = g.value();
      if (labels_[neighbour] != kNoRegion) continue;
      const double cost = Cost(neighbour, proxy);
      if (cost >= best_cost_[neighbour]) continue;
      best_cost_[neighbour] = cost;
      if (replace_top) {
        heap_.ReplaceTop({cost, neighbour, region});
        replace_top = false;
        continue;
      }
      heap_.Push({cost, neighbour, region});
    }
    return !replace_top;
  }

  // Alg. 2.2: every region restarts from its seed; the cheapest pending claim is granted
  // next if its face is still free, and the face's free neighbours are claimed for the
  // same region against that region's proxy.
  void Flood() {
    if (IsCancelled(cancel_)) {
      cancelled_ = true;
      return;
    }
    labels_.swap(previous_labels_);
    std::fill(labels_.begin(), labels_.end(), kNoRegion);
    std::fill(best_cost_.begin(), best_cost_.end(), kInfinity);
    heap_.clear();
    const uint32_t k = num_regions();
    for (uint32_t region = 0; region < k; ++region) labels_[seeds_[region]] = region;
    for (uint32_t region = 0; region < k; ++region) {
      ClaimNeighbours(seeds_[region], region, /*replace_top=*/false);
    }
    uint32_t until_cancel_check = kFacesPerCancelCheck;
    while (!heap_.empty()) {
      if (--until_cancel_check == 0) {
        until_cancel_check = kFacesPerCancelCheck;
        if (IsCancelled(cancel_)) {
          cancelled_ = true;
          return;
        }
      }
      const Claim claim = heap_.Top();
      if (labels_[claim.face] != kNoRegion) {
        heap_.Pop();
        continue;
      }
      labels_[claim.face] = claim.region;
      if (!ClaimNeighbours(claim.face, claim.region, /*replace_top=*/true)) heap_.Pop();
    }
  }

  uint32_t CountChanged() const {
    uint32_t changed = 0;
    for (uint32_t f = 0; f < num_faces_; ++f) changed += labels_[f] != previous_labels_[f];
    return changed;
  }

  // Proxy fitting: N_i = normalised sum of A_j n_j over the region (a unit vector even when
  // the sum vanishes, as PlanarEnergy::FitProxy, so the costs add up to its energy); the
  // region's error is the sum of its faces' costs and its seed the cheapest face (the
  // first in face order on ties).
  void Fit() {
    const uint32_t k = num_regions();
    std::fill(normal_sums_.begin(), normal_sums_.end(), Vec3{});
    std::fill(sizes_.begin(), sizes_.end(), 0);
    for (uint32_t f = 0; f < num_faces_; ++f) {
      const FaceRecord& r = faces_[f];
      Vec3& sum = normal_sums_[labels_[f]];
      sum.x += r.area * r.x;
      sum.y += r.area * r.y;
      sum.z += r.area * r.z;
      ++sizes_[labels_[f]];
    }
    for (uint32_t region = 0; region < k; ++region) {
      const double length = Norm(normal_sums_[region]);
      proxies_[region] = length > 0 ? normal_sums_[region] / length : Vec3{0, 0, 1};
    }
    std::fill(errors_.begin(), errors_.end(), 0.0);
    std::fill(smallest_cost_.begin(), smallest_cost_.end(), kInfinity);
    for (uint32_t f = 0; f < num_faces_; ++f) {
      const uint32_t region = labels_[f];
      const double cost = Cost(f, proxies_[region]);
      face_cost_[f] = cost;
      errors_[region] += cost;
      if (cost < smallest_cost_[region]) {
        smallest_cost_[region] = cost;
        seeds_[region] = f;
      }
    }
    energy_ = 0;
    for (uint32_t region = 0; region < k; ++region) energy_ += errors_[region];
    fitted_ = true;
  }

  const FaceAdjacency& adjacency_;
  const uint32_t num_faces_;
  std::vector<FaceRecord> faces_;
  std::vector<uint32_t> labels_, previous_labels_;
  std::vector<double> best_cost_;  // per face: its cheapest claim in this flood
  std::vector<double> face_cost_;  // per face: its cost against its region's proxy
  ClaimHeap heap_;
  // Per region.
  std::vector<Vec3> proxies_;
  std::vector<uint32_t> seeds_;
  std::vector<double> errors_;
  std::vector<uint32_t> sizes_;
  std::vector<Vec3> normal_sums_;
  std::vector<double> smallest_cost_;
  const std::atomic<bool>* cancel_ = nullptr;
  bool cancelled_ = false;
  double energy_ = 0;
  bool fitted_ = false;  // proxies, errors, seeds and energy_ are those of labels_
};

// CGAL's error diffusion (Variational_shape_approximation::add_proxies_error_diffusion):
// `count` new seeds shared among the regions in proportion to their error, visiting the
// regions in increasing error and carrying each rounding residual to the next region so
// that the shares add up to `count`. With no error at all (a region per plane), shares
// follow the face counts instead. Unlike CGAL, a region gets at most size - 1 seeds (its
// non-seed faces) and whatever rounding or that cap leaves over goes to the regions of the
// largest error with room, so that every round adds exactly `count`.
std::vector<uint32_t> DiffuseSeeds(const Vsa& vsa, uint32_t count) {
  const uint32_t k = vsa.num_regions();
  const std::vector<double>& errors = vsa.errors();
  const std::vector<uint32_t>& sizes = vsa.sizes();
  std::vector<uint32_t> order(k);
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> weight(k);
  double total = 0;
  for (uint32_t r = 0; r < k; ++r) total += errors[r];
  if (total > 0) {
    for (uint32_t r = 0; r < k; ++r) weight[r] = errors[r];
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t a, uint32_t b) { return errors[a] < errors[b]; });
  } else {
    for (uint32_t r = 0; r < k; ++r) weight[r] = sizes[r];
    total = vsa.num_faces();
  }
  const double average = total / count;
  std::vector<uint32_t> share(k, 0);
  int64_t assigned = 0;
  double residual = 0;
  for (uint32_t r : order) {
    const double wanted = (residual + weight[r]) / average;
    const double rounded = std::floor(wanted + 0.5);
    residual = (wanted - rounded) * average;
    share[r] = std::min<uint32_t>(static_cast<uint32_t>(std::max(0.0, rounded)), sizes[r] - 1);
    assigned += share[r];
  }
  // Trim an excess from the regions of the smallest error, fill a shortfall from those of
  // the largest.
  for (auto it = order.begin(); assigned > count && it != order.end(); ++it) {
    const uint32_t take = std::min<int64_t>(share[*it], assigned - count);
    share[*it] -= take;
    assigned -= take;
  }
  for (auto it = order.rbegin(); assigned < count && it != order.rend(); ++it) {
    const uint32_t give = std::min<int64_t>(sizes[*it] - 1 - share[*it], count - assigned);
    share[*it] += give;
    assigned += give;
  }
  return share;
}

// Places each region's share of new seeds, farthest first: each new seed goes to the
// face that the region's proxy and the region's new seeds so far (each a proxy fitted to
// its face) fit worst, i.e. k-means++'s deterministic cousin applied within the region.
// CGAL takes the region's first faces in face order instead, which tends to put a
// region's seeds side by side. With everything else equal (before teleportation was added),
// farthest first gave lower energies on 9 of the 12 bench cases (fandisk, bunny00,
// armadillo, elephant at k = 50, 200, 1000), by up to 60% (fandisk at k = 50: 0.0066
// against 0.0165), and at most 0.4% higher ones on the other 3. Costs O(share x region
// size) per region.
std::vector<uint32_t> PlaceSeeds(const Vsa& vsa, const std::vector<uint32_t>& share) {
  const std::vector<uint32_t>& labels = vsa.labels();
  const std::vector<uint32_t>& seeds = vsa.seeds();
  const uint32_t k = vsa.num_regions();
  // The candidates (non-seed faces) of each region that gets seeds, grouped by region in
  // face order (a counting sort).
  std::vector<uint32_t> offset(k + 1, 0);
  for (uint32_t f = 0; f < vsa.num_faces(); ++f) {
    const uint32_t r = labels[f];
    if (share[r] > 0 && seeds[r] != f) ++offset[r + 1];
  }
  std::partial_sum(offset.begin(), offset.end(), offset.begin());
  std::vector<uint32_t> candidates(offset[k]);
  {
    std::vector<uint32_t> cursor(offset.begin(), offset.end() - 1);
    for (uint32_t f = 0; f < vsa.num_faces(); ++f) {
      const uint32_t r = labels[f];
      if (share[r] > 0 && seeds[r] != f) candidates[cursor[r]++] = f;
    }
  }
  std::vector<uint32_t> picked;
  std::vector<double> distance;  // per candidate: its cost against the nearest proxy
  for (uint32_t r = 0; r < k; ++r) {
    if (share[r] == 0) continue;
    const uint32_t* region = candidates.data() + offset[r];
    const size_t size = offset[r + 1] - offset[r];
    distance.resize(size);
    for (size_t i = 0; i < size; ++i) distance[i] = vsa.face_costs()[region[i]];
    for (uint32_t s = 0; s < share[r]; ++s) {
      size_t farthest = size;  // the first of the largest distance; taken ones are < 0
      for (size_t i = 0; i < size; ++i) {
        if (distance[i] >= 0 && (farthest == size || distance[i] > distance[farthest])) {
          farthest = i;
        }
      }
      picked.push_back(region[farthest]);
      distance[farthest] = -1;
      const Vec3 proxy = vsa.FaceProxy(region[farthest]);
      for (size_t i = 0; i < size; ++i) {
        if (distance[i] > 0) distance[i] = std::min(distance[i], vsa.Cost(region[i], proxy));
      }
    }
  }
  return picked;
}

void SeedRandom(Vsa& vsa, uint32_t k, uint32_t inner, Random& random, uint32_t& relaxations) {
  const uint32_t missing = k - vsa.num_regions();
  if (missing == 0) return;
  // A partial Fisher-Yates shuffle of the non-seed faces.
  std::vector<uint32_t> candidates;
  candidates.reserve(vsa.num_faces());
  std::vector<bool> is_seed(vsa.num_faces(), false);
  for (uint32_t s : vsa.seeds()) is_seed[s] = true;
  for (uint32_t f = 0; f < vsa.num_faces(); ++f) {
    if (!is_seed[f]) candidates.push_back(f);
  }
  for (uint32_t i = 0; i < missing; ++i) {
    std::swap(candidates[i], candidates[i + random.Below(candidates.size() - i)]);
  }
  for (uint32_t i = 0; i < missing; ++i) vsa.AddRegionAt(candidates[i]);
  relaxations += vsa.Relax(inner);
}

void SeedIncremental(Vsa& vsa, uint32_t k, uint32_t inner, uint32_t& relaxations) {
  while (vsa.num_regions() < k && !vsa.cancelled()) {
    // The region with the largest error that has a face besides its seed (one exists while
    // there are fewer regions than faces), and its costliest non-seed face.
    uint32_t worst = kNoRegion;
    for (uint32_t r = 0; r < vsa.num_regions(); ++r) {
      if (vsa.sizes()[r] > 1 && (worst == kNoRegion || vsa.errors()[r] > vsa.errors()[worst])) {
        worst = r;
      }
    }
    uint32_t face = kNoFace;
    for (uint32_t f = 0; f < vsa.num_faces(); ++f) {
      if (vsa.labels()[f] != worst || vsa.seeds()[worst] == f) continue;
      if (face == kNoFace || vsa.face_costs()[f] > vsa.face_costs()[face]) face = f;
    }
    vsa.AddRegionAt(face);
    relaxations += vsa.Relax(inner);
  }
}

void SeedHierarchical(Vsa& vsa, uint32_t k, uint32_t inner, uint32_t& relaxations) {
  while (vsa.num_regions() < k && !vsa.cancelled()) {
    const uint32_t target = std::min(k, 2 * vsa.num_regions());
    const std::vector<uint32_t> share = DiffuseSeeds(vsa, target - vsa.num_regions());
    for (uint32_t face : PlaceSeeds(vsa, share)) vsa.AddRegionAt(face);
    relaxations += vsa.Relax(inner);
  }
}

}  // namespace

absl::StatusOr<VsaOptions::Seeding> ParseVsaSeeding(absl::string_view name) {
  if (name == "random") return VsaOptions::Seeding::kRandom;
  if (name == "incremental") return VsaOptions::Seeding::kIncremental;
  if (name == "hierarchical") return VsaOptions::Seeding::kHierarchical;
  return absl::InvalidArgumentError(absl::StrCat(
      "unknown VSA seeding '", name, "' (expected random, incremental or hierarchical)"));
}

const char* VsaSeedingName(VsaOptions::Seeding seeding) {
  switch (seeding) {
    case VsaOptions::Seeding::kRandom:
      return "random";
    case VsaOptions::Seeding::kIncremental:
      return "incremental";
    case VsaOptions::Seeding::kHierarchical:
    default:
      return "hierarchical";
  }
}

absl::StatusOr<VsaResult> RunVsa(const MeshProblem& problem, const VsaOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshProblem(problem));
  const size_t num_faces = problem.mesh->num_faces();
  if (problem.energy.kind != MeshEnergyKind::kPlanar) {
    return absl::InvalidArgumentError(
        absl::StrCat("energy: VSA is defined for the planar (L2,1) energy only, not '",
                     MeshEnergyName(problem.energy.kind), "'"));
  }
  const uint32_t k = options.clusters;
  if (k == 0 || k > num_faces) {
    return absl::InvalidArgumentError(
        absl::StrCat("clusters: k = ", k, " is not in [1, ", num_faces, "] (the face count)"));
  }
  if (!(options.min_relative_decrease >= 0)) {
    return absl::InvalidArgumentError("min_relative_decrease must be >= 0");
  }

  auto cancelled = [] { return absl::CancelledError("cancelled during VSA"); };
  if (IsCancelled(options.cancel)) return cancelled();
  Vsa vsa(*problem.adjacency, *problem.measures);
  vsa.SetCancel(options.cancel);
  vsa.Reserve(k);
  const uint32_t components = vsa.StartFromComponents();
  if (k < components) {
    return absl::InvalidArgumentError(absl::StrCat("clusters: k = ", k, " is below the ",
                                                   components,
                                                   " connected components of the mesh "
                                                   "(every component needs a region)"));
  }

  VsaResult result;
  Random random(options.seed);
  switch (options.seeding) {
    case VsaOptions::Seeding::kRandom:
      SeedRandom(vsa, k, options.inner_iterations, random, result.seeding_iterations);
      break;
    case VsaOptions::Seeding::kIncremental:
      SeedIncremental(vsa, k, options.inner_iterations, result.seeding_iterations);
      break;
    case VsaOptions::Seeding::kHierarchical:
    default:
      SeedHierarchical(vsa, k, options.inner_iterations, result.seeding_iterations);
      break;
  }

  // With no relaxation the seeding's last regions are the carved-up regions before the
  // insertions, which need not be connected: one partition makes them so.
  if (options.inner_iterations == 0 && k > components) {
    vsa.Iterate();
    ++result.seeding_iterations;
  }
  if (vsa.cancelled() || IsCancelled(options.cancel)) return cancelled();

  // Lloyd iterations, keeping the best partition seen: flooding is greedy, so an iteration
  // may end slightly above the one before.
  result.initial_energy = vsa.energy();
  double best = vsa.energy();
  std::vector<uint32_t> best_labels = vsa.labels();
  result.initial_labels.resize(num_faces);
  for (size_t f = 0; f < num_faces; ++f) result.initial_labels[f] = ClusterId(best_labels[f]);
  std::vector<Vec3> best_proxies = vsa.proxies();
  std::vector<uint32_t> best_seeds = vsa.seeds();
  double previous = best;
  // The energy at the stall where the last teleport was done: another is tried only at a
  // stall of lower energy.
  double teleported_from = kInfinity;
  for (uint32_t iteration = 1; iteration <= options.iterations; ++iteration) {
    const uint32_t changed = vsa.Iterate();
    if (vsa.cancelled()) return cancelled();
    result.iterations = iteration;
    const double energy = vsa.energy();
    if (options.on_iteration) options.on_iteration(iteration, energy);
    if (energy < best) {
      best = energy;
      best_labels = vsa.labels();
      best_proxies = vsa.proxies();
      best_seeds = vsa.seeds();
      result.best_iteration = iteration;
    }
    // Stop at a fixed point or, if asked, at a small decrease; teleport there, and also
    // where the energy did not fall at all (Lloyd can cycle between equal partitions).
    const bool stop =
        changed == 0 || (options.min_relative_decrease > 0 &&
                         !(previous - energy >= options.min_relative_decrease * previous));
    const bool stalled = stop || !(energy < previous);
    previous = energy;
    if (!stalled) continue;
    if (options.teleport && iteration < options.iterations && energy < teleported_from &&
        vsa.Teleport()) {
      ++result.teleports;
      teleported_from = energy;
      previous = vsa.energy();
      continue;
    }
    if (!stop) continue;
    result.converged = true;
    break;
  }

  result.energy = best;
  result.labels.resize(num_faces);
  for (size_t f = 0; f < num_faces; ++f) result.labels[f] = ClusterId(best_labels[f]);
  result.proxies = std::move(best_proxies);
  result.seeds.resize(k);
  for (uint32_t r = 0; r < k; ++r) result.seeds[r] = FaceId(best_seeds[r]);
  return result;
}

}  // namespace mlclust
