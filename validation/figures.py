"""Figures of cases 4 and 6 (docs/validation.md) from validation/out/: PNG + CSV beside, in docs/img/.

  .venv/bin/python validation/figures.py
"""
from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

OUT = Path("validation/out")
IMG = Path("docs/img")
# case 4 packings by family, for the convergence plot
CASE4 = {"walled (YADE box)": ["ds_2000_s1", "ds_2000_s2", "ds_2000_s3", "ds_10000_s1"],
         "tiled (cut cube)": ["tiled_10000_s1", "tiled_10000_s2", "tiled_10000_s3", "tiled_1e5",
                              "tiled_1e6"]}


def fit_order(n, e):
    """e = a N^p by least squares in log-log: (p, a)."""
    p, loga = np.polyfit(np.log(n), np.log(e), 1)
    return float(p), float(np.exp(loga))


def case4():
    best = "tiled_1e5"
    rows = list(csv.DictReader(open(OUT / "case4" / f"{best}_profiles.csv")))
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for fo in sorted({r["fourier"] for r in rows}, key=float):
        sel = [r for r in rows if r["fourier"] == fo]
        x = [float(r["x_over_L"]) for r in sel]
        a.plot(x, [float(r["T_exact_C"]) for r in sel], "-", color="0.5")
        a.plot(x, [float(r["T_dem_C"]) for r in sel], "o", label=f"Fo = {float(fo):.4f}")
        b.plot(x, [100 * float(r["error_K"]) / (float(r["T_exact_C"])) for r in sel], "o-",
               label=f"Fo = {float(fo):.4f}")
    a.set_xlabel("x / L (held planes)")
    a.set_ylabel("T (°C)")
    a.set_title("cube slab, 1e5 spheres: DEM (dots), eq. 17 (lines)")
    a.legend()
    b.axhline(0.7, ls="--", color="r", label="Haddad's max 0.7 %")
    b.axhline(-0.7, ls="--", color="r")
    b.set_xlabel("x / L")
    b.set_ylabel("(T_DEM − T_exact) / T_exact(°C)  (%)")
    b.legend()
    fig.tight_layout()
    fig.savefig(IMG / "validation_case4_profiles.png", dpi=120)
    plt.close(fig)
    with open(IMG / "validation_case4_profiles.csv", "w") as f:
        f.write(open(OUT / "case4" / f"{best}_profiles.csv").read())

    fig, ax = plt.subplots(figsize=(5.5, 4))
    table = []
    for family, names in CASE4.items():
        ns, ec, ed = [], [], []
        for name in names:
            p = OUT / "case4" / f"{name}.json"
            if not p.exists():
                continue
            s = json.loads(p.read_text())
            ns.append(s["n_particles"])
            ec.append(s["max_rel_error_celsius"])
            ed.append(s["max_error_over_dT"])
            table.append((family, name, s["n_particles"], s["ct_held_plane"],
                          s["ct_domain_length"], s["max_rel_error_celsius"],
                          s["max_error_over_dT"], s["steps"], s["run_seconds"]))
        if len(set(ns)) >= 2:
            p, _ = fit_order(ns, ed)
            lab = f"{family}: |err|/ΔT, order {p:.2f}"
        else:
            lab = f"{family}: |err|/ΔT"
        line, = ax.loglog(ns, 100 * np.array(ed), "o", label=lab)
        ax.loglog(ns, 100 * np.array(ec), "x", color=line.get_color(),
                  label=f"{family}: |err|/T(°C)")
    ax.axhline(0.7, ls="--", color="r", lw=0.8, label="Haddad 1e5: 0.7 % (of T in °C)")
    ax.set_xlabel("N (spheres)")
    ax.set_ylabel("max relative error (%)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(IMG / "validation_case4_convergence.png", dpi=120)
    plt.close(fig)
    with open(IMG / "validation_case4_convergence.csv", "w") as f:
        f.write("family,name,n_particles,ct_held,ct_domain,max_err_over_T_celsius,"
                "max_err_over_dT,steps,run_seconds\n")
        for r in table:
            f.write(",".join(str(v) for v in r) + "\n")
    return table


def case6():
    rows = list(csv.DictReader(open(OUT / "case6" / "case6.csv")))
    by = defaultdict(list)
    for r in rows:
        by[r["name"]].append(r)
    summary = []
    for name, rs in by.items():
        summary.append((name, int(rs[0]["n_particles"]), rs[0]["shape"],
                        np.mean([float(r["ct_domain"]) for r in rs]),
                        np.mean([float(r["ct_held"]) for r in rs]),
                        float(rs[0]["z_all"]), float(rs[0]["z_bulk"])))
    fig, ax = plt.subplots(figsize=(6, 4))
    for fam, marker in (("walled", "s"), ("tiled", "o")):
        for shape, fill in (("box", None), ("cylinder", "none")):
            s = [r for r in summary if r[0].startswith(fam) and r[2] == shape]
            if not s:
                continue
            ax.semilogx([r[1] for r in s], [r[3] for r in s], marker, mfc=fill, color="C0",
                        label=f"{fam} {shape}: domain length (tdem calibrate; paper's L)")
            ax.semilogx([r[1] for r in s], [r[4] for r in s], marker, mfc=fill, color="C1",
                        label=f"{fam} {shape}: held-plane distance (tdem post)")
    ax.axhspan(0.75, 0.84, color="0.85", label="Haddad Fig. 3: 0.75–0.84")
    ax.semilogx([1e5, 1e6], [0.806, 0.834], "r*", ms=10, label="Haddad: 0.806 (1e5), 0.834 (1e6)")
    ax.set_xlabel("N (spheres)")
    ax.set_ylabel("C_t (mean over the axes)")
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(IMG / "validation_case6_ct.png", dpi=120)
    plt.close(fig)
    with open(IMG / "validation_case6_ct.csv", "w") as f:
        f.write(open(OUT / "case6" / "case6.csv").read())
    return summary


if __name__ == "__main__":
    for r in case4():
        print(r)
    for r in case6():
        print(r)
