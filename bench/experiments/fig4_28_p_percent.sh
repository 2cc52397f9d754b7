#!/usr/bin/env bash
# Fig. 4.28 and Tables 4.4/4.5 (section 4.5): the CVD energy curves of ML, HC (the text's
# HFC) and p% ML (Alg. 4.2: the first p% merged in sequential sweeps, then ML) for p = 50,
# 75, 95 on bunny00, and the time of each whole hierarchy (one thread, repeats 1); Table 4.4
# also on the 11 spherical zones of fig4_21_sphere_fit.sh (14,880 faces; the text's
# 11Spheres has 28k).
#   bash bench/experiments/fig4_28_p_percent.sh
# Writes bench/results/experiments/fig4_28_bunny00.{csv,png} (algo,clusters,energy for the
# levels with 500..20000 clusters: every 5th up to 5000, every 50th above) and fig4_28_times.csv (mesh,faces,algo,p,seconds,levels).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=bench/results/experiments
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
/usr/bin/python3 bench/experiments/sphere_models.py beads11 "$TMP/beads11.off"
echo "mesh,faces,algo,p,seconds,levels" > "$OUT/fig4_28_times.csv"
echo "algo,clusters,energy" > "$OUT/fig4_28_bunny00.csv"
for mesh in data/bench/bunny00.off "$TMP/beads11.off"; do
  for spec in "ml 0" "hc 0" "ml 50" "ml 75" "ml 95"; do
    set -- $spec
    algo=$1 p=$2
    name=$algo; [ "$p" = 0 ] || name="p$p"
    row=$(build/bench/ml_bench "$mesh" --algo $algo --energy cvd --p-percent "$p" --threads 1 \
      --repeats 1 --at 1 --curve "$TMP/curve.csv" 2>/dev/null)
    # ml_bench: mesh,faces,algo,energy,optimizer,p_percent,pml_until,threads,seconds,levels,...
    echo "$row" | awk -F, -v OFS=, -v n="$name" -v p="$p" '{print $1, $2, n, p, $9, $10}' \
      >> "$OUT/fig4_28_times.csv"
    if [ "$mesh" = data/bench/bunny00.off ]; then
      awk -F, -v OFS=, -v n="$name" 'NR > 1 && $1 >= 500 && $1 <= 20000 && ($1 % 5 == 0 && $1 <= 5000 || $1 % 50 == 0) {print n, $1, $2}' \
        "$TMP/curve.csv" >> "$OUT/fig4_28_bunny00.csv"
    fi
  done
done
/usr/bin/python3 - "$OUT/fig4_28_bunny00" <<'PY'
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
base = sys.argv[1]
curves = {}
for r in csv.DictReader(open(base + ".csv")):
    curves.setdefault(r["algo"], []).append((int(r["clusters"]), float(r["energy"])))
fig, ax = plt.subplots(figsize=(7, 4.5))
for name, label in (("ml", "ML"), ("hc", "HC (HFC)"), ("p50", "p = 50 %"), ("p75", "p = 75 %"),
                    ("p95", "p = 95 %")):
    rows = sorted(curves[name])
    ax.plot([r[0] for r in rows], [r[1] for r in rows], label=label, linewidth=1)
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel("clusters")
ax.set_ylabel("CVD energy")
ax.set_title("bunny00 (75,408 faces): CVD energy, ML / HC / p% ML (Alg. 4.2)")
ax.legend()
fig.tight_layout()
fig.savefig(base + ".png", dpi=80)
PY
cat "$OUT/fig4_28_times.csv"
