"""Re-run a pressure campaign's thermal cases on packings that already exist (no YADE), with a
chosen implicit scheme, and compare two such runs (issue 16: the default scheme changed).

    python bench/remeasure_campaign.py run CAMPAIGN.toml --packings DIR --scheme theta \
        --out runs/out/remeasure_7500/theta --threads 1
    python bench/remeasure_campaign.py run CAMPAIGN.toml --packings DIR --scheme auto \
        --out runs/out/remeasure_7500/auto --threads 1
    python bench/remeasure_campaign.py compare runs/out/remeasure_7500/theta \
        runs/out/remeasure_7500/auto

`run` writes <out>/campaign.toml (the campaign with `scheme = ...` added to [solver]) and runs
tdem.campaign.run_campaign on it with the packings DIR/packing_<p>Pa.h5 instead of building them
(the campaign's packing step is replaced; everything after it - case scenes, thermal runs,
post-processing, report.md, results.csv - is the campaign's own code). `compare` prints
gamma, gamma_steady and tau of both runs per pressure and law and their relative differences.
"""
import argparse
import re
import sys
from pathlib import Path


def run(args):
    import tdem.campaign as campaign
    from tdem.pack import read_pack_table
    from thermal_kernel.atomic import write_text_atomic

    src = Path(args.campaign)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = src.read_text()
    if args.scheme != "auto":
        text, n = re.subn(r"(?m)^(\[solver\][^\n]*\n)", rf'\1scheme = "{args.scheme}"\n', text)
        if n != 1:
            sys.exit(f"{src}: no [solver] table")
    scene = out / "campaign.toml"
    write_text_atomic(scene, text)
    _, params = read_pack_table(scene)
    pdir = Path(args.packings)
    packings = [pdir / f"packing_{p:.4g}Pa.h5" for p in params["pressures_pa"]]
    missing = [p for p in packings if not p.exists()]
    if missing:
        sys.exit(f"missing packing {missing[0]}")

    def existing_packings(*_a, **_k):
        print(f"remeasure: using the {len(packings)} existing packings in {pdir}/ (no YADE)",
              flush=True)
        return packings

    campaign.build_packings = existing_packings
    campaign.run_campaign(scene, out, threads=args.threads, quiet=True)


def compare(args):
    import pandas as pd
    a = pd.read_csv(Path(args.a) / "results.csv").set_index(["law", "pressure_pa"])
    b = pd.read_csv(Path(args.b) / "results.csv").set_index(["law", "pressure_pa"])
    print(f"A = {args.a}, B = {args.b}; rel = B/A - 1")
    print("| p (bar) | law | γ A | γ B | rel | γ_steady A | γ_steady B | rel | τ A (s) | τ B (s) "
          "| rel | flags A / B |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    worst = {}
    for (law, p), ra in a.iterrows():
        rb = b.loc[(law, p)]
        cells = []
        for key in ("gamma", "gamma_steady", "tau_s"):
            rel = rb[key] / ra[key] - 1
            worst[key] = max(worst.get(key, 0.0), abs(rel))
            cells += [f"{ra[key]:.4g}", f"{rb[key]:.4g}", f"{rel:+.2e}"]
        print(f"| {p / 1e5:.3g} | {law} | " + " | ".join(cells)
              + f" | {ra['flags']} / {rb['flags']} |")
    print("max |rel|: " + ", ".join(f"{k} {v:.2e}" for k, v in worst.items()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("campaign")
    r.add_argument("--packings", required=True)
    r.add_argument("--scheme", default="auto", choices=["auto", "theta", "rannacher", "tr-bdf2"])
    r.add_argument("--out", required=True)
    r.add_argument("--threads", type=int, default=1)
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = ap.parse_args()
    run(args) if args.cmd == "run" else compare(args)


if __name__ == "__main__":
    main()
