#!/usr/bin/env python3
"""Energy of a hierarchy against a reference one, level by level (points_bench --curve CSVs).

    compare_curves.py REFERENCE.csv OTHER.csv [--max-clusters 2000] [--at 1000,100,10]

For every cluster count both curves have, up to --max-clusters, the ratio OTHER / REFERENCE
of the level's energy (the last level with that count where a curve has several); prints
the mean and largest ratio, less one, in percent, and the ratio at the --at counts. Standard
library only."""
import argparse
import csv


def read(path):
    energies = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            energies[int(row["clusters"])] = float(row["energy"])
    return energies


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("reference")
    parser.add_argument("other")
    parser.add_argument("--max-clusters", type=int, default=2000)
    parser.add_argument("--at", default="1000,100,10")
    args = parser.parse_args()
    ref, other = read(args.reference), read(args.other)
    common = [k for k in ref if k in other and k <= args.max_clusters and ref[k] > 0]
    if not common:
        raise SystemExit("no common levels")
    ratios = [other[k] / ref[k] for k in common]
    at = []
    for k in (int(x) for x in args.at.split(",")):
        at.append(f"k={k}: {100 * (other[k] / ref[k] - 1):+.2f}%" if k in common else f"k={k}: -")
    print(f"{args.other}: {len(common)} levels, mean {100 * (sum(ratios) / len(ratios) - 1):+.2f}%, "
          f"max {100 * (max(ratios) - 1):+.2f}%, " + ", ".join(at))


if __name__ == "__main__":
    main()
