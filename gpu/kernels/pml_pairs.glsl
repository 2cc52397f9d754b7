// PML on the GPU (pml_levels.h): the mesh's part of the mutual pairs (mutual_pairs.glsl
// follows): a cluster is empty at size 0, a pair costs CvdMergeCost. After pml_cvd.glsl.
layout(std430, binding = 1) readonly buffer Sizes { uint sizes[]; };

bool ClusterIsEmpty(uint c) { return sizes[c] == 0u; }
double PairMergeCost(uint c, uint d) { return CvdMergeCost(c, d); }
