#!/usr/bin/env bash
# Figs. 4.21-4.25 (section 4.4): sphere-fit energy against clusters for a cube with a
# spherical cap (7 shapes), 11 spherical zones and a height field of 12 spherical patches of
# different radii (where HC's early merges go wrong, Fig. 4.25): ML and HC over every level,
# EMLO from
# RUNS random seeds at a few K, and the elbows (core/hierarchy/elbow.h) of each curve.
#   bash bench/experiments/fig4_21_sphere_fit.sh [RUNS]
# Needs build/bench/{ml_bench,mesh_bench,plot_levels,ml_labels}. Writes into
# bench/results/experiments/: fig4_2x_MODEL_{ml,hc}.csv (every level), fig4_2x_MODEL_emlo.csv,
# fig4_2x_MODEL_{ml,hc}_elbows.png, fig4_2x_MODEL.png (all three together) and
# fig4_2x_MODEL_{ml,hc}_K.png (the clusterings at the true count K).
set -euo pipefail
cd "$(dirname "$0")/../.."
RUNS=${1:-20}
OUT=bench/results/experiments
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
for spec in "cube_sphere 4_22 7,8,10,15,20,30 7 20 30" "beads11 4_24 11,12,15,20,30 11 20 30" \
            "patches12 4_25 12,13,15,20,30 12 60 -60"; do
  set -- $spec
  model=$1 fig=$2 ks=$3 true_k=$4 elev=$5 azim=$6
  /usr/bin/python3 bench/experiments/sphere_models.py "$model" "$TMP/$model.off"
  echo "$model: the true shapes' energy: $(build/bench/mesh_bench "$TMP/$model.off" \
    --energy sphere --truth "$TMP/$model.truth")"
  # The pictures (Figs. 4.21, 4.23, 4.25): ML's clustering at the true count, and HC's.
  for algo in ml hc; do
    build/bench/ml_labels "$TMP/$model.off" --energy sphere --algo $algo --at "$true_k" \
      --out "$TMP/${model}_$algo" > /dev/null
    /usr/bin/python3 bench/render_ply.py "$TMP/${model}_${algo}_$true_k.ply" \
      "$OUT/fig${fig}_${model}_${algo}_$true_k.png" --elev "$elev" --azim "$azim" \
      --title "$model, ${algo^^} at $true_k clusters, sphere energy" > /dev/null
  done
  for algo in ml hc; do
    build/bench/ml_bench "$TMP/$model.off" --algo $algo --energy sphere --repeats 1 \
      --curve "$TMP/${model}_$algo.csv" --at 1 > /dev/null 2>&1
    # Keep the levels with at most 200 clusters (the figure's range).
    awk -F, 'NR == 1 || $1 <= 200' "$TMP/${model}_$algo.csv" > "$OUT/fig${fig}_${model}_$algo.csv"
    echo "$model $algo: $(build/bench/plot_levels "$TMP/${model}_$algo.csv" \
      "$OUT/fig${fig}_${model}_${algo}_elbows.png" "$model, $algo, sphere energy")"
  done
  build/bench/mesh_bench --header > "$OUT/fig${fig}_${model}_emlo.csv"
  for k in ${ks//,/ }; do
    build/bench/mesh_bench "$TMP/$model.off" --k "$k" --energy sphere --init random --seed 1 \
      --runs "$RUNS" --repeats 1 >> "$OUT/fig${fig}_${model}_emlo.csv"
  done
  /usr/bin/python3 - "$OUT/fig${fig}_${model}" "$model" <<'PY'
import csv, sys, statistics
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
base, model = sys.argv[1], sys.argv[2]
fig, ax = plt.subplots(figsize=(7, 4.5))
for algo, style in (("ml", "-"), ("hc", "--")):
    rows = [(int(r["clusters"]), float(r["energy"])) for r in csv.DictReader(open(f"{base}_{algo}.csv"))]
    rows = [r for r in rows if r[0] <= 40]
    ax.plot([r[0] for r in rows], [r[1] for r in rows], style, label=algo.upper())
emlo = {}
for r in csv.DictReader(open(f"{base}_emlo.csv")):
    emlo.setdefault(int(r["k"]), []).append(float(r["final_energy"]))
ks = sorted(emlo)
ax.errorbar(ks, [statistics.mean(emlo[k]) for k in ks],
            yerr=[[statistics.mean(emlo[k]) - min(emlo[k]) for k in ks],
                  [max(emlo[k]) - statistics.mean(emlo[k]) for k in ks]],
            fmt="o", capsize=4, label=f"EMLO, {len(emlo[ks[0]])} random seeds (min/mean/max)")
ax.set_xlabel("clusters")
ax.set_ylabel("sphere-fit energy (eq. 3.46)")
ax.set_yscale("symlog", linthresh=0.1)
ax.set_title(f"{model}: sphere fit, ML / HC / EMLO")
ax.legend()
fig.tight_layout()
fig.savefig(f"{base}.png", dpi=80)
for k in ks:
    print(f"  EMLO K={k}: min {min(emlo[k]):.4g} mean {statistics.mean(emlo[k]):.4g} max {max(emlo[k]):.4g}")
PY
done
