// ML/PML for points on the GPU (points_levels.h): the points' part of the mutual pairs
// (mutual_pairs.glsl follows): a cluster is empty at count 0, a pair costs its Ward cost.
// After points_common.glsl.
bool ClusterIsEmpty(uint c) { return counts[c] == 0u; }
double PairMergeCost(uint c, uint d) { return WardCost(c, d); }
