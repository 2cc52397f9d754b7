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
// A step is not taken (and the batch ends) at u_lowest clusters, without an ODE left, where
// gone's faces would overflow the log (u_log_capacity faces), or, after the batch's first
// step, once the loop iterations spent exceed u_loop_budget.
//
// Loop budget: llvmpipe ends every loop of an invocation once 65,535 loop iterations in all
// have run in it (gallivm's LP_MAX_TGSI_LOOP_ITERATIONS, shared by every loop of the
// shader), silently. So each invocation counts its loop iterations, the group's sum (an
// upper bound of any SIMD batch's count) ends a batch at u_loop_budget (the host sets it
// on software renderers), the member walk is unrolled by 8, and after every step a canary
// loop of u_two iterations checks that the limit was not reached: if it was, control[4]
// is set and the host fails the pass (a step too large for the driver: INTERNAL).
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
// clusters left, steps of this batch, log faces used, steps in all (the marks), the loop
// limit reached (0 or 1)
layout(std430, binding = 13) buffer Control { uint control[]; };
layout(location = 2) uniform uint u_max_steps;
layout(location = 3) uniform uint u_lowest;
layout(location = 4) uniform uint u_log_capacity;
layout(location = 5) uniform uint u_loop_budget;
layout(location = 6) uniform uint u_two;  // 2, not a constant: the canary loop stays a loop

const uint kMaxLevels = 8u;
shared uint s_size[kMaxLevels];    // LevelSize(l)
shared uint s_offset[kMaxLevels];  // LevelOffset(l), l >= 1
shared uint s_spent;
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

// Invocation 0: the step's collapse, or s_go = 0. Returns the loop iterations spent.
uint Collapse(uint step, uint top) {
  s_go = 0u;
  uint left = control[0];
  if (left <= u_lowest) return 0u;
  if (step > 0u && s_spent > u_loop_budget) return 0u;
  uint a = tree[2u * s_offset[top]];
  if (!HasOde(a)) return 0u;
  uint b = clusters[a].partner;
  uint size_a = clusters[a].size;
  uint size_b = clusters[b].size;
  bool a_keeps = size_a > size_b || (size_a == size_b && a < b);
  uint keep = a_keeps ? a : b;
  uint gone = a_keeps ? b : a;
  uint gone_size = a_keeps ? size_b : size_a;
  uint used = control[2];
  if (used + gone_size > u_log_capacity) return 0u;
  precise double keep_before = CvdEnergy(keep);
  precise double gone_before = CvdEnergy(gone);
  AddCvdSums(keep, gone);
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
  uint spent = 0u;
  uint at = used;
  uint f = clusters[gone].mhead;
  while (f != kNone) {  // unrolled by 8 where the compiler unrolls the inner loop
    ++spent;
    for (uint k = 0u; k < 8u && f != kNone; ++k) {
      ++spent;  // counted as if it did not
      labels[f] = keep;
      log_faces[at] = f;
      ++at;
      f = member_next[f];
    }
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
    ++spent;
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
  return spent + 8u;
}

// Returns the loop iterations spent.
uint UpdateNeighbour(uint d, uint keep, uint gone) {
  uint partner = clusters[d].partner;
  uint spent = 1u;
  if (partner == keep || partner == gone) {
    double best = Infinity();
    uint best_d = kNone;
    for (uint e = clusters[d].ehead; e != kNone; e = edge_next[e]) {
      ++spent;
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
    return spent;
  }
  double cost = CvdMergeCost(d, keep);
  if (CheaperDualEdge(cost, keep, ode_cost[d], partner)) {
    clusters[d].partner = keep;
    ode_cost[d] = cost;
  }
  return spent;
}

// hc_common.glsl's RecomputeNode with the levels' sizes and offsets from shared memory and
// the children's loop unrolled by 4. Returns the loop iterations spent.
uint RecomputeNodeInStep(uint level, uint node) {
  uint best = kNone;
  uint first = node * kFanout;
  uint end = min(first + kFanout, s_size[level - 1u]);
  uint child_offset = s_offset[level - 1u];
  uint spent = 0u;
  for (uint i = first; i < end; i += 4u) {
    ++spent;
    for (uint k = i; k < min(i + 4u, end); ++k) {
      uint c = level == 1u ? k : tree[2u * (child_offset + k)];
      if (Before(c, best)) best = c;
    }
  }
  tree[2u * (s_offset[level] + node)] = best;
  return spent;
}

void main() {
  uint t = gl_LocalInvocationID.x;
  uint group = gl_WorkGroupSize.x;
  uint top = TopLevel();
  if (t == 0u) {
    for (uint level = 0u; level < kMaxLevels; ++level) {
      s_size[level] = LevelSize(level);
      s_offset[level] = level >= 1u ? LevelOffset(level) : 0u;
    }
    s_spent = 0u;
  }
  memoryBarrierShared();
  barrier();
  for (uint step = 0u; step < u_max_steps; ++step) {
    uint spent = 0u;
    if (t == 0u) spent += Collapse(step, top);
    memoryBarrier();
    barrier();
    if (s_go == 0u) break;
    uint keep = s_keep;
    uint gone = s_gone;
    uint count = s_count;
    uint mark = s_mark;
    for (uint i = 2u + t; i < count; i += group) spent += UpdateNeighbour(touched[i], keep, gone);
    memoryBarrier();
    barrier();
    for (uint level = 1u; level <= top; ++level) {
      uint offset = s_offset[level];
      for (uint i = t; i < count; i += group) {
        ++spent;
        uint node = touched[i] >> (5u * level);
        if (atomicExchange(tree[2u * (offset + node) + 1u], mark) != mark) {
          spent += RecomputeNodeInStep(level, node);
        }
      }
      memoryBarrier();
      barrier();
    }
    // The canary: a loop of two iterations runs one where the driver's limit was reached.
    uint canary = 0u;
    for (uint k = 0u; k < u_two; ++k) ++canary;
    if (canary != 2u) atomicOr(control[4], 1u);
    atomicAdd(s_spent, spent + top + 4u);
    memoryBarrierShared();
    barrier();
  }
}
