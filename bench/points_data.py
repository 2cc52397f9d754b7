#!/usr/bin/python3
"""Writes the synthetic point sets of the issue-5 benchmarks as float32 .npy files.

Gaussian blobs: `blobs` centres uniform in [-range, range]^d, every point drawn from one
centre (uniformly at random, or exactly `per_blob` points each) with standard deviation
`sigma` per coordinate. Reproducible from --seed (numpy's PCG64).

  bench/points_data.py --m 1000000 --d 3 --blobs 1000 --seed 1 --out data/bench/p.npy
  bench/points_data.py --per-blob 500 --d 3 --blobs 200 --seed 4 --out /tmp/k200.npy
  bench/points_data.py --from-off data/bench/armadillo.off --out /tmp/armadillo.npy

--from-off writes the vertices of an OFF mesh instead: a real 3-D point cloud (a scanned
surface: dense, thin, no blobs).
"""
import argparse

import numpy as np


def blobs(m, d, k, sigma, half_range, seed, per_blob=0):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-half_range, half_range, size=(k, d))
    if per_blob:
        which = np.repeat(np.arange(k), per_blob)
    else:
        which = rng.integers(0, k, size=m)
    points = centres[which] + rng.normal(0.0, sigma, size=(len(which), d))
    return points.astype(np.float32), which


def off_vertices(path):
    """The vertex positions of an OFF file (header OFF, counts line, vertices)."""
    with open(path) as f:
        words = [line.split("#")[0].split() for line in f]
    words = [w for w in words if w]
    first = words[0]
    if first[0] != "OFF":
        raise SystemExit(f"{path}: not an OFF file")
    counts = first[1:] if len(first) > 1 else words[1]
    start = 1 if len(first) > 1 else 2
    vertices = int(counts[0])
    return np.array([[float(v) for v in w[:3]] for w in words[start:start + vertices]],
                    dtype=np.float32)


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--m", type=int, default=100000, help="points (ignored with --per-blob)")
    parser.add_argument("--d", type=int, default=3)
    parser.add_argument("--blobs", type=int, default=100)
    parser.add_argument("--per-blob", type=int, default=0)
    parser.add_argument("--sigma", type=float, default=1.0)
    parser.add_argument("--range", type=float, default=25.0, help="centres in [-range, range]^d")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--from-off", help="write this OFF mesh's vertices instead of blobs")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    if args.from_off:
        np.save(args.out, off_vertices(args.from_off))
        return
    if args.m < 1 or args.d < 1 or args.blobs < 1 or args.per_blob < 0:
        parser.error("m, d and blobs must be >= 1, per-blob >= 0")
    points, _ = blobs(args.m, args.d, args.blobs, args.sigma, args.range, args.seed,
                      args.per_blob)
    np.save(args.out, points)


if __name__ == "__main__":
    main()
