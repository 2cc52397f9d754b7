// HC and ML for points on the GPU (points_levels.h, PointLevelsGpu::Step*): one merge per
// step, the CPU engine's queue of optimal dual edges (core/cluster/detail/ode_heap.h) and
// PointSpace::UpdateOdes' bookkeeping (core/cluster/point_clustering.cc), with the stored
// ODEs (binding 17) as the CPU's queue holds them: a cluster's ODE is recomputed only where
// the CPU recomputes it (the fresh ODEs of every cluster, binding 7, come from
// points_ode.glsl after each step), and a popped ODE whose partner is gone is recomputed
// and the choice made again (u_phase 5). After points_common.glsl. Phases:
//   0 (per cluster)  mark: the clusters the CPU refreshes after the step (those listing a
//                    gone cluster, then for each touched cluster in order itself and those
//                    listing it), appended with their group (the first place the CPU adds
//                    them); within a group by id (the CPU: its reverse lists' order)
//   1 (per listed)   order: each listed cluster's rank by (group, id)
//   2 (one)          refresh the ordered clusters [u_begin, u_end) one after the other
//                    (RefreshLocalNeighbours with the merged cluster and the gone one's
//                    neighbours as candidates; LinkIsolated where none is left)
//   3 (one)          the gone cluster's row emptied; the ODEs to recompute flagged: the
//                    refreshed clusters and the touched clusters' neighbours
//   7 (per cluster)  flag 2 (fresh ODE needed, not stored) where the stored ODE's partner
//                    is gone: phase 5 may need its fresh ODE (points_ode.glsl computes
//                    the fresh ODEs of the flagged clusters only)
//   4 (per cluster)  the flag-1 (every one with u_all) stored ODEs := the fresh ones
//   5 (one)          after ml_min_ode.glsl chose (pair_ids): a partner gone means that
//                    cluster's ODE is recomputed (stored := fresh) and the choice repeated
//   8 (one)          after the merge (pair_merge.glsl): the kept cluster's size, the kept
//                    and the gone cluster into the state, as the GPU decided them, and
//                    the two clusters' energy changes (their bits) after it (one read-back)
//   9 (per touched)  the touched clusters' places (1 + p) in their flags, for phase 0
//   6 (per listed)   the rows of the refreshed clusters (then the gone one's) gathered
//                    after the step's lists, for the host's mirror (ML)
layout(std430, binding = 4) buffer Neighbours { uint neighbours[]; };  // k x 2d, in place
layout(std430, binding = 7) readonly buffer FreshOdes { uint fresh[]; };  // 3 per cluster
layout(std430, binding = 8) readonly buffer PairIds { uint pair_ids[]; };
layout(std430, binding = 9) readonly buffer PairValues { double pair_values[]; };
layout(std430, binding = 17) buffer StoredOdes { uint stored[]; };  // 3 per cluster
// The step's scratch: state (listed, repaired, chosen, its partner), the touched clusters
// (u_touched), the listed clusters, the ordered ones, each cluster's group, the ODE flags,
// the gathered rows.
layout(std430, binding = 18) buffer Work { uint work[]; };
layout(location = 0) uniform uint u_count;  // cluster ids
layout(location = 1) uniform uint u_phase;
layout(location = 3) uniform uint u_touched;
layout(location = 4) uniform uint u_keep;
layout(location = 5) uniform uint u_gone;
layout(location = 6) uniform uint u_begin;
layout(location = 7) uniform uint u_end;
layout(location = 8) uniform uint u_all;
const uint kMaxSlots = 128u;  // 2 kVoxelStartMaxDims

uint TouchedAt(uint p) { return work[4u + p]; }
uint ListedAt(uint i) { return 4u + u_count + i; }
uint OrderedAt(uint i) { return 4u + 2u * u_count + i; }
uint GroupAt(uint c) { return 4u + 3u * u_count + c; }
uint FlagAt(uint c) { return 4u + 4u * u_count + c; }
uint RowAt(uint r) { return 4u + 5u * u_count + r * 2u * u_dims; }

bool Precedes(uint a, uint b) {
  uint ga = work[GroupAt(a)];
  uint gb = work[GroupAt(b)];
  return ga != gb ? ga < gb : a < b;
}

double best[kMaxSlots];
uint out_ids[kMaxSlots];

// RefreshLocalNeighbours' test of candidate n for cluster c.
void Offer(uint c, uint n) {
  if (n == kNone || n == c || counts[n] == 0u) return;
  uint s = Subspace(c, n);
  double dist = CentroidDistance(c, n);
  if (dist < best[s] || (dist == best[s] && n < out_ids[s])) {
    best[s] = dist;
    out_ids[s] = n;
  }
}

void RefreshOne(uint c) {
  uint slots = 2u * u_dims;
  double infinity = packDouble2x32(uvec2(0u, 0x7FF00000u));
  for (uint s = 0u; s < slots; ++s) {
    best[s] = infinity;
    out_ids[s] = kNone;
  }
  Offer(c, u_keep);
  for (uint s = 0u; s < slots; ++s) Offer(c, neighbours[u_gone * slots + s]);
  for (uint s = 0u; s < slots; ++s) {
    uint n = neighbours[c * slots + s];
    if (n == kNone) continue;
    Offer(c, n);
    for (uint t = 0u; t < slots; ++t) Offer(c, neighbours[n * slots + t]);
  }
  bool any = false;
  for (uint s = 0u; s < slots; ++s) any = any || out_ids[s] != kNone;
  if (!any) {
    for (uint n = 0u; n < u_count; ++n) Offer(c, n);
  }
  for (uint s = 0u; s < slots; ++s) neighbours[c * slots + s] = out_ids[s];
}

void main() {
  uint i = LinearInvocationIndex();
  uint slots = 2u * u_dims;
  if (u_phase == 0u || u_phase == 4u || u_phase == 7u) {
    if (i >= u_count) return;
    if (u_phase == 7u) {
      uint partner = stored[3u * i + 2u];
      if (work[FlagAt(i)] == 0u && counts[i] != 0u && partner != 0u && counts[partner - 1u] == 0u) {
        work[FlagAt(i)] = 2u;
      }
      return;
    }
    if (u_phase == 4u) {
      if (u_all != 0u || work[FlagAt(i)] == 1u) {
        for (uint w = 0u; w < 3u; ++w) stored[3u * i + w] = fresh[3u * i + w];
      }
      work[FlagAt(i)] = 0u;
      return;
    }
    if (counts[i] == 0u) return;
    // A touched cluster's flag holds 1 + its place p (phase 9): O(2d) per cluster.
    uint group = kNone;
    for (uint s = 0u; s < slots; ++s) {
      uint n = neighbours[i * slots + s];
      if (n == kNone) continue;
      if (n == u_gone) group = 0u;
      uint place = work[FlagAt(n)];
      if (place != 0u) group = min(group, 2u * place);
    }
    uint own = work[FlagAt(i)];
    if (own != 0u) group = min(group, 2u * own - 1u);
    if (group == kNone) return;
    work[GroupAt(i)] = group;
    work[ListedAt(atomicAdd(work[0], 1u))] = i;
    return;
  }
  if (u_phase == 9u) {
    if (i < u_touched) work[FlagAt(TouchedAt(i))] = i + 1u;
    return;
  }
  if (u_phase == 6u) {
    uint listed = work[0];
    if (i > listed) return;
    uint c = i < listed ? work[OrderedAt(i)] : u_gone;
    for (uint s = 0u; s < slots; ++s) work[RowAt(i) + s] = neighbours[c * slots + s];
    return;
  }
  if (u_phase == 1u) {
    uint listed = work[0];
    if (i >= listed) return;
    uint c = work[ListedAt(i)];
    uint rank = 0u;
    for (uint j = 0u; j < listed; ++j) rank += Precedes(work[ListedAt(j)], c) ? 1u : 0u;
    work[OrderedAt(rank)] = c;
    return;
  }
  if (i != 0u) return;
  if (u_phase == 2u) {
    for (uint r = u_begin; r < u_end; ++r) RefreshOne(work[OrderedAt(r)]);
  } else if (u_phase == 3u) {
    for (uint p = 0u; p < u_touched; ++p) work[FlagAt(TouchedAt(p))] = 0u;  // phase 9's
    for (uint s = 0u; s < slots; ++s) neighbours[u_gone * slots + s] = kNone;
    uint listed = work[0];
    for (uint r = 0u; r < listed; ++r) work[FlagAt(work[OrderedAt(r)])] = 1u;
    for (uint p = 0u; p < u_touched; ++p) {
      uint c = TouchedAt(p);
      for (uint s = 0u; s < slots; ++s) {
        uint n = neighbours[c * slots + s];
        if (n != kNone && counts[n] != 0u) work[FlagAt(n)] = 1u;
      }
    }
  } else if (u_phase == 8u) {
    uint a = pair_ids[0];
    uint b = pair_ids[1];
    uint keep = counts[a] != 0u ? a : b;
    work[1] = counts[keep];
    work[2] = keep;
    work[3] = keep == a ? b : a;
    uvec2 keep_change = unpackDouble2x32(pair_values[1]);
    uvec2 gone_change = unpackDouble2x32(pair_values[2]);
    work[4] = keep_change.x;
    work[5] = keep_change.y;
    work[6] = gone_change.x;
    work[7] = gone_change.y;
  } else if (u_phase == 5u) {
    uint chosen = pair_ids[0];
    uint partner = pair_ids[1];
    bool repair = chosen != kNone && counts[partner] == 0u;
    if (repair) {
      for (uint w = 0u; w < 3u; ++w) stored[3u * chosen + w] = fresh[3u * chosen + w];
    }
    work[1] = repair ? 1u : 0u;
    work[2] = chosen;
    work[3] = partner;
  }
}
