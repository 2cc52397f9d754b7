#!/usr/bin/python3
"""Markdown tables from bench/run_mesh_benchmarks.sh's CSVs (best repeat of each run).

    /usr/bin/python3 bench/plot_mesh_tables.py bench/results > bench/results/tables.md

Every CSV row is one run of one tool: rep,load1,proc_wall_s,proc_cpu_s, then the tool's own
columns. For each configuration the table keeps the repeat with the smallest time and
shows the load average it ran under; "*" marks a one-thread run whose process waited for
a core (wall-clock > 1.1 x CPU time).
"""
import csv
import os
import sys

RESULTS = sys.argv[1] if len(sys.argv) > 1 else "bench/results"
REQUESTED_K = [1000, 200, 50]
FACES_ORDER = ["elephant", "fandisk", "armadillo", "bunny00", "armadillo_1m"]


def read(name):
    path = os.path.join(RESULTS, name)
    if not os.path.exists(path):
        return []
    with open(path) as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        if "mesh" in r:
            r["mesh"] = r["mesh"].removesuffix(".off")
    return rows


def best(rows, keys, time_col):
    """One row per configuration (the values of `keys`): the repeat with the least time."""
    out = {}
    for r in rows:
        key = tuple(r[k] for k in keys)
        if key not in out or float(r[time_col]) < float(out[key][time_col]):
            out[key] = r
    return out


def waited(r):
    return float(r["proc_wall_s"]) > 1.1 * float(r["proc_cpu_s"]) + 0.02


def load(r, threads=1):
    """The load average; "*" for a one-thread run that waited for a core (for a run on
    two threads the wall/CPU ratio says nothing of waiting)."""
    return r["load1"] + ("*" if threads == 1 and waited(r) else "")


def s(x):
    x = float(x)
    return "%.3f s" % x if x < 100 else "%.1f s" % x


def e(x):
    return "%.5g" % float(x)


def table(header, rows):
    print("| " + " | ".join(header) + " |")
    print("|" + "|".join("---" if i == 0 else "---:" for i in range(len(header))) + "|")
    for row in rows:
        print("| " + " | ".join(str(c) for c in row) + " |")
    print()


def load_span(*row_lists):
    loads = [float(r["load1"]) for rows in row_lists for r in rows]
    return "%.2f–%.2f" % (min(loads), max(loads)) if loads else "n/a"


def mesh_key(m):
    return FACES_ORDER.index(m) if m in FACES_ORDER else 99


def section_a():
    ours = read("emlo_vs_cgal_mesh_bench.csv")
    cgal = read("emlo_vs_cgal_cgal_vsa.csv")
    if not ours:
        return
    print("### (a) EMLO (CVD) vs CGAL VSA, bunny00, k = 1000\n")
    print("load1 over the runs: %s\n" % load_span(ours, cgal))
    b_ours = best(ours, ["init"], "total_s")
    b_cgal = best(cgal, ["seeding"], "total_seconds")
    rows = []
    for init in ["lneigh", "random"]:
        r = b_ours[(init,)]
        rows.append(["mlclust EMLO, init " + init, s(r["init_s"]), s(r["opt_s"]), "**%s**" % s(r["total_s"]),
                     "CVD " + e(r["final_energy"]), load(r)])
    for seeding in ["random", "hierarchical"]:
        r = b_cgal[(seeding,)]
        rows.append(["CGAL VSA, seeding " + seeding, s(r["seed_seconds"]), s(r["iterate_seconds"]),
                     "**%s**" % s(r["total_seconds"]), "L2,1 " + e(r["energy_l21"]), load(r)])
    table(["run", "initial clusters / seeding", "EMLO / 30 Lloyd iterations", "total", "energy",
           "load1"], rows)
    fastest_cgal = min(float(r["total_seconds"]) for r in b_cgal.values())
    for init in ["lneigh", "random"]:
        print("- EMLO with %s initial clusters: %.1f× faster than CGAL's faster seeding." %
              (init, fastest_cgal / float(b_ours[(init,)]["total_s"])))
    print()


def section_b():
    ours = read("vsa_vs_cgal_vsa_bench.csv")
    cgal = read("vsa_vs_cgal_cgal_vsa.csv")
    if not ours:
        return
    print("### (b) our VSA vs CGAL VSA (L2,1 energy, 30 iterations)\n")
    print("load1 over the runs: %s\n" % load_span(ours, cgal))
    b_ours = best(ours, ["mesh", "k", "seeding"], "seconds")
    b_cgal = best(cgal, ["mesh", "k", "seeding"], "total_seconds")
    rows = []
    met_e = met_t = total = 0
    for key in sorted(b_ours, key=lambda k: (mesh_key(k[0]), k[2], int(k[1]))):
        o, c = b_ours[key], b_cgal.get(key)
        if c is None:
            continue
        te = float(o["energy"]) / float(c["energy_l21"])
        tt = float(o["seconds"]) / float(c["total_seconds"])
        total += 1
        met_e += te <= 1.05
        met_t += tt <= 1.0
        rows.append([key[0], key[1], key[2], s(o["seconds"]), s(c["total_seconds"]), "%.2f" % tt,
                     e(o["energy"]), e(c["energy_l21"]), "%.3f" % te,
                     ("E ok" if te <= 1.05 else "**E missed**") + ", " +
                     ("t ok" if tt <= 1.0 else "**t missed**"),
                     load(o) + " / " + load(c)])
    table(["mesh", "k", "seeding", "ours", "CGAL", "time ours/CGAL", "E ours", "E CGAL",
           "E ours/CGAL", "target", "load1 ours / CGAL"], rows)
    print("Energy within 5%% (or lower): %d of %d; not slower: %d of %d.\n" %
          (met_e, total, met_t, total))
    so = read("vsa_seeds_vs_cgal_vsa_bench.csv")
    sc = {r["rep"]: r for r in read("vsa_seeds_vs_cgal_cgal_vsa.csv")}
    if so and sc:
        print("Random seeding, fandisk, k = 200, seeds 1..%d (the rep column is the seed; "
              "CGAL's std::srand(seed), our own generator):\n" % len(so))
        rows = [[r["rep"], e(r["energy"]), e(sc[r["rep"]]["energy_l21"]),
                 "%.3f" % (float(r["energy"]) / float(sc[r["rep"]]["energy_l21"]))] for r in so]
        mo = sum(float(r["energy"]) for r in so) / len(so)
        mc = sum(float(r["energy_l21"]) for r in sc.values()) / len(sc)
        rows.append(["mean", e(mo), e(mc), "%.3f" % (mo / mc)])
        table(["seed", "E ours", "E CGAL", "ours/CGAL"], rows)


def section_c():
    rows_in = read("bb_sweep_threads.csv")
    if not rows_in:
        return
    print("### (c) BB: time per sweep, threads 1 vs 2 (CVD, l-neighbourhood initial clusters)\n")
    print("load1 over the runs: %s\n" % load_span(rows_in))
    b = best(rows_in, ["mesh", "k", "algo", "threads"], "opt_s")
    rows = []
    for key in sorted(b, key=lambda k: (mesh_key(k[0]), k[2], int(k[3]))):
        r = b[key]
        it = int(r["iterations"])
        per = "%.2f ms" % (1000 * float(r["opt_s"]) / it) if key[2] == "bb" and it else "–"
        speed = ""
        if key[2] == "bb" and key[3] == "2":
            one = b[(key[0], key[1], "bb", "1")]
            speed = "%.2f×" % (float(one["opt_s"]) / float(r["opt_s"]))
        threads = int(r["threads"]) or 1
        rows.append([key[0], r["faces"], key[1], key[2].upper(), key[3] if key[2] == "bb" else "1",
                     s(r["init_s"]), s(r["opt_s"]), it if key[2] == "bb" else "–", per, speed,
                     e(r["final_energy"]), load(r, threads)])
    table(["mesh", "faces", "k", "optimiser", "threads", "init", "optimisation", "sweeps",
           "per sweep", "speed-up 2 vs 1", "final CVD", "load1"], rows)


def section_d():
    rows_in = read("table3_1_mwcvd.csv")
    if not rows_in:
        return
    print("### (d) Table 3.1: l-neighbourhood initial clusters and EMLO per energy\n")
    print("load1 over the runs: %s\n" % load_span(rows_in))
    b = best(rows_in, ["mesh", "k", "energy"], "total_s")
    names = {"mwcvd-area": "MWCVD w^A", "mwcvd-variance": "MWCVD w^V", "mwcvd-max": "MWCVD w^M",
             "cvd": "CVD (reference)"}
    rows = []
    for key in sorted(b, key=lambda k: (mesh_key(k[0]), -int(k[1]), list(names).index(k[2]))):
        r = b[key]
        rows.append([key[0], r["faces"], key[1], names[key[2]], s(r["init_s"]), s(r["opt_s"]),
                     s(r["total_s"]), e(r["initial_energy"]), e(r["final_energy"]),
                     "%.1f%%" % (100 * (1 - float(r["final_energy"]) / float(r["initial_energy"]))),
                     r["moves"], load(r)])
    table(["mesh", "faces", "k", "energy", "l-neighbourhood init", "EMLO", "total", "E initial",
           "E after EMLO", "EMLO lowers E by", "moves", "load1"], rows)


def section_e():
    rows_in = read("fig3_13_cli.csv")
    if not rows_in:
        return
    print("### (e) Fig. 3.13: fandisk, k = 200, EMLO through the CLI\n")
    rows = [[r["energy"], e(r["energy_value"]), s(r["cli_seconds"]),
             "![](bench/results/fig313_fandisk_%s.png)" % r["energy"],
             "%d KB" % (int(r["png_bytes"]) // 1024)] for r in rows_in]
    table(["energy", "E at k=200", "job time (CLI)", "picture", "PNG"], rows)


def section_f():
    ml = read("ml_hierarchy_vs_cgal_ml_bench.csv")
    cgal = read("ml_hierarchy_vs_cgal_cgal_vsa.csv")
    if not ml:
        return
    print("### (f) the whole ML hierarchy of bunny00 vs one CGAL VSA partition (k = 1000)\n")
    print("load1 over the runs: %s\n" % load_span(ml, cgal))
    m = best(ml, ["algo"], "seconds")[("ml",)]
    bc = best(cgal, ["seeding"], "total_seconds")
    rows = [["ML (CVD, EMLO), all %s levels" % m["levels"], "**%s**" % s(m["seconds"]),
             "CVD %s at k=%s" % (e(m["energy_at_k"]), m["k"]), load(m)]]
    for seeding in ["random", "hierarchical"]:
        r = bc[(seeding,)]
        rows.append(["CGAL VSA k=1000, %s seeding" % seeding, "**%s**" % s(r["total_seconds"]),
                     "L2,1 %s" % e(r["energy_l21"]), load(r)])
    table(["run", "time", "energy", "load1"], rows)
    fastest = min(float(r["total_seconds"]) for r in bc.values())
    ratio = float(m["seconds"]) / fastest
    print("ML's whole hierarchy takes %.2f× the time of CGAL's faster single partition: target "
          "(ML all levels faster than one CGAL partition) **%s**.\n" %
          (ratio, "met" if ratio < 1 else "missed"))


def ml_best(rows, keys=("mesh", "algo", "energy", "pml_until", "threads")):
    """ml_bench prints one row per k; the time is the run's. Returns {config: {k: row}}."""
    runs = {}
    for r in rows:
        # Rows come in the order of --at (1000,200,50 or 1000 alone); the k column holds
        # the level reached (PML skips counts: its first level with at most k clusters).
        # Runs without the optimiser (other than HC) get "none" appended to their key.
        extra = ("none",) if r["optimizer"] == "none" and r["algo"] != "hc" else ()
        by_k = runs.setdefault(tuple(r[k] for k in keys) + extra + (r["rep"],), {})
        by_k[str(REQUESTED_K[len(by_k)])] = r
    out = {}
    for key, by_k in runs.items():
        config = key[:-1]
        t = float(next(iter(by_k.values()))["seconds"])
        if config not in out or t < float(next(iter(out[config].values()))["seconds"]):
            out[config] = by_k
    return out


def at(by_k, k, what="energy_at_k"):
    r = by_k.get(str(k))
    return r[what] if r else None


def section_g():
    rows_in = read("pml_then_ml.csv")
    if not rows_in:
        return
    print("### (g) PML down to 2000 clusters, then ML, vs ML (CVD, EMLO)\n")
    print("load1 over the runs: %s\n" % load_span(rows_in))
    b = ml_best(rows_in)
    rows = []
    for mesh in sorted({k[0] for k in b}, key=mesh_key):
        ml = b[(mesh, "ml", "cvd", "0", "0")]
        t_ml = float(at(ml, 1000, "seconds"))
        for cfg, name in [((mesh, "ml", "cvd", "0", "0"), "ML"),
                          ((mesh, "pml", "cvd", "2000", "0"), "PML→2000, ML (all cores)"),
                          ((mesh, "pml", "cvd", "2000", "1"), "PML→2000, ML (1 thread)")]:
            r = b.get(cfg)
            if r is None:
                continue
            t = float(at(r, 1000, "seconds"))
            e1000 = float(at(r, 1000)) / float(at(ml, 1000))
            threads = 2 if cfg[1] == "pml" and cfg[4] == "0" else 1
            rows.append([mesh, name, s(t), "%.0f%%" % (100 * t / t_ml), e(at(r, 1000)),
                         "%+.2f%%" % (100 * (e1000 - 1)), e(at(r, 200)), e(at(r, 50)),
                         ("" if cfg[1] == "ml" else
                          ("t " + ("ok" if t <= 0.25 * t_ml else "**missed**") + ", E " +
                           ("ok" if abs(e1000 - 1) <= 0.02 else "**missed**"))),
                         load(next(iter(r.values())), threads)])
    table(["mesh", "run", "time", "of ML's", "E at k=1000", "vs ML", "E at 200", "E at 50",
           "target (≤ 25% time, E within 2%)", "load1"], rows)
    rows = []
    for mesh in sorted({k[0] for k in b}, key=mesh_key):
        ml = b[(mesh, "ml", "cvd", "0", "0")]
        pml = b[(mesh, "pml", "cvd", "2000", "0")]
        hc = b.get((mesh, "hc", "cvd", "0", "0"))
        pml_hc = b.get((mesh, "pml", "cvd", "2000", "0", "none"))
        if hc is None or pml_hc is None:
            continue
        t = {name: float(at(r, 1000, "seconds")) for name, r in
             [("ml", ml), ("pml", pml), ("hc", hc), ("pml_hc", pml_hc)]}
        first = {name: next(iter(r.values())) for name, r in [("ml", ml), ("pml", pml)]}
        rows.append([mesh, s(t["hc"]), s(t["pml_hc"]), "%.0f%%" % (100 * t["pml_hc"] / t["hc"]),
                     s(t["ml"] - t["hc"]), s(t["pml"] - t["pml_hc"]),
                     "{:,} / {:,}".format(int(first["ml"]["evaluations"]),
                                          int(first["pml"]["evaluations"])),
                     "%.0f%%" % (100 * (t["ml"] - t["hc"]) / t["ml"])])
    if rows:
        print("Where the time goes: the same runs without the optimiser (HC = ML's merges "
              "alone; PML→2000, HC = PML's merges alone), and the optimiser's share "
              "(the difference):\n")
        table(["mesh", "HC", "PML→2000, HC", "of HC's", "optimiser in ML",
               "optimiser in PML→2000, ML", "optimiser evaluations ML / PML",
               "optimiser share of ML"], rows)


def section_h():
    rows_in = read("planar_hierarchies.csv")
    cgal = read("vsa_vs_cgal_cgal_vsa.csv")
    ours_vsa = read("vsa_vs_cgal_vsa_bench.csv")
    if not rows_in:
        return
    print("### (h) planar (L2,1) energy at k = 200: ML vs CGAL VSA's better seeding\n")
    print("load1 over the ML runs: %s; CGAL energies from (b) (deterministic: the seeding's "
          "seed is fixed)\n" % load_span(rows_in))
    b = ml_best(rows_in)
    bc = best(cgal, ["mesh", "k", "seeding"], "total_seconds")
    bo = best(ours_vsa, ["mesh", "k", "seeding"], "seconds")
    rows = []
    for mesh in sorted({k[0] for k in b}, key=mesh_key):
        ml = b[(mesh, "ml", "planar", "0", "0")]
        hc = b.get((mesh, "hc", "planar", "0", "0"), {})
        pml = b.get((mesh, "pml", "planar", "0", "0"), {})
        c = {sd: bc.get((mesh, "200", sd)) for sd in ["random", "hierarchical"]}
        c = {sd: r for sd, r in c.items() if r}
        if not c:
            continue
        best_sd = min(c, key=lambda sd: float(c[sd]["energy_l21"]))
        ec = float(c[best_sd]["energy_l21"])
        em = float(at(ml, 200))
        v = bo.get((mesh, "200", "hierarchical"))
        rows.append([mesh, "**%s**" % e(em), e(at(hc, 200)) if hc else "–",
                     "%s (k=%s)" % (e(at(pml, 200)), at(pml, 200, "k")) if pml else "–",
                     e(v["energy"]) if v else "–",
                     e(c["random"]["energy_l21"]), e(c["hierarchical"]["energy_l21"]),
                     "%.2f" % (em / ec), "met" if em < ec else "**missed**",
                     s(at(ml, 200, "seconds")), s(c[best_sd]["total_seconds"])])
    table(["mesh", "ML", "HC", "PML", "our VSA (hier.)", "CGAL random", "CGAL hierarchical",
           "ML / best CGAL", "target (ML below)", "ML all levels", "CGAL k=200 (better seeding)"],
          rows)


def section_i():
    rows_in = read("cvd_hierarchies.csv")
    if not rows_in:
        return
    b = ml_best(rows_in)
    meshes = sorted({k[0] for k in b}, key=mesh_key)
    configs = [("ml", "0", "ML"), ("hc", "0", "HC"), ("pml", "0", "PML"),
               ("pml", "2000", "PML→2000, ML")]
    print("### (i) the whole hierarchy, CVD (tables 4.3–4.5, 5.3)\n")
    print("load1 over the runs: %s. PML and PML→2000 use both cores (threads = 0).\n" %
          load_span(rows_in))
    rows = []
    for mesh in meshes:
        first = next(iter(b[(mesh, "ml", "cvd", "0", "0")].values()))
        row = [mesh, "{:,}".format(int(first["faces"]))]
        t_ml = None
        for algo, until, _ in configs:
            r = b.get((mesh, algo, "cvd", until, "0"))
            if r is None:
                row.append("–")
                continue
            t = float(at(r, 1000, "seconds"))
            t_ml = t if algo == "ml" else t_ml
            row.append(s(t) + ("" if algo == "ml" else " (%.0f%%)" % (100 * t / t_ml)))
        row.append("%.2f µs" % (1e6 * t_ml / int(first["faces"])))
        row.append(load(first))
        rows.append(row)
    print("Time for every level (one cluster per face down to one cluster; % of ML's time):\n")
    table(["mesh", "faces"] + [c[2] for c in configs] + ["ML per face", "load1 (ML)"], rows)
    for k in [1000, 200, 50]:
        rows = []
        for mesh in meshes:
            ml = b[(mesh, "ml", "cvd", "0", "0")]
            em = float(at(ml, k))
            row = [mesh]
            for algo, until, _ in configs:
                r = b.get((mesh, algo, "cvd", until, "0"))
                if r is None:
                    row.append("–")
                    continue
                ek, got = float(at(r, k)), at(r, k, "k")
                text = e(ek)
                if algo != "ml":
                    text += " (%+.1f%%)" % (100 * (ek / em - 1))
                if got != str(k):
                    text += " [k=%s]" % got
                row.append(text)
            rows.append(row)
        print("CVD energy at k = %d (vs ML; [k=..] where PML skipped k: its first level "
              "below):\n" % k)
        table(["mesh"] + [c[2] for c in configs], rows)


def main():
    machine = os.path.join(RESULTS, "machine_mesh.txt")
    print("<!-- generated by bench/plot_mesh_tables.py from bench/results/*.csv -->\n")
    if os.path.exists(machine):
        print("```\n" + open(machine).read().strip() + "\n```\n")
    for f in [section_a, section_b, section_c, section_d, section_e, section_f, section_g,
              section_h, section_i]:
        f()


if __name__ == "__main__":
    main()
