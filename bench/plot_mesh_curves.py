#!/usr/bin/python3
"""Plots from bench/run_mesh_benchmarks.sh's results (PNG, dpi 80, into RESULTS):

    /usr/bin/python3 bench/plot_mesh_curves.py bench/results

curves_MESH.png  energy vs number of clusters, log-log: left CVD (ML, HC, PML, PML->2000
                 then ML), right planar L2,1 (ML, HC, PML) with VSA points at k = 50, 200,
                 1000 (CGAL random and hierarchical seeding, ours hierarchical).
scaling.png      time of the whole hierarchy vs faces (ML, HC, PML, PML->ML; CVD), with
                 CGAL VSA at k = 1000 (one partition, faster seeding) for reference.
Curves come from RESULTS/curves/MESH_ENERGY_ALGO.csv (clusters,energy), times from
cvd_hierarchies.csv and vsa_vs_cgal_cgal_vsa.csv (best repeat).
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

RESULTS = sys.argv[1] if len(sys.argv) > 1 else "bench/results"
MESHES = ["elephant", "fandisk", "armadillo", "bunny00", "armadillo_1m"]
STYLE = {"ml": ("ML", "C0", "-"), "hc": ("HC", "C3", "--"), "pml": ("PML", "C2", (0, (1, 1.5))),
         "pml2000ml": ("PML→2000, ML", "C1", "-.")}


def read(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def curve(mesh, energy, algo):
    rows = read(os.path.join(RESULTS, "curves", "%s_%s_%s.csv" % (mesh, energy, algo)))
    pts = [(int(r["clusters"]), float(r["energy"])) for r in rows]
    return [p for p in pts if p[1] > 0]


def best_rows(rows, keys, time_col):
    out = {}
    for r in rows:
        r["mesh"] = r["mesh"].removesuffix(".off")
        key = tuple(r[k] for k in keys)
        if key not in out or float(r[time_col]) < float(out[key][time_col]):
            out[key] = r
    return out


def plot_curves():
    cgal = best_rows(read(os.path.join(RESULTS, "vsa_vs_cgal_cgal_vsa.csv")),
                     ["mesh", "k", "seeding"], "total_seconds")
    ours = best_rows(read(os.path.join(RESULTS, "vsa_vs_cgal_vsa_bench.csv")),
                     ["mesh", "k", "seeding"], "seconds")
    for mesh in MESHES:
        panels = [("cvd", "CVD")]
        if curve(mesh, "planar", "ml"):
            panels.append(("planar", "planar L2,1"))
        if not curve(mesh, "cvd", "ml"):
            continue
        fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.5), squeeze=False)
        for ax, (energy, title) in zip(axes[0], panels):
            for algo, (label, colour, dash) in STYLE.items():
                pts = curve(mesh, energy, algo)
                if pts:
                    ax.plot([p[0] for p in pts], [p[1] for p in pts], color=colour,
                            linestyle=dash, label=label, lw=2.0 if algo == "pml" else 1.3)
            if energy == "planar":
                for (src, seeding, marker, colour, label) in [
                        (cgal, "random", "x", "k", "CGAL VSA, random"),
                        (cgal, "hierarchical", "+", "k", "CGAL VSA, hierarchical"),
                        (ours, "hierarchical", "o", "C4", "our VSA, hierarchical")]:
                    ks, es = [], []
                    for k in ["50", "200", "1000"]:
                        r = src.get((mesh, k, seeding))
                        if r:
                            ks.append(int(k))
                            es.append(float(r.get("energy_l21") or r.get("energy")))
                    if ks:
                        ax.plot(ks, es, marker, color=colour, ms=8, mfc="none", label=label)
            ax.set_xscale("log")
            ax.set_yscale("log")
            # Flat regions merge at rounding-noise energies (1e-15): show 8 decades only.
            top = max(p[1] for p in curve(mesh, energy, "ml"))
            ax.set_ylim(bottom=max(ax.get_ylim()[0], top * 1e-8))
            ax.set_xlabel("clusters k")
            ax.set_ylabel("energy")
            ax.set_title("%s: %s" % (mesh, title))
            ax.grid(True, which="major", alpha=0.3)
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(RESULTS, "curves_%s.png" % mesh), dpi=80)
        plt.close(fig)


def plot_scaling():
    rows = read(os.path.join(RESULTS, "cvd_hierarchies.csv"))
    if not rows:
        return
    # One time per run (ml_bench repeats it on each k row; PML's k is the level it reached).
    b = best_rows(rows, ["mesh", "algo", "pml_until"], "seconds")
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for (algo, until), name in [(("ml", "0"), "ml"), (("hc", "0"), "hc"), (("pml", "0"), "pml"),
                                (("pml", "2000"), "pml2000ml")]:
        pts = sorted((int(r["faces"]), float(r["seconds"])) for key, r in b.items()
                     if key[1] == algo and key[2] == until)
        label, colour, dash = STYLE[name]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], linestyle=dash, marker="o",
                color=colour, label=label + " (all levels)")
    cgal = best_rows(read(os.path.join(RESULTS, "vsa_vs_cgal_cgal_vsa.csv")),
                     ["mesh", "k", "seeding"], "total_seconds")
    pts = {}
    for (mesh, k, _), r in cgal.items():
        if k == "1000":
            t = float(r["total_seconds"])
            pts[int(r["faces"])] = min(t, pts.get(int(r["faces"]), t))
    if pts:
        xs = sorted(pts)
        ax.plot(xs, [pts[x] for x in xs], "x", color="k", ms=8,
                label="CGAL VSA, one partition k=1000")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("faces")
    ax.set_ylabel("seconds (best of repeats)")
    ax.set_title("the whole hierarchy, CVD (2 cores, shared)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(RESULTS, "scaling.png"), dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    plot_curves()
    plot_scaling()
