"""`tdem campaign` end to end with YADE on a tiny bed (200 spheres, two pressures, laws pipe and
bob), and its resumption after an interruption.

Asserted: one results.csv row per pressure x law with finite, positive gamma inside its interval
and close to the steady ETC (25 %: the profile fit and the steady heat flow measure the same
conductivity in two ways, but this 200-sphere bed is only 4.5 radii wide and ~6 of its ~12
top-layer spheres touch the plate; measured 6-10 %, against 3-8 % on the 7,500 bed); gamma
grows with pressure (contact radii grow as F^(1/3)); pipe > bob
(003 eq. 40 vs 34: 1.033 for equal spheres); the report names both laws; a second run reuses the
packings and every case; a campaign killed after its second case resumes with the two finished
cases kept and ends with the same table; --repost post-processes the kept runs to the same table.

Without YADE (the committed 300-sphere beds stand in for the built packings): every case's
``flags`` (the attribute of its thermal.h5) is a column of results.csv and of the report's
table, and the flagged runs are listed; a clean campaign says none is flagged.
"""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pandas as pd
import pytest

from tdem.committed_beds import BED_THERMAL, BEDS, NO_PACK
from tdem.yade import yade_environment

needs_yade = pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                reason="Debian's yade is not installed")

CAMPAIGN = '''[campaign]
laws = ["pipe", "bob"]
n_bins = 5

[pack]
generator = "bed"
n_particles = 200
cylinder_radius_m = 0.009
pressures_pa = [2.8e4, 1.6e6]
seed = 7

''' + BED_THERMAL + '''

[solver]
method = "implicit"
theta = 0.5
dt = 0.5
end_time = 1000.0
output_times = [2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 1000.0]
'''


def campaign(path, out, *extra):
    return subprocess.run([sys.executable, "-m", "tdem.cli", "campaign", str(path), "--out",
                           str(out), "--quiet", *extra], capture_output=True, text=True,
                          timeout=1200)


@pytest.mark.yade
@needs_yade
def test_campaign_runs_and_resumes(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(CAMPAIGN)
    out = tmp_path / "out"
    first = campaign(path, out)
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    table = pd.read_csv(out / "results.csv")
    assert len(table) == 4
    assert set(table.law) == {"pipe", "bob"}
    assert (table.gamma > 0).all()
    assert ((table.gamma_ci95_low < table.gamma) & (table.gamma < table.gamma_ci95_high)).all()
    assert ((table.gamma / table.gamma_steady - 1).abs() < 0.25).all()
    for law, g in table.groupby("law"):
        g = g.sort_values("pressure_pa")
        assert g.gamma.iloc[1] > g.gamma.iloc[0], law
    by = table.set_index(["law", "pressure_pa"]).gamma
    for p in table.pressure_pa.unique():
        assert by[("pipe", p)] > by[("bob", p)]
    report = (out / "report.md").read_text()
    assert "pipe" in report and "bob" in report and "paper" in report
    assert (out / "gamma_p.png").exists() and (out / "tau_p.png").exists()

    again = campaign(path, out)
    assert again.returncode == 0
    assert "reusing the 2 packings" in again.stdout
    assert again.stdout.count("done before") == 4

    # a real interruption: a second campaign in another folder is killed as soon as its second
    # case is reported; the next run keeps both finished cases, computes the other two, and gives
    # the same table (the packings are bit-identical for the seed: YADE runs single-threaded)
    out2 = tmp_path / "out2"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "campaign", str(path), "--out",
                             str(out2), "--quiet"], stdout=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.startswith("[2/4]"):
            proc.kill()
            break
    proc.wait(timeout=60)
    assert proc.returncode != 0 and not (out2 / "results.csv").exists()
    third = campaign(path, out2)
    assert third.returncode == 0
    assert "reusing the 2 packings" in third.stdout
    assert third.stdout.count("done before") == 2
    assert not list(out2.rglob("*.tmp"))
    resumed = pd.read_csv(out2 / "results.csv")
    pd.testing.assert_series_equal(resumed.gamma, table.gamma, rtol=1e-12)

    # --repost keeps the thermal runs and post-processes them again: same numbers
    fourth = campaign(path, out, "--repost")
    assert fourth.returncode == 0
    assert fourth.stdout.count("post-processed again") == 4
    pd.testing.assert_frame_equal(pd.read_csv(out / "results.csv"), table, rtol=1e-12)


@pytest.mark.yade
@needs_yade
def test_bad_campaign_is_one_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(CAMPAIGN.replace('laws = ["pipe", "bob"]', 'laws = ["pipe", "bobby"]'))
    proc = campaign(path, tmp_path / "out")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "campaign.laws" in proc.stderr
    assert "Traceback" not in proc.stderr


def _campaign_on_committed_beds(tmp_path, monkeypatch, solver_extra, name):
    from tdem import campaign as camp
    monkeypatch.setattr(camp, "build_packings", lambda *a, **k: BEDS)
    path = tmp_path / f"{name}.toml"
    path.write_text(NO_PACK + solver_extra)
    out = tmp_path / name
    camp.run_campaign(path, out, threads=1, quiet=True)
    return out, pd.read_csv(out / "results.csv", keep_default_na=False), \
        (out / "report.md").read_text()


def _case_flags(out):
    """{pressure_pa: flags attribute of the case's thermal.h5 ("none" if empty)}."""
    flags = {}
    for bed in BEDS:
        with h5py.File(bed) as f:
            pressure = float(f.attrs["pressure_pa"])
        with h5py.File(out / "cases" / f"{bed.stem}_pipe" / "thermal.h5") as f:
            flags[pressure] = f.attrs["flags"] or "none"
    return flags


# slow: a campaign on the committed beds, run twice;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_report_shows_each_runs_flags(tmp_path, monkeypatch, capsys):
    # plain Crank-Nicolson at dt = 5 s rings on the stiff 405-bar bed (tests/test_max_principle)
    out, table, report = _campaign_on_committed_beds(
        tmp_path, monkeypatch, 'theta = 0.5\nscheme = "theta"\n', "ringing")
    flags = _case_flags(out)
    high = max(flags)
    assert "max_principle" in flags[high]
    assert dict(zip(table.pressure_pa, table["flags"])) == flags
    rows = [line for line in report.splitlines()
            if line.startswith(f"| {high / 1e5:.3g} | pipe |")]
    assert len(rows) == 1 and rows[0].rstrip().endswith(f"| {flags[high]} |")
    assert "| flags |" in report
    n_flagged = sum("max_principle" in v or "energy_ledger" in v for v in flags.values())
    assert f"**{n_flagged} of 2 runs flagged: their numbers are suspect**" in report
    assert f"{high / 1e5:.3g} bar pipe: max_principle" in report
    # a second call keeps the finished cases and still reads their flags from thermal.h5
    capsys.readouterr()
    from tdem import campaign as camp
    camp.run_campaign(tmp_path / "ringing.toml", out, threads=1, quiet=True)
    assert "done before" in capsys.readouterr().out
    again = pd.read_csv(out / "results.csv", keep_default_na=False)
    assert list(again["flags"]) == list(table["flags"])


# slow: a campaign on the committed beds;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_report_of_a_clean_campaign(tmp_path, monkeypatch):
    # the default second-order scheme (Crank-Nicolson with Rannacher start-up) does not ring
    out, table, report = _campaign_on_committed_beds(tmp_path, monkeypatch, "theta = 0.5\n",
                                                     "clean")
    assert all("max_principle" not in f and "energy_ledger" not in f for f in table["flags"])
    assert dict(zip(table.pressure_pa, table["flags"])) == _case_flags(out)
    assert "No run flagged" in report and "runs flagged" not in report
    # results.csv and report.md's table are the campaign's record (campaign.json), read back
    from tdem_post.campaign_record import CampaignRecord, CaseRow
    from tdem_post.records import markdown_table, read_csv, record_from_json, to_dict
    record = record_from_json(CampaignRecord, out / "campaign.json")
    assert json.dumps([to_dict(r) for r in read_csv(CaseRow, out / "results.csv")]) == \
        json.dumps([to_dict(r) for r in record.rows])
    assert "\n".join(markdown_table(record.rows)) in report
    assert [r.gamma for r in record.rows] == list(table.gamma)


@pytest.mark.parametrize("old, new, key", [
    ("end_time = 200.0", "end_time = 200.0\nsafty = 0.5", "solver.safty: unknown key"),
    ("conductivity = 205.0", "conductivity = -205.0", "material.conductivity: expected a number"),
    ('laws = ["pipe"]', 'laws = ["argento"]', None),
])
def test_case_scenes_checked_before_any_packing(tmp_path, monkeypatch, capsys, old, new, key):
    """Issue 16 sec. 3: a typo in the thermal part was found after YADE built every packing, in
    a generated cases/.../scene.toml. Now one line naming the campaign file and key, and
    build_packings (YADE) is never called."""
    from tdem import campaign as camp
    from tdem.cli import main

    def no_yade(*a, **k):
        raise AssertionError("build_packings called before the case scenes were checked")
    monkeypatch.setattr(camp, "build_packings", no_yade)
    path = tmp_path / "camp.toml"
    text = NO_PACK.replace(old, new)
    if key is None:                 # one law's [law_params] bad (argento: beta > 0)
        text = text.replace("[material]", "[law_params]\nbeta = 0\n\n[material]", 1)
        key = "law_params.beta: expected a number > 0"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["campaign", str(path), "--out", str(out), "--quiet", "--threads", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tdem: error: {path}: {key}"), err
    assert "checked before any packing is built" in err
    assert not out.exists()


# --- seeds (issue 15): one packing series per seed, without YADE -----------------------------

# slow: two seeds' campaigns, then a rerun;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_seeds_campaign_runs_each_series_and_resumes(tmp_path, monkeypatch, capsys):
    """[campaign] seeds = [3, 5]: the committed beds stand in for each seed's series (the fake
    build records the seed and folder); the cases go to seed_<s>/cases/, results.csv has a seed
    column, the report gives mean +- sd over the seeds, and a rerun keeps every case; a case
    whose summary is removed is the only one run again, to the same table."""
    from tdem import campaign as camp
    calls = []
    # each seed's series as the campaign names it; seed 5's measured pressures 1 % off seed 3's
    # (each series reaches the target within its own tolerance): grouped by the target
    series = {}
    for seed, factor in ((3, 1.0), (5, 1.01)):
        folder = tmp_path / f"beds_{seed}"
        folder.mkdir()
        series[seed] = []
        for bed in BEDS:
            target = bed.stem.removeprefix("bed_small_")
            copy = folder / f"packing_{target}.h5"
            shutil.copy(bed, copy)
            with h5py.File(copy, "r+") as f:
                f.attrs["pressure_pa"] = float(f.attrs["pressure_pa"]) * factor
            series[seed].append(copy)

    def fake_build(path, out_dir, *, threads, quiet, seed=None):
        calls.append((seed, Path(out_dir).name))
        return series[seed]
    monkeypatch.setattr(camp, "build_packings", fake_build)
    path = tmp_path / "seeds.toml"
    path.write_text(NO_PACK.replace('n_bins = 5', 'n_bins = 5\nseeds = [3, 5]')
                    + 'theta = 0.5\n')
    out = tmp_path / "out"
    camp.run_campaign(path, out, threads=1, quiet=True, jobs=2)
    assert sorted(calls) == [(3, "seed_3"), (3, "seed_3"), (5, "seed_5"), (5, "seed_5")]
    table = pd.read_csv(out / "results.csv", keep_default_na=False)
    assert sorted(table.seed) == [3, 3, 5, 5] and len(table) == 4
    for s in (3, 5):
        for bed in series[s]:
            assert (out / f"seed_{s}" / "cases" / f"{bed.stem.removeprefix('packing_')}_pipe"
                    / "post" / "summary.json").exists()
    assert sorted(set(table.pressure_target_pa)) == [1.6e6, 4.05e7]
    assert table.pressure_pa.nunique() == 4
    # the same contacts under both seeds: one group per target, spread zero
    stats = camp.seed_statistics(table)
    assert list(stats.n_seeds) == [2, 2] and (stats.gamma_std < 1e-12).all()
    report = (out / "report.md").read_text()
    assert "## Over the 2 packing seeds" in report and "| pipe | 16 | 16.2 | 2 |" in report
    assert "log-log slope of γ(p) = " in report and "| seed | p (bar) |" in report
    assert (out / "gamma_p.png").exists() and (out / "contact_angles.png").exists()
    for col in ("gamma_paper", "gamma_affine", "fabric_nz2", "tau_slab_s"):
        assert col in table.columns
    capsys.readouterr()
    camp.run_campaign(path, out, threads=1, quiet=True)
    assert capsys.readouterr().out.count("done before") == 4
    (out / "seed_5" / "cases" / "4.05e+07Pa_pipe" / "post" / "summary.json").unlink()
    camp.run_campaign(path, out, threads=1, quiet=True)
    printed = capsys.readouterr().out
    assert printed.count("done before") == 3 and "[4/4] seed 5" in printed
    again = pd.read_csv(out / "results.csv", keep_default_na=False)
    pd.testing.assert_series_equal(again.gamma, table.gamma, rtol=1e-12)


def test_a_seeds_series_is_built_once_and_reused(tmp_path, monkeypatch, capsys):
    """build_packings with a seed: YADE (a fake that writes params.json and copies the committed
    beds, as compressed_bed.py would) runs with [pack] and that seed into seed_<s>/packings/;
    a second call reuses the series; another seed, or changed parameters, builds again."""
    from tdem import campaign as camp
    from tdem import yade
    runs = []

    def fake_generator(generator, params, out_dir, *, threads=1, quiet=False):
        out_dir = Path(out_dir)
        assert out_dir.is_absolute()
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "params.json").write_text(json.dumps(dict(params,
                                                             output_dir=str(out_dir))))
        for p, bed in zip(params["pressures_pa"], BEDS):
            shutil.copy(bed, out_dir / f"packing_{p:.4g}Pa.h5")
        runs.append((params["seed"], out_dir.parent.name))
        return 0.1
    monkeypatch.setattr(yade, "run_generator", fake_generator)
    path = tmp_path / "c.toml"
    path.write_text(CAMPAIGN)
    out = tmp_path / "out"
    made = camp.build_packings(path, out / "seed_2", threads=1, quiet=True, seed=2)
    assert runs == [(2, "seed_2")] and [p.name for p in made] == [
        "packing_2.8e+04Pa.h5", "packing_1.6e+06Pa.h5"]
    camp.build_packings(path, out / "seed_2", threads=1, quiet=True, seed=2)
    assert runs == [(2, "seed_2")]
    assert "reusing the 2 packings" in capsys.readouterr().out
    camp.build_packings(path, out / "seed_4", threads=1, quiet=True, seed=4)
    assert runs[-1] == (4, "seed_4")
    path.write_text(CAMPAIGN.replace("n_particles = 200", "n_particles = 201"))
    camp.build_packings(path, out / "seed_2", threads=1, quiet=True, seed=2)
    assert runs[-1] == (2, "seed_2") and len(runs) == 3


def test_target_pressure_from_the_packing_name():
    from tdem.campaign import target_pressure
    assert target_pressure(Path("x/packing_2.8e+04Pa.h5"), 2.83e4) == 2.8e4
    assert target_pressure(Path("bed_small_1.6e+06Pa.h5"), 1.61e6) == 1.6e6
    assert target_pressure(Path("packing_100000Pa.h5"), 1.01e5) == 1e5
    assert target_pressure(Path("settled.h5"), 123.0) == 123.0


@pytest.mark.parametrize("seeds", ["[1, 1]", "[-1]", '"1"', "[]", "[1.5]", "[true]"])
def test_bad_seeds_are_one_line(tmp_path, seeds):
    from tdem import campaign as camp
    from tdem.errors import UserError
    path = tmp_path / "bad.toml"
    path.write_text(CAMPAIGN.replace("n_bins = 5", f"n_bins = 5\nseeds = {seeds}"))
    with pytest.raises(UserError, match="campaign.seeds: expected a list of distinct"):
        camp.read_campaign(path)
