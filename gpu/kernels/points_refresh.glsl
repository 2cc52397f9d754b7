// ML/PML for points on the GPU (points_levels.h): every live cluster's local neighbours
// (eq. 6.1) after a level, one invocation per cluster id, from the table before the level
// (neighbours_in) to the new one (neighbours_out): the candidates are the cluster's
// neighbours and theirs, and where it kept a partner this level the partner's neighbours
// and theirs (PointClusters::RefreshNeighbours' second-order candidates), each mapped
// through remap to the cluster it merged into; per subspace the nearest candidate
// centroid, equal distances to the smaller id (so the result does not depend on the
// order of the candidates). A live cluster left with no neighbour takes the nearest in
// each subspace among all live clusters (the CPU's LinkIsolated); with u_link_all every
// live cluster does (the CPU's ConnectWhenStuck). Gone clusters get an empty row.
// All rows are refreshed from the table before the level at once (the CPU refreshes the
// clusters the level touched one after the other). After points_common.glsl.
layout(std430, binding = 3) readonly buffer Remap { uint remap[]; };
layout(std430, binding = 4) readonly buffer NeighboursIn { uint neighbours_in[]; };
layout(std430, binding = 5) writeonly buffer NeighboursOut { uint neighbours_out[]; };
layout(std430, binding = 15) readonly buffer Partner { uint partner[]; };
layout(location = 0) uniform uint u_count;  // cluster ids
layout(location = 3) uniform uint u_level;
layout(location = 4) uniform uint u_link_all;
const uint kMaxSlots = 128u;  // 2 kVoxelStartMaxDims

double best[kMaxSlots];
uint out_ids[kMaxSlots];

void Offer(uint c, uint n) {
  if (n == kNone) return;
  uint x = remap[n];
  if (x == c || counts[x] == 0u) return;
  uint s = Subspace(c, x);
  double dist = CentroidDistance(c, x);
  if (dist < best[s] || (dist == best[s] && x < out_ids[s])) {
    best[s] = dist;
    out_ids[s] = x;
  }
}

// n's own neighbours and theirs (rows of the table before the level).
void OfferAround(uint c, uint n) {
  uint slots = 2u * u_dims;
  for (uint s = 0u; s < slots; ++s) {
    uint x = neighbours_in[n * slots + s];
    if (x == kNone) continue;
    Offer(c, x);
    for (uint t = 0u; t < slots; ++t) Offer(c, neighbours_in[x * slots + t]);
  }
}

void main() {
  uint c = LinearInvocationIndex();
  if (c >= u_count) return;
  uint slots = 2u * u_dims;
  double infinity = packDouble2x32(uvec2(0u, 0x7FF00000u));
  for (uint s = 0u; s < slots; ++s) {
    best[s] = infinity;
    out_ids[s] = kNone;
  }
  if (counts[c] > 0u) {
    if (u_link_all == 0u) {
      OfferAround(c, c);
      if (partner[2u * c + 1u] == u_level && partner[2u * c] != kNone) {
        OfferAround(c, partner[2u * c]);
      }
    }
    bool any = false;
    for (uint s = 0u; s < slots; ++s) any = any || out_ids[s] != kNone;
    if (!any) {
      for (uint n = 0u; n < u_count; ++n) Offer(c, n);
    }
  }
  for (uint s = 0u; s < slots; ++s) neighbours_out[c * slots + s] = out_ids[s];
}
