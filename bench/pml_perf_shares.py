#!/usr/bin/python3
"""Shares of a multilevel run's CPU samples: inside TBB's parallel bodies or sequential.

Reads `perf script` output of a `perf record --call-graph dwarf` of bench/pml_cpu_bench
(one thread, so that every sample is counted once) and counts the samples under
RunMultilevel (mesh loading excluded): a sample is parallel when a frame of its stack is a
TBB parallel_for / parallel_sort body (start_for, quick_sort), sequential otherwise. The
sequential samples are broken down by the innermost mlclust frame. Prints the shares and
Amdahl's bound, 1 / ((1 - p) + p / n), for n = 2, 4, 8, 16 cores.

  perf record -F 2999 --call-graph dwarf,16384 -o run.data \\
      build/bench/pml_cpu_bench MESH --algo pml --pml-until 2000 --threads 1 ...
  perf script -i run.data | bench/pml_perf_shares.py
"""
import collections
import re
import sys

PARALLEL = re.compile(r"tbb::detail::d1::(start_for|quick_sort|start_reduce)")


def samples(lines):
    stack = []
    for line in lines:
        if not line.strip():
            if stack:
                yield stack
            stack = []
        elif line[0] in " \t":
            parts = line.strip().split(None, 1)
            frame = parts[1] if len(parts) > 1 else ""
            frame = frame.rsplit(" (", 1)[0]  # the DSO
            stack.append(frame.replace("(anonymous namespace)", "anon"))
        else:
            if stack:
                yield stack
            stack = []
    if stack:
        yield stack


def main():
    total = parallel = 0
    sequential = collections.Counter()
    for stack in samples(sys.stdin):
        if not any("RunMultilevel" in frame for frame in stack):
            continue
        total += 1
        if any(PARALLEL.search(frame) for frame in stack):
            parallel += 1
            continue
        where = "other"
        for frame in stack:  # innermost first
            if "mlclust::" in frame:
                where = re.sub(r"\+0x[0-9a-f]+$", "", frame)
                where = re.sub(r"\(.*", "", where)
                while re.search(r"<[^<>]*>", where):
                    where = re.sub(r"<[^<>]*>", "", where)
                where = where[:110]
                break
        sequential[where] += 1
    if total == 0:
        print("no samples under RunMultilevel")
        return 1
    p = parallel / total
    print(f"samples under RunMultilevel: {total}")
    print(f"parallel (TBB bodies): {parallel} = {100 * p:.1f}%")
    print(f"sequential: {total - parallel} = {100 * (1 - p):.1f}%")
    for where, count in sequential.most_common(12):
        print(f"  {100 * count / total:5.1f}%  {where}")
    for n in (2, 4, 8, 16):
        print(f"Amdahl bound on {n} cores: {1 / ((1 - p) + p / n):.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
