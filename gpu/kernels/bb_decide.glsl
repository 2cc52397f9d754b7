// BoundaryBasedDecider (bb_decide.h): the decide stage of boundary-based optimisation
// (Alg. 5.1 as the GPU passes of Alg. 5.4/5.5), one invocation per face, against proxies
// fixed for the sweep. The same rule as DecideBoundaryMove (core/cluster/boundary_based.h):
// among the clusters of the face's edge neighbours other than its own, the one with the
// smallest cost (the first in edge order on ties), if it beats the own cluster's cost by
// more than 1e-12 relative; otherwise kNoMove. Costs in fp64:
//   cost(face, cluster) = (weight_c * mass_f) * |point_f - point_c|^2
// which is FaceCost of every energy whose proxy is a point and a weight (CVD, adaptive CVD,
// MWCVD: point = centroid; planar: point = unit normal). After the prelude of
// gpu/context/compute.h.
//
// Only the proposals come back: a face that moves appends (face, target) through an atomic
// counter (stream compaction; the order is arbitrary, each face appears at most once), so a
// sweep reads back 8 bytes per proposal instead of 4 per face.
layout(std430, binding = 0) readonly buffer Neighbours { uint neighbours[]; };  // 3 per face
layout(std430, binding = 1) readonly buffer Labels { uint labels[]; };          // 1 per face
layout(std430, binding = 2) readonly buffer Faces { dvec4 faces[]; };           // point, mass
layout(std430, binding = 3) readonly buffer Proxies { dvec4 proxies[]; };       // point, weight
layout(std430, binding = 4) writeonly buffer Proposals { uvec2 proposals[]; };  // (face, target)
layout(std430, binding = 5) buffer ProposalCount { uint proposal_count; };       // reset to 0
layout(location = 0) uniform uint u_face_count;
const uint kInvalid = 0xFFFFFFFFu;  // no neighbour across the edge; kNoMove

double Cost(dvec4 face, dvec4 proxy) {
  dvec3 d = face.xyz - proxy.xyz;
  precise double squared = d.x * d.x + d.y * d.y + d.z * d.z;
  precise double cost = (proxy.w * face.w) * squared;
  return cost;
}

void main() {
  uint face = LinearInvocationIndex();
  if (face >= u_face_count) return;
  uint own = labels[face];
  dvec4 point = faces[face];
  double best = Cost(point, proxies[own]);
  double own_cost = best;
  uint best_cluster = own;
  for (uint edge = 0u; edge < 3u; ++edge) {
    uint neighbour = neighbours[3u * face + edge];
    if (neighbour == kInvalid) continue;
    uint c = labels[neighbour];
    if (c == own || c == best_cluster) continue;
    double cost = Cost(point, proxies[c]);
    if (cost < best) {
      best = cost;
      best_cluster = c;
    }
  }
  if (best_cluster != own && own_cost - best > 1e-12LF * own_cost) {
    proposals[atomicAdd(proposal_count, 1u)] = uvec2(face, best_cluster);
  }
}
