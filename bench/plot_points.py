#!/usr/bin/python3
"""Plots the issue-5 point benchmarks from bench/results/ (run_points_benchmarks.sh).

  bench/plot_points.py [RESULTS_DIR]

Writes, for the CSVs present: points_true_k.png (Fig. 6.15), points_fig6_11.png (time vs k),
points_fig6_12.png (time vs m), points_fig6_13.png (time per ML step vs d).
"""
import collections
import csv
import json
import os
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def truek(results):
    path = os.path.join(results, "points_true_k_ml.csv")
    if not os.path.exists(path):
        return
    by_k = collections.defaultdict(list)
    for r in rows(path):
        by_k[int(r["K"])].append(int(r["best_k"]))
    ks = sorted(by_k)
    means = [statistics.mean(by_k[k]) for k in ks]
    sds = [statistics.pstdev(by_k[k]) for k in ks]
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.fill_between(ks, [0.95 * k for k in ks], [1.05 * k for k in ks], color="0.9",
                    label="within 5% of K")
    ax.plot(ks, ks, color="0.5", lw=1, label="K")
    ax.errorbar(ks, means, yerr=sds, fmt="o-", capsize=3, label="ML + BIC (mean, sd)")
    ax.scatter([k for k in ks for _ in by_k[k]], [v for k in ks for v in by_k[k]], s=6,
               color="C0", alpha=0.4, label="ML + BIC (each set)")
    ward = os.path.join(results, "points_true_k_ward.jsonl")
    if os.path.exists(ward):
        points = collections.defaultdict(list)
        with open(ward) as f:
            for line in f:
                run = json.loads(line)
                k = int(os.path.basename(run["file"]).split("_K")[1].split("_")[0])
                points[k].append(run["best_k"])
        wk = sorted(points)
        ax.errorbar(wk, [statistics.mean(points[k]) for k in wk],
                    yerr=[statistics.pstdev(points[k]) for k in wk], fmt="s", color="C3",
                    capsize=3, label="Ward + BIC (fastcluster)")
    ax.set_xlabel("true number of clusters K (500 points each, sigma 1, [-25, 25]^3)")
    ax.set_ylabel("K chosen by the BIC")
    ax.set_title("True number of clusters (Fig. 6.15), 10 data sets per K")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(results, "points_true_k.png"), dpi=120)


def lines(results, name, x, out, title, xlabel, ylabel, per_step=False, logx=False):
    path = os.path.join(results, name)
    if not os.path.exists(path):
        return
    by_algo = collections.defaultdict(list)
    for r in rows(path):
        seconds = float(r["seconds"])
        if per_step:
            seconds /= max(1, int(r["steps"]))
        by_algo[r["algo"]].append((int(r[x]), seconds))
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for algo, pts in sorted(by_algo.items()):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=algo)
    if logx:
        ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(results, out), dpi=120)


def main():
    results = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "results")
    truek(results)
    lines(results, "points_time_vs_k.csv", "k", "points_fig6_11.png",
          "Time vs k, m = 1M 3-D points (Fig. 6.11)", "k", "seconds, end to end")
    lines(results, "points_time_vs_m.csv", "m", "points_fig6_12.png",
          "Time vs m, k = 1000 (Fig. 6.12)", "m (points)", "seconds, end to end", logx=True)
    lines(results, "points_time_vs_d.csv", "d", "points_fig6_13.png",
          "Time per hierarchy step vs d, m = 20,000 (Fig. 6.13)", "d",
          "seconds per level", per_step=True, logx=True)


if __name__ == "__main__":
    main()
