// PML on the GPU (pml_levels.h): the mesh's part of the collapse of the level's pairs
// (pair_merge.glsl): the kept cluster's sums become keep + gone in the CPU's order
// (CvdSums::operator+=), the gone cluster's are zeroed and it maps to the kept one
// (remap) for the relabelling passes; the energies are CvdEnergy. After pml_cvd.glsl,
// before pair_merge.glsl.
layout(std430, binding = 1) buffer Sizes { uint sizes[]; };
layout(std430, binding = 3) buffer Remap { uint remap[]; };

uint ClusterSize(uint c) { return sizes[c]; }

double ClusterEnergy(uint c) { return CvdEnergy(c); }

void MergeInto(uint keep, uint gone, uint size) {
  AddCvdSums(keep, gone);
  sizes[keep] = size;
  sizes[gone] = 0u;
  remap[gone] = keep;
}
