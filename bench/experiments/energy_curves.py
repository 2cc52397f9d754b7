#!/usr/bin/python3
"""Energy against number of clusters: hierarchies (every level) beside single-K algorithms
run many times from random seeds, through the `mlclust` CLI, as the dissertation's
Figs. 4.15/4.16/4.20 (fandisk: ML, HFC and 50 random EMLO runs, CVD and planar),
5.15 (bunny: BB against EMLO, 100 random runs each) and 6.10 (points: ML against k-means,
100 random runs) draw them.

  energy_curves.py --mlclust BUILD/client/mlclust --input data/fandisk.off --energy cvd \
      --curves ml,hc --spread emlo --ks 1000,500,200,100,50,20 --runs 50 \
      --out bench/results/experiments/fig4_16_fandisk_cvd
  energy_curves.py --mlclust ... --input blobs.npy --points --curves ml --grids 16,23 \
      --spread kmeans --ks 102,80,57,50,40 --runs 100 --out .../fig6_10_blobs

Writes OUT.csv (rows: algo,clusters,seed,energy; seed is empty for hierarchy levels, and
for hierarchies only levels with at most 4 x max(ks) clusters are kept), OUT.md (a table
per K: each hierarchy's energy at K, the spread's min / mean / max, and how they compare)
and OUT.png (matplotlib: the curves, the spread as min-max bars with the mean).

Single-K runs: --init random --seed S for S = 1..runs; the energy is that of the last level
the CLI reports (for emlo, bb and kmeans: the result at K). Runs one process at a time.
"""
import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile


def run_levels(args, algo, extra):
    """Runs the CLI and returns its levels as (clusters, energy) rows."""
    with tempfile.TemporaryDirectory() as tmp:
        levels = os.path.join(tmp, "levels.csv")
        kind = "points" if args.points else "mesh"
        command = [args.mlclust, kind, args.input, "--algo", algo, "--levels-csv", levels,
                   "--quiet"] + extra + args.extra.split()
        if not args.points:
            command += ["--energy", args.energy]
        result = subprocess.run(command, capture_output=True, text=True)
        if result.returncode != 0:
            sys.exit(f"{' '.join(command)} failed: {result.stderr.strip()}")
        with open(levels) as f:
            return [(int(r["clusters"]), float(r["energy"])) for r in csv.DictReader(f)]


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mlclust", required=True)
    parser.add_argument("--input", required=True)
    parser.add_argument("--points", action="store_true", help="a point set (mlclust points)")
    parser.add_argument("--energy", default="cvd")
    parser.add_argument("--curves", default="ml,hc", help="hierarchies: every level")
    parser.add_argument("--grids", default="", help="points: ML's --grid values (one curve each)")
    parser.add_argument("--spread", default="emlo", help="single-K algorithms, run --runs times")
    parser.add_argument("--ks", required=True)
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--extra", default="",
                        help="more CLI options for every run, e.g. '--guard off'")
    parser.add_argument("--title", default="")
    parser.add_argument("--out", required=True)
    parser.add_argument("--plot-only", action="store_true",
                        help="redraw OUT.png (and OUT.md) from OUT.csv without running")
    args = parser.parse_args()
    ks = [int(k) for k in args.ks.split(",")]
    keep = 4 * max(ks)
    if args.plot_only:
        curves, spread = read_csv(args.out + ".csv")
        ks = sorted({k for per_k in spread.values() for k in per_k}, reverse=True) or ks
        keep = 4 * max(ks)
        report(args, curves, spread, ks, keep)
        return

    curves = {}  # name -> [(clusters, energy)]
    for algo in [a for a in args.curves.split(",") if a]:
        grids = [g for g in args.grids.split(",") if g] if args.points else []
        for grid in grids or [None]:
            extra = ["--grid", grid] if grid else []
            name = f"{algo} (a={grid})" if grid else algo
            curves[name] = [(k, e) for k, e in run_levels(args, algo, extra) if k <= keep]
            print(f"{name}: {len(curves[name])} levels", file=sys.stderr)
    spread = {}  # algo -> {k: [energy per seed]}
    for algo in [a for a in args.spread.split(",") if a]:
        spread[algo] = {}
        for k in ks:
            energies = []
            for seed in range(1, args.runs + 1):
                levels = run_levels(args, algo,
                                    ["--clusters", str(k), "--init", "random", "--seed", str(seed)])
                energies.append(levels[-1][1])
            spread[algo][k] = energies
            print(f"{algo} K={k}: min {min(energies):.6g} mean {statistics.mean(energies):.6g} "
                  f"max {max(energies):.6g}", file=sys.stderr)

    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    write_csv(args.out + ".csv", curves, spread)
    report(args, curves, spread, ks, keep)


def read_csv(path):
    curves, spread = {}, {}
    with open(path) as f:
        for row in csv.DictReader(f):
            k, e = int(row["clusters"]), float(row["energy"])
            if row["seed"]:
                spread.setdefault(row["algo"], {}).setdefault(k, []).append(e)
            else:
                curves.setdefault(row["algo"], []).append((k, e))
    return curves, spread


def write_csv(path, curves, spread):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["algo", "clusters", "seed", "energy"])
        for name, rows in curves.items():
            for k, e in rows:
                w.writerow([name, k, "", repr(e)])
        for algo, per_k in spread.items():
            for k, energies in per_k.items():
                for seed, e in enumerate(energies, 1):
                    w.writerow([algo, k, seed, repr(e)])


def report(args, curves, spread, ks, keep):
    runs = max((len(v) for per_k in spread.values() for v in per_k.values()), default=0)

    def at(rows, k):
        """The energy of the first level with at most k clusters."""
        for clusters, e in rows:
            if clusters <= k:
                return clusters, e
        return None, float("nan")

    header = ["K"] + list(curves) + [f"{a} min / mean / max ({runs} runs)" for a in spread]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for k in ks:
        cells = [str(k)]
        for name, rows in curves.items():
            clusters, e = at(rows, k)
            cells.append(f"{e:.5g}" + ("" if clusters == k else f" (at {clusters})"))
        for algo, per_k in spread.items():
            v = per_k[k]
            cells.append(f"{min(v):.5g} / {statistics.mean(v):.5g} / {max(v):.5g}")
        lines.append("| " + " | ".join(cells) + " |")
    # Ratios against the first curve, or, with no curve, against the first spread's mean.
    base_name = next(iter(curves), None)
    first_spread = next(iter(spread), None)
    notes = []
    for k in ks:
        parts = []
        if base_name:
            base = at(curves[base_name], k)[1]
        else:
            base = statistics.mean(spread[first_spread][k])
        for name, rows in list(curves.items())[1:]:
            parts.append(f"{name}/{base_name} {at(rows, k)[1] / base:.3f}")
        for algo, per_k in spread.items():
            if not base_name and algo == first_spread:
                continue
            v = per_k[k]
            mean = statistics.mean(v)
            parts.append(f"{algo} mean/{base_name or first_spread + ' mean'} {mean / base:.3f}")
            if base_name:
                below = sum(e < base for e in v)
                parts.append(f"{below} of {len(v)} {algo} runs below {base_name}")
            else:
                first = spread[first_spread][k]
                parts.append(f"{algo} min {min(v) / base:.3f}, max {max(v) / base:.3f}; "
                             f"{sum(e < max(first) for e in v)} of {len(v)} {algo} runs below "
                             f"the worst {first_spread} run")
        notes.append(f"- K = {k}: " + "; ".join(parts))
    with open(args.out + ".md", "w") as f:
        f.write("\n".join(lines) + "\n\n" + "\n".join(notes) + "\n")
    print("\n".join(lines + [""] + notes))

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(8, 5))
    low_k = min(ks) / 1.5
    for name, rows in curves.items():
        shown = [(k, e) for k, e in rows if k >= low_k and e > 0]
        ax.plot([k for k, _ in shown], [e for _, e in shown], label=name, linewidth=1.5)
    for algo, per_k in spread.items():
        xs = list(per_k)
        means = [statistics.mean(per_k[k]) for k in xs]
        low = [m - min(per_k[k]) for m, k in zip(means, xs)]
        high = [max(per_k[k]) - m for m, k in zip(means, xs)]
        ax.errorbar(xs, means, yerr=[low, high], fmt="o", capsize=4,
                    label=f"{algo}: {runs} random runs (min-max, mean)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(low_k, keep)
    ax.set_xlabel("number of clusters (log scale)")
    ax.set_ylabel("energy (log scale)")
    ax.set_title(args.title or os.path.basename(args.out))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out + ".png", dpi=100)


if __name__ == "__main__":
    main()
