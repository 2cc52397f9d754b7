#!/usr/bin/env python3
"""The peer a data scientist would write for brute-force k-means on a GPU (issue 10,
"Speed"): Lloyd with the assignment as chunked torch.cdist + argmin, the update as
index_add_ on the GPU. Same data as gpu_stages_bench (M points around 1000 Gaussian blobs;
not the same random stream, so energies are comparable in size only) and the same
centres rule (M random points as initial centres here: seeding is not timed). Prints one
CSV row: stage,points,dims,k,iterations,seconds,seconds_per_iteration,inertia,device.

Needs PyTorch with CUDA (GPU nodes have it; Debian's archive does not, so this machine
cannot run it).
  python3 bench/peers/torch_kmeans.py --points 10000000 --k 10000 --iterations 3
"""
import argparse
import time

import torch


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--k", type=int, default=1000)
    parser.add_argument("--dims", type=int, default=3)
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=65536)
    args = parser.parse_args()
    device = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    generator = torch.Generator(device="cpu").manual_seed(1)
    blobs = torch.rand(1000, args.dims, generator=generator) * 200 - 100
    which = torch.arange(args.points) % 1000
    points = (blobs[which] + torch.randn(args.points, args.dims, generator=generator)).to(device)
    centres = points[torch.randperm(args.points, generator=generator)[: args.k].to(device)].clone()
    labels = torch.empty(args.points, dtype=torch.long, device=device)
    if device.type == "cuda":
        torch.cuda.synchronize()
    start = time.perf_counter()
    for _ in range(args.iterations):
        for begin in range(0, args.points, args.chunk):
            chunk = points[begin:begin + args.chunk]
            labels[begin:begin + args.chunk] = torch.cdist(chunk, centres).argmin(dim=1)
        sums = torch.zeros_like(centres).index_add_(0, labels, points)
        counts = torch.zeros(args.k, device=device).index_add_(
            0, labels, torch.ones(args.points, device=device))
        keep = counts > 0
        centres[keep] = sums[keep] / counts[keep].unsqueeze(1)
    if device.type == "cuda":
        torch.cuda.synchronize()
    seconds = time.perf_counter() - start
    inertia = float(((points - centres[labels]) ** 2).sum(dtype=torch.float64))
    print(f"torch-kmeans,{args.points},{args.dims},{args.k},{args.iterations},{seconds:.4f},"
          f"{seconds / args.iterations:.6f},{inertia:.9g},{torch.cuda.get_device_name() if device.type == 'cuda' else 'cpu'}")


if __name__ == "__main__":
    main()
