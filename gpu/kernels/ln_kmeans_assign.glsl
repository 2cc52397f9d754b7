// LnKmeansKernel::Assign (ln_kmeans.h): LN k-means' assign stage (Alg. 6.1), one
// invocation per point to check. The same rule as ChooseTargets
// (core/cluster/detail/ln_kmeans_stages.h): the point's best cluster among its own, its
// cluster's local neighbours and the neighbours of the neighbour in the point's subspace
// (eq. 6.1), in that order, at most 256 candidates; ties to the smaller id. Distances in
// fp64 from the float coordinates less the data's mean. With u_margins, also ChooseTargets'
// margin: for a point that stays, the distance to its second-best candidate less the
// distance to its own centroid; -infinity for a point that moves. Entries from u_full on
// are compared with their own candidates only (the CPU's round 0 for the points next to a
// merged cluster, PointSpace::Optimise): entry u_full + e has the candidates
// check[base + g] for g in [check[u_count + 2e], check[u_count + 2e + 1]), base = u_count +
// 2 (u_count - u_full); it moves to the nearest that is strictly nearer than its own
// centroid (margin 0, not used). After the prelude of gpu/context/compute.h.
layout(std430, binding = 0) readonly buffer Points { float points[]; };         // d per point
layout(std430, binding = 1) readonly buffer Origin { double origin[]; };        // d
layout(std430, binding = 2) readonly buffer Labels { uint labels[]; };          // per point
layout(std430, binding = 3) readonly buffer Centroids { double centroids[]; };  // d per cluster
layout(std430, binding = 4) readonly buffer Neighbours { uint neighbours[]; };  // 2d per cluster
layout(std430, binding = 5) readonly buffer Counts { uint counts[]; };          // per cluster
layout(std430, binding = 6) readonly buffer Check { uint check[]; };            // points to check
layout(std430, binding = 7) writeonly buffer Targets { uint targets[]; };       // per check entry
layout(location = 0) uniform uint u_count;  // entries of check
layout(location = 1) uniform uint u_dims;   // d
layout(std430, binding = 8) writeonly buffer Margins { double margins[]; };  // per check entry
layout(location = 2) uniform uint u_margins;  // 1: write margins
layout(location = 3) uniform uint u_full;     // entries before it get the full rule
const uint kNone = 0xFFFFFFFFu;
const uint kMaxCandidates = 256u;

double Coordinate(uint point, uint j) { return double(points[point * u_dims + j]) - origin[j]; }

double Distance(uint point, uint cluster) {
  precise double dist = 0.0LF;
  for (uint j = 0u; j < u_dims; ++j) {
    precise double diff = Coordinate(point, j) - centroids[cluster * u_dims + j];
    dist += diff * diff;
  }
  return dist;
}

uint own;
uint best_cluster;
double best;
double second;

void Consider(uint point, uint n) {
  if (n == best_cluster || counts[n] == 0u) return;
  double dist = Distance(point, n);
  if (dist < best || (dist == best && n < best_cluster && n != own)) {
    second = best;
    best = dist;
    best_cluster = n;
  } else if (dist < second) {
    second = dist;
  }
}

void main() {
  uint r = LinearInvocationIndex();
  if (r >= u_count) return;
  uint point = check[r];
  own = labels[point];
  if (r >= u_full) {
    uint e = r - u_full;
    uint base = u_count + 2u * (u_count - u_full);
    double nearest = Distance(point, own);
    uint to = kNone;
    for (uint g = check[u_count + 2u * e]; g < check[u_count + 2u * e + 1u]; ++g) {
      uint candidate = check[base + g];
      double dist = Distance(point, candidate);
      if (dist < nearest) {
        nearest = dist;
        to = candidate;
      }
    }
    targets[r] = to;
    if (u_margins != 0u) margins[r] = 0.0LF;
    return;
  }
  // SubspaceIndex(centroid(own), x): the axis of the largest difference (ties to the lower
  // axis) and its sign.
  uint axis = 0u;
  double largest = -1.0LF;
  for (uint j = 0u; j < u_dims; ++j) {
    double diff = abs(Coordinate(point, j) - centroids[own * u_dims + j]);
    if (diff > largest) {
      largest = diff;
      axis = j;
    }
  }
  uint subspace = 2u * axis + (Coordinate(point, axis) > centroids[own * u_dims + axis] ? 0u : 1u);
  double own_distance = Distance(point, own);
  best = own_distance;
  best_cluster = own;
  second = packDouble2x32(uvec2(0u, 0x7FF00000u));  // +infinity
  uint count = 0u;
  uint width = 2u * u_dims;
  for (uint t = 0u; t < width; ++t) {
    uint n = neighbours[own * width + t];
    if (n == kNone || count >= kMaxCandidates) continue;
    ++count;
    Consider(point, n);
  }
  uint towards = neighbours[own * width + subspace];
  if (towards != kNone) {
    for (uint t = 0u; t < width; ++t) {
      uint n = neighbours[towards * width + t];
      if (n == kNone || n == own || count >= kMaxCandidates) continue;
      ++count;
      Consider(point, n);
    }
  }
  targets[r] = best_cluster != own ? best_cluster : kNone;
  if (u_margins != 0u) {
    margins[r] = best_cluster != own ? packDouble2x32(uvec2(0u, 0xFFF00000u))  // -infinity
                                     : sqrt(second) - sqrt(own_distance);
  }
}
