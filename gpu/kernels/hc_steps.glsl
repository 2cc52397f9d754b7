// HC on the GPU (hc_levels.h): up to u_max_steps merges (Alg. 5.6 without optimisation,
// one collapse per step) in one work group, after "#version 450" with the group's size,
// pml_cvd.glsl and hc_common.glsl. Each step:
//   invocation 0   the root of the tree is the cheapest ODE (a, b): the larger cluster
//                  keeps its id, the smaller id on equal sizes (KeepAndGone); the sums are
//                  added (keep + gone, CvdSums::operator+=), the energy changes kept; gone's
//                  faces are relabelled and logged in member order (the CPU's triplet
//                  order); the member and edge lists are joined; keep's edges are walked,
//                  those now inside keep unlinked, giving keep's ODE and its distinct
//                  neighbours (the touched list: keep, gone, then the neighbours)
//   all            every neighbour d: where its ODE was keep or gone, recomputed from its
//                  edges; else it takes the edge to keep if cheaper (CheaperDualEdge: equal
//                  costs to the larger id) — the CPU engine's UpdateOdes gives the same
//   all            the tree nodes above the touched clusters, level by level (each node
//                  once per step through its mark)
// A step is not taken (and the batch ends) at u_lowest clusters, without an ODE left, or
// where gone's faces would overflow the log (u_log_capacity faces).
layout(std430, binding = 3) buffer Labels { uint labels[]; };
layout(std430, binding = 4) readonly buffer Edges { uint edges[]; };  // (face, neighbour)
layout(std430, binding = 5) buffer EdgeNext { uint edge_next[]; };
layout(std430, binding = 8) buffer MemberNext { uint member_next[]; };
layout(std430, binding = 10) buffer Touched { uint touched[]; };
struct Step {
  uint keep;
  uint gone;
  uint first;  // gone's faces are log_faces[first, first + count)
  uint count;
  double keep_change;  // E(keep after) - E(keep before)
  double gone_change;  // 0 - E(gone before)
};
layout(std430, binding = 11) writeonly buffer Steps { Step steps[]; };
layout(std430, binding = 12) writeonly buffer LogFaces { uint log_faces[]; };
// clusters left, steps of this batch, log faces used, steps in all (the marks)
layout(std430, binding = 13) buffer Control { uint control[]; };
layout(location = 2) uniform uint u_max_steps;
layout(location = 3) uniform uint u_lowest;
layout(location = 4) uniform uint u_log_capacity;

shared uint s_go;
shared uint s_keep;
shared uint s_gone;
shared uint s_count;
shared uint s_mark;

double Infinity() { return packDouble2x32(uvec2(0u, 0x7FF00000u)); }

// core/cluster/detail/ode_heap.h's CheaperDualEdge.
bool CheaperDualEdge(double cost, uint candidate, double best_cost, uint best_partner) {
  return cost < best_cost ||
         (cost == best_cost && best_partner != kNone && candidate > best_partner) ||
         (best_partner == kNone && cost <= best_cost);
}

void Collapse() {
  s_go = 0u;
  uint left = control[0];
  if (left <= u_lowest) return;
  uint a = tree[2u * LevelOffset(TopLevel())];
  if (!HasOde(a)) return;
  uint b = clusters[a].partner;
  uint size_a = clusters[a].size;
  uint size_b = clusters[b].size;
  bool a_keeps = size_a > size_b || (size_a == size_b && a < b);
  uint keep = a_keeps ? a : b;
  uint gone = a_keeps ? b : a;
  uint gone_size = a_keeps ? size_b : size_a;
  uint used = control[2];
  if (used + gone_size > u_log_capacity) return;
  precise double keep_before = CvdEnergy(keep);
  precise double gone_before = CvdEnergy(gone);
  for (uint j = 0u; j < 5u; ++j) {
    precise double sum = sums[5u * keep + j] + sums[5u * gone + j];
    sums[5u * keep + j] = sum;
    sums[5u * gone + j] = 0.0LF;
  }
  precise double keep_after = CvdEnergy(keep);
  uint mark = control[3] + 1u;
  control[3] = mark;
  uint record = control[1];
  control[1] = record + 1u;
  control[0] = left - 1u;
  steps[record].keep = keep;
  steps[record].gone = gone;
  steps[record].first = used;
  steps[record].count = gone_size;
  steps[record].keep_change = keep_after - keep_before;
  steps[record].gone_change = 0.0LF - gone_before;
  uint at = used;
  for (uint f = clusters[gone].mhead; f != kNone; f = member_next[f]) {
    labels[f] = keep;
    log_faces[at] = f;
    ++at;
  }
  control[2] = at;
  member_next[clusters[keep].mtail] = clusters[gone].mhead;
  clusters[keep].mtail = clusters[gone].mtail;
  if (clusters[gone].ehead != kNone) {
    if (clusters[keep].ehead == kNone) {
      clusters[keep].ehead = clusters[gone].ehead;
    } else {
      edge_next[clusters[keep].etail] = clusters[gone].ehead;
    }
    clusters[keep].etail = clusters[gone].etail;
  }
  clusters[keep].size = size_a + size_b;
  clusters[gone].size = 0u;
  clusters[gone].partner = kNone;
  clusters[gone].ehead = kNone;
  clusters[gone].etail = kNone;
  clusters[gone].mhead = kNone;
  clusters[gone].mtail = kNone;
  ode_cost[gone] = Infinity();
  clusters[keep].stamp = mark;
  clusters[gone].stamp = mark;
  touched[0] = keep;
  touched[1] = gone;
  uint count = 2u;
  double best = Infinity();
  uint best_d = kNone;
  uint prev = kNone;
  uint e = clusters[keep].ehead;
  while (e != kNone) {
    uint next = edge_next[e];
    uint d = labels[edges[2u * e + 1u]];
    if (d == keep) {  // inside keep now: unlinked
      if (prev == kNone) {
        clusters[keep].ehead = next;
      } else {
        edge_next[prev] = next;
      }
      e = next;
      continue;
    }
    prev = e;
    double cost = CvdMergeCost(keep, d);
    if (CheaperDualEdge(cost, d, best, best_d)) {
      best = cost;
      best_d = d;
    }
    if (clusters[d].stamp != mark) {
      clusters[d].stamp = mark;
      touched[count] = d;
      ++count;
    }
    e = next;
  }
  clusters[keep].etail = prev;
  clusters[keep].partner = best_d;
  ode_cost[keep] = best;
  s_keep = keep;
  s_gone = gone;
  s_count = count;
  s_mark = mark;
  s_go = 1u;
}

void UpdateNeighbour(uint d, uint keep, uint gone) {
  uint partner = clusters[d].partner;
  if (partner == keep || partner == gone) {
    double best = Infinity();
    uint best_d = kNone;
    for (uint e = clusters[d].ehead; e != kNone; e = edge_next[e]) {
      uint x = labels[edges[2u * e + 1u]];
      if (x == d) continue;
      double cost = CvdMergeCost(d, x);
      if (CheaperDualEdge(cost, x, best, best_d)) {
        best = cost;
        best_d = x;
      }
    }
    clusters[d].partner = best_d;
    ode_cost[d] = best;
    return;
  }
  double cost = CvdMergeCost(d, keep);
  if (CheaperDualEdge(cost, keep, ode_cost[d], partner)) {
    clusters[d].partner = keep;
    ode_cost[d] = cost;
  }
}

void main() {
  uint t = gl_LocalInvocationID.x;
  uint group = gl_WorkGroupSize.x;
  uint top = TopLevel();
  for (uint step = 0u; step < u_max_steps; ++step) {
    if (t == 0u) Collapse();
    memoryBarrier();
    barrier();
    if (s_go == 0u) break;
    uint keep = s_keep;
    uint gone = s_gone;
    uint count = s_count;
    uint mark = s_mark;
    for (uint i = 2u + t; i < count; i += group) UpdateNeighbour(touched[i], keep, gone);
    memoryBarrier();
    barrier();
    for (uint level = 1u; level <= top; ++level) {
      uint offset = LevelOffset(level);
      for (uint i = t; i < count; i += group) {
        uint node = touched[i] >> (5u * level);
        if (atomicExchange(tree[2u * (offset + node) + 1u], mark) != mark) {
          RecomputeNode(level, node);
        }
      }
      memoryBarrier();
      barrier();
    }
  }
}
