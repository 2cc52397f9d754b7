#!/usr/bin/env bash
# Figs. 6.14 and 6.16: the BIC of every ML level. Fig. 6.14: 10k 2-D points of 10
# Gaussians (Fig. 6.8's setting); Fig. 6.16: 250 Gaussians in 3-D, 500 points each
# (Fig. 6.15's setting). Writes the curves and a PNG beside them, and prints where each
# curve is highest and how many local maxima it has below 100 clusters (the text: X-means
# is trapped by such maxima, the ML curve has none).
#   bench/experiments/fig6_14_16_bic_curves.sh BUILD_DIR [OUT_DIR]
set -euo pipefail
build=${1:?build dir}
out=${2:-bench/results/experiments}
mkdir -p "$out"
/usr/bin/python3 bench/points_data.py --per-blob 1000 --d 2 --blobs 10 --range 10 --seed 614 \
  --out "$out/fig6_14_points.npy"
/usr/bin/python3 bench/points_data.py --per-blob 500 --d 3 --blobs 250 --range 25 --seed 616 \
  --out "$out/fig6_16_points.npy"
"$build/bench/bic_direction" "$out/fig6_14_points.npy" --curve "$out/fig6_14_bic.csv"
"$build/bench/bic_direction" "$out/fig6_16_points.npy" --curve "$out/fig6_16_bic.csv"
rm -f "$out/fig6_14_points.npy" "$out/fig6_16_points.npy"
/usr/bin/python3 - "$out" <<'PY'
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
out = sys.argv[1]
for fig, truth, xmax in (("fig6_14", 10, 40), ("fig6_16", 250, 400)):
    rows = [(int(r["clusters"]), float(r["bic"])) for r in csv.DictReader(open(f"{out}/{fig}_bic.csv"))]
    by_k = {}
    for k, b in rows:  # the last level with each count
        by_k[k] = b
    ks = sorted(by_k)
    best = max(ks, key=lambda k: by_k[k])
    below = [k for k in ks if k < 100]
    maxima = [k for i, k in enumerate(below[1:-1], 1)
              if by_k[k] > by_k[below[i - 1]] and by_k[k] > by_k[below[i + 1]]]
    print(f"{fig}: {len(ks)} levels, true {truth}, BIC highest at {best}; "
          f"local maxima below 100 clusters: {len(maxima)} {maxima[:10]}")
    plt.figure(figsize=(6, 3.5))
    shown = [k for k in ks if k <= xmax]
    plt.plot(shown, [by_k[k] for k in shown], lw=1)
    plt.axvline(truth, color="grey", ls="--", lw=0.8)
    plt.xlabel("clusters"); plt.ylabel("BIC"); plt.title(f"{fig}: BIC of every ML level")
    plt.tight_layout(); plt.savefig(f"{out}/{fig}_bic.png", dpi=110)
PY
