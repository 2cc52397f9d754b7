// HC on the GPU (hc_levels.h): what the HC kernels share, after pml_cvd.glsl (the CVD
// merge cost and energy, binding 0). Per cluster c: its Cluster record and its ODE's cost;
// the tree of minima over the clusters' ODEs: level 0 are the clusters (implicit), a node
// of level l >= 1 holds the winner of its 32 children of level l - 1 (kNone: none), the
// levels 1, 2, ... one after the other in `tree` as (winner, mark) pairs; the last level
// has one node, the root. The order of the ODEs is the CPU queue's (OdeHeap, CheaperLast):
// cheaper first, then the smaller tie key (the cluster's size with u_tie_by_size, else
// none), then the smaller id; a cluster without an ODE (merged away, or no neighbour left)
// is never a winner.
const uint kNone = 0xFFFFFFFFu;
const uint kFanout = 32u;  // kHcTreeFanout
struct Cluster {
  uint size;     // faces (0: merged away)
  uint partner;  // the ODE's other cluster, kNone for none
  uint stamp;    // the last step that listed it as touched
  uint ehead;    // its directed face edges (a list through edge_next), kNone: none
  uint etail;
  uint mhead;    // its faces in the CPU engine's member order (through member_next)
  uint mtail;
  uint pad;
};
layout(std430, binding = 1) buffer Clusters { Cluster clusters[]; };
layout(std430, binding = 2) buffer OdeCost { double ode_cost[]; };
layout(std430, binding = 9) buffer Tree { uint tree[]; };  // (winner, mark) per node
layout(location = 0) uniform uint u_clusters;              // cluster ids (the faces)
layout(location = 1) uniform uint u_tie_by_size;

bool HasOde(uint c) { return c != kNone && clusters[c].partner != kNone; }

// Whether the ODE of x goes before that of y.
bool Before(uint x, uint y) {
  if (!HasOde(x)) return false;
  if (!HasOde(y)) return true;
  double cx = ode_cost[x];
  double cy = ode_cost[y];
  if (cx != cy) return cx < cy;
  uint kx = u_tie_by_size != 0u ? clusters[x].size : 0u;
  uint ky = u_tie_by_size != 0u ? clusters[y].size : 0u;
  if (kx != ky) return kx < ky;
  return x < y;
}

uint LevelSize(uint level) {
  uint size = u_clusters;
  for (uint l = 0u; l < level; ++l) size = (size + kFanout - 1u) / kFanout;
  return size;
}
// The index of level `level`'s (>= 1) first node in `tree`.
uint LevelOffset(uint level) {
  uint offset = 0u;
  uint size = u_clusters;
  for (uint l = 1u; l < level; ++l) {
    size = (size + kFanout - 1u) / kFanout;
    offset += size;
  }
  return offset;
}
// The root's level (>= 1 for two or more clusters).
uint TopLevel() {
  uint size = u_clusters;
  uint level = 0u;
  while (size > 1u) {
    size = (size + kFanout - 1u) / kFanout;
    ++level;
  }
  return max(level, 1u);
}

// Node `node` of level `level` (>= 1) from its children.
void RecomputeNode(uint level, uint node) {
  uint best = kNone;
  uint first = node * kFanout;
  uint end = min(first + kFanout, LevelSize(level - 1u));
  uint child_offset = level >= 2u ? LevelOffset(level - 1u) : 0u;
  for (uint i = first; i < end; ++i) {
    uint c = level == 1u ? i : tree[2u * (child_offset + i)];
    if (Before(c, best)) best = c;
  }
  tree[2u * (LevelOffset(level) + node)] = best;
}
