#!/usr/bin/env python3
"""The energy ratio of two hierarchies count by count, from two `--levels-csv` files.

    python3 bench/levels_ratio.py RUN.csv REFERENCE.csv [--above 0.01] [--at 1000 200]

Both files are `mlclust ... --levels-csv` output (rows: clusters,energy). Counts present
in both with a positive reference energy are compared (a hierarchy with one merge per
level, HC or ML, has every count from the faces down to its lowest level; level 0's energy
is 0 and is skipped). Prints how many counts were compared, the lowest and the highest
ratio RUN / REFERENCE with their counts, every count where the ratio is more than
1 + ABOVE, and the ratio at each --at count. Where a file has several levels with one
count (it cannot for one merge per level), the last is taken.
"""
import argparse
import csv
import sys


def read_levels(path):
    with open(path) as f:
        return {int(row["clusters"]): float(row["energy"]) for row in csv.DictReader(f)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run")
    parser.add_argument("reference")
    parser.add_argument("--above", type=float, default=0.01,
                        help="list the counts whose ratio exceeds 1 + ABOVE (default 0.01)")
    parser.add_argument("--at", type=int, nargs="*", default=[],
                        help="counts whose ratio to print")
    args = parser.parse_args()
    run, reference = read_levels(args.run), read_levels(args.reference)
    ratios = {k: run[k] / reference[k] for k in run.keys() & reference.keys() if reference[k] > 0}
    if not ratios:
        sys.exit("levels_ratio: no count with a positive reference energy in both files")
    low = min(ratios, key=lambda k: ratios[k])
    high = max(ratios, key=lambda k: ratios[k])
    print(f"counts compared: {len(ratios)} (run {len(run)} levels, reference {len(reference)})")
    print(f"lowest ratio {ratios[low]:.4f} at {low} clusters, "
          f"highest {ratios[high]:.4f} at {high} clusters")
    over = sorted((k for k in ratios if ratios[k] > 1 + args.above), reverse=True)
    print(f"above {1 + args.above:g}: " +
          (", ".join(f"{k} ({ratios[k]:.4f})" for k in over) if over else "none"))
    for k in args.at:
        print(f"at {k}: " + (f"{ratios[k]:.4f}" if k in ratios else "not in both"))


if __name__ == "__main__":
    main()
