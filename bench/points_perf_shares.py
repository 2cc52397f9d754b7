#!/usr/bin/python3
"""Shares of a point ML run's CPU samples: inside TBB's parallel bodies or sequential.

bench/pml_perf_shares.py for bench/points_bench: reads `perf script` output of a
`perf record --call-graph dwarf` of points_bench (one thread, so that every sample is
counted once), counts the samples under RunPointMultilevel (the data's generation
excluded): a sample is parallel when a frame of its stack is a TBB parallel_for /
parallel_sort / parallel_reduce body, sequential otherwise. Both are broken down by the
innermost mlclust frame (the parallel ones by the body's caller as well). Prints the
shares and Amdahl's bound, 1 / ((1 - p) + p / n), and the time bound
work x ((1 - p) + p / n) for n = 2, 4, 8, 16 cores when --work (one-thread CPU seconds)
is given.

  perf record -F 499 --call-graph dwarf,16384 -o run.data \\
      build/bench/points_bench --algo ml --m 300000 --blobs 1000 --threads 1
  perf script -i run.data | bench/points_perf_shares.py [--work SECONDS]
"""
import argparse
import collections
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pml_perf_shares import PARALLEL, samples  # noqa: E402


def innermost(stack, skip_parallel=False):
    for frame in stack:  # innermost first
        if skip_parallel and PARALLEL.search(frame):
            continue
        if "mlclust::" in frame:
            where = re.sub(r"\+0x[0-9a-f]+$", "", frame)
            where = re.sub(r"\(.*", "", where)
            while re.search(r"<[^<>]*>", where):
                where = re.sub(r"<[^<>]*>", "", where)
            return where[:110]
    return "other"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--work", type=float, default=0.0,
                        help="one-thread CPU seconds of the run, for the time bound")
    parser.add_argument("--under", default="RunPointMultilevel",
                        help="count only samples with a frame containing this")
    args = parser.parse_args()
    total = parallel = 0
    sequential = collections.Counter()
    bodies = collections.Counter()
    for stack in samples(sys.stdin):
        if not any(args.under in frame for frame in stack):
            continue
        total += 1
        at = [k for k, frame in enumerate(stack) if PARALLEL.search(frame)]
        if at:
            parallel += 1
            # The body's caller: the first mlclust frame outside the TBB frames.
            bodies[innermost(stack[at[-1] + 1:])] += 1
            continue
        sequential[innermost(stack)] += 1
    if total == 0:
        print(f"no samples under {args.under}")
        return 1
    p = parallel / total
    print(f"samples under {args.under}: {total}")
    print(f"parallel (TBB bodies): {parallel} = {100 * p:.1f}%")
    for where, count in bodies.most_common(8):
        print(f"  {100 * count / total:5.1f}%  {where}")
    print(f"sequential: {total - parallel} = {100 * (1 - p):.1f}%")
    for where, count in sequential.most_common(16):
        print(f"  {100 * count / total:5.1f}%  {where}")
    for n in (2, 4, 8, 16):
        factor = (1 - p) + p / n
        line = f"Amdahl bound on {n} cores: {1 / factor:.2f}x"
        if args.work > 0:
            line += f", {args.work * factor:.2f} s of {args.work:.2f} s"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
