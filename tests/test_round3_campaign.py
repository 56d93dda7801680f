"""Reliability round 3 (issue 28) for campaigns, `tdem validate`'s saved results and the command
line: the rules, each stated on a test that failed on the code before the round.

- A campaign case is kept only while it matches its inputs: rerun into the same ``--out`` after
  the scene (k / 10, hot wall 600 K) or one packing file was edited, the campaign gives the
  results of a fresh campaign on the edited inputs, and its lines say which cases were recomputed
  and why (before: every case "done before, kept", the report showing the old numbers).
- A kept case posted by other post-processing code (tdem_post's hash) is posted again; ``--repost``
  of a thermal.h5 holding a NaN temperature does not post it silently: the case is recomputed
  and the line says why.
- No slope or power law over pressure through pressures that are not distinct (two copies of
  one bed gave "log-log slope -0.659" through two identical points).
- Refusals (one table): one line on stderr naming the file or flag and what was expected,
  exit 2, no traceback, and the folder as it was (nothing made, nothing left): a campaign's bad
  [pack] (its --out was made and left empty), a listed packing without the walls the scene holds
  (found only when its case ran, after the others), seeds out of range, negative values given
  as ``--flag -1e8``; and a corrupt ``validation/results/caseN.json`` (truncated, empty, binary,
  a list, ``result`` missing, wrong types) under --list, a run of that case and ``--force 1``.
- SIGTERM ends a run as Ctrl-C does (one line, exit 143, no lock, nothing written); an interrupt
  that arrives after the command returned, or that a finaliser swallowed, is one line and
  128 + the signal, not "Exception ignored ... KeyboardInterrupt" and exit 0.

The campaigns run on the committed 300-sphere beds listed as ``[campaign] packings`` (no YADE),
with a short Crank-Nicolson transient; every comparison is against a fresh run, not numbers.
"""
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main

DATA = Path(__file__).resolve().parent / "data"
LOW, HIGH = DATA / "bed_small_1.6e+06Pa.h5", DATA / "bed_small_4.05e+07Pa.h5"
SOLVER = """
[solver]
method = "implicit"
theta = 0.5
dt = 2.0
end_time = 200.0
output_times = [10.0, 20.0, 50.0, 100.0, 200.0]
"""
# the wall-clock columns differ between two runs of the same case
CLOCKS = ["thermal_wall_seconds", "case_wall_seconds"]


def write_campaign(path: Path, beds, thermal=BED_THERMAL, extra="") -> Path:
    path.write_text(f'[campaign]\nlaws = ["pipe"]\nn_bins = 6\npackings = '
                    f'{json.dumps([str(b) for b in beds])}\n{extra}{thermal}{SOLVER}')
    return path


def campaign(capsys, path, out, *extra):
    """`tdem campaign` in this process: (exit code, stdout, stderr)."""
    capsys.readouterr()
    code = main(["campaign", str(path), "--out", str(out), "--quiet", "--threads", "1", *extra])
    got = capsys.readouterr()
    return code, got.out, got.err


def results(out) -> pd.DataFrame:
    return pd.read_csv(out / "results.csv", keep_default_na=False).drop(columns=CLOCKS)


def same_as_fresh(out, fresh):
    pd.testing.assert_frame_equal(results(out), results(fresh), rtol=1e-12)
    table = [line for line in (out / "report.md").read_text().splitlines()
             if line.startswith("| ") or line.startswith("- ")]
    assert table == [line for line in (fresh / "report.md").read_text().splitlines()
                     if line.startswith("| ") or line.startswith("- ")]


def case_lines(stdout):
    return {line.split(": ", 1)[0].split("] ", 1)[1]: line
            for line in stdout.splitlines() if line.startswith("[")}


# --- stale cases ----------------------------------------------------------------------------

# slow (issue 28): whole campaigns run twice, 11-18 s each on the shared machine
@pytest.mark.slow
def test_rerun_after_a_scene_edit_equals_a_fresh_campaign(tmp_path, capsys):
    """k / 10 and the hot wall at 600 K, rerun into the same --out: the case is recomputed (its
    line says the scene changed), and the table and report are those of a fresh campaign on the
    edited file. The edit matters: tau is ~10x longer."""
    out = tmp_path / "out"
    path = write_campaign(tmp_path / "camp.toml", [LOW])
    assert campaign(capsys, path, out)[0] == 0
    before = results(out)
    summary = json.loads((out / "cases" / f"{LOW.stem}_pipe" / "post" / "summary.json")
                         .read_text())
    for key in ("scene_sha256", "packing_sha256", "post_sha256"):
        assert len(summary[key]) == 64

    edited = BED_THERMAL.replace("conductivity = 205.0", "conductivity = 20.5") \
        .replace("value = 500.0", "value = 600.0")
    assert edited != BED_THERMAL
    path2 = write_campaign(tmp_path / "camp_edited.toml", [LOW], thermal=edited)
    code, stdout, err = campaign(capsys, path2, out)
    assert code == 0, err
    assert "done before" not in stdout
    assert "recomputed: the scene changed since it ran" in case_lines(stdout)[f"{LOW.stem}_pipe"]
    fresh = tmp_path / "fresh"
    assert campaign(capsys, path2, fresh)[0] == 0
    same_as_fresh(out, fresh)
    assert (results(out).tau_s > 5 * before.tau_s).all()
    assert "camp_edited.toml" in (out / "report.md").read_text().splitlines()[0]


# slow (issue 28): whole campaigns run twice, 11-18 s each on the shared machine
@pytest.mark.slow
def test_rerun_after_a_packing_edit_recomputes_that_case_only(tmp_path, capsys):
    """One listed packing file edited (the pressure it records, which the report's fits over
    pressure read): that case is recomputed ("the packing file changed"), the other kept, and
    the result is a fresh campaign's on the edited files."""
    beds = [shutil.copy(b, tmp_path / b.name) for b in (LOW, HIGH)]
    path = write_campaign(tmp_path / "camp.toml", beds)
    out = tmp_path / "out"
    assert campaign(capsys, path, out)[0] == 0
    before = results(out)
    with h5py.File(beds[0], "r+") as f:
        f.attrs["pressure_pa"] = 1.5 * f.attrs["pressure_pa"]
    code, stdout, err = campaign(capsys, path, out)
    assert code == 0, err
    lines = case_lines(stdout)
    assert "recomputed: the packing file changed since it ran" in lines[f"{LOW.stem}_pipe"]
    assert "done before" in lines[f"{HIGH.stem}_pipe"]
    fresh = tmp_path / "fresh"
    assert campaign(capsys, path, fresh)[0] == 0
    same_as_fresh(out, fresh)
    assert sorted(results(out).pressure_pa) != sorted(before.pressure_pa)   # the edit matters


# slow (issue 28): whole campaigns run twice, 11-18 s each on the shared machine
@pytest.mark.slow
def test_a_kept_run_is_posted_again_when_post_changed_or_its_file_is_bad(tmp_path, capsys):
    """A case posted by other post-processing code (its stored hash of tdem_post differs, and
    its gamma with it) is posted again from its thermal.h5, not kept. A NaN put into a kept
    case's thermal.h5: --repost does not post it; the case is recomputed and its line says why.
    Both end with the untouched campaign's table."""
    path = write_campaign(tmp_path / "camp.toml", [LOW])
    out = tmp_path / "out"
    assert campaign(capsys, path, out)[0] == 0
    before = results(out)
    summary_path = out / "cases" / f"{LOW.stem}_pipe" / "post" / "summary.json"
    summary = json.loads(summary_path.read_text())
    summary_path.write_text(json.dumps(dict(summary, post_sha256="0" * 64, gamma=1.0)))
    code, stdout, _ = campaign(capsys, path, out)
    assert code == 0 and "done before" not in stdout
    assert "the post-processing (tdem_post) changed since it was posted" in stdout
    pd.testing.assert_frame_equal(results(out), before, rtol=1e-12)

    thermal = out / "cases" / f"{LOW.stem}_pipe" / "thermal.h5"
    with h5py.File(thermal, "r+") as f:
        t = f["temperature"][()]
        t[2, 7] = np.nan
        f["temperature"][...] = t
    code, stdout, _ = campaign(capsys, path, out, "--repost")
    assert code == 0
    assert "recomputed: its thermal.h5 could not be post-processed again" in stdout
    pd.testing.assert_frame_equal(results(out), before, rtol=1e-12)
    with h5py.File(thermal) as f:
        assert np.isfinite(f["temperature"][()]).all()


def test_no_slope_through_pressures_that_are_not_distinct(tmp_path, capsys):
    """Two copies of one bed (one pressure): no log-log slope and no power law are fitted
    (they would go through two identical points); the report says why and a warning names the
    copy."""
    from tdem.campaign import n_distinct
    copy = shutil.copy(LOW, tmp_path / "bed_copy.h5")
    path = write_campaign(tmp_path / "camp.toml", [LOW, copy])
    code, _, stderr = campaign(capsys, path, tmp_path / "out")
    assert code == 0
    assert "has the same content as" in stderr and "bed_copy.h5" in stderr
    report = (tmp_path / "out" / "report.md").read_text()
    slope = [line for line in report.splitlines() if "log-log slope of γ(p)" in line]
    assert len(slope) == 1 and "not fitted: 2 cases at 1 distinct pressure" in slope[0]
    assert "γ(p) not fitted (fewer than 4 distinct pressures with a measured γ: 1)" in report
    assert n_distinct([1e5, 1e5, 2e5]) == 2 and n_distinct([1e5, 1e5 * (1 + 1e-12)]) == 1



def test_results_gamma_paper_is_posts_and_meets_app_a(tmp_path, capsys):
    """results.csv's gamma_paper is post's (the fitted diffusivity read in 003's convention,
    alpha = gamma_paper k_p / (rho_p c_p)), so App. A holds in the table: tau_slab gamma_paper =
    L^2 rho_p c_p / (8 k_p). It was gamma / phi, which mixes the packing's solid fraction with
    the run's own capacity (the report's 'App. A requires' line was then off by their ratio)."""
    out = tmp_path / "out"
    assert campaign(capsys, write_campaign(tmp_path / "camp.toml", [LOW]), out)[0] == 0
    row = results(out).iloc[0]
    summary = json.loads((out / "cases" / f"{LOW.stem}_pipe" / "post" / "summary.json")
                         .read_text())
    assert row.gamma_paper == pytest.approx(summary["gamma_paper"], rel=1e-12)
    # BED_THERMAL: k_p 205 W/m/K, rho_p 2500 kg/m^3, c_p 900 J/kg/K
    app_a = row.length_m ** 2 * 2500.0 * 900.0 / (8 * 205.0)
    assert row.tau_slab_s * row.gamma_paper == pytest.approx(app_a, rel=1e-9)
    assert abs(row.gamma / row.solid_fraction / row.gamma_paper - 1) > 1e-3   # not gamma/phi

# --- refusals: one line, exit 2, nothing left --------------------------------------------------

PACK = """[pack]
generator = "bed"
n_particles = 200
cylinder_radius_m = 0.009
pressures_pa = [2.8e4, 1.6e6]
seed = 7
"""


def _bad_pressure(tmp):
    (tmp / "c.toml").write_text('[campaign]\nlaws = ["pipe"]\n' + PACK.replace(
        "[2.8e4, 1.6e6]", "[-1.0]") + BED_THERMAL + SOLVER)
    return ["campaign", "c.toml", "--out", "out", "--quiet"], ["c.toml", "pack.pressures_pa"]


def _incompatible_walls(tmp):
    shutil.copy(DATA / "dense_box.h5", tmp / "box.h5")
    write_campaign(tmp / "c.toml", [LOW, tmp / "box.h5"])
    return ["campaign", "c.toml", "--out", "out", "--quiet"], \
        ["c.toml", "boundary[1].on: 'plate'", "box.h5", "before any runs"]


def _campaign_seed_huge(tmp):
    (tmp / "c.toml").write_text('[campaign]\nlaws = ["pipe"]\nseeds = [1, 9223372036854775808]\n'
                                + PACK + BED_THERMAL + SOLVER)
    return ["campaign", "c.toml", "--out", "out"], ["c.toml", "campaign.seeds", "64-bit"]


def _pack_scene(tmp):
    (tmp / "s.toml").write_text(PACK)
    return "s.toml"


ROWS = {
    "campaign_bad_pressure": _bad_pressure,
    "campaign_incompatible_walls": _incompatible_walls,
    "campaign_seed_huge": _campaign_seed_huge,
    "pack_seeds_negative": lambda tmp: (["pack", _pack_scene(tmp), "--out", "o", "--seeds",
                                         "-1,2"], ["--seeds", "from 0 to", "[-1, 2]"]),
    "pack_seeds_huge": lambda tmp: (["pack", _pack_scene(tmp), "--out", "o", "--seeds",
                                     "99999999999999999999999"], ["--seeds", "64-bit"]),
    "import_young_negative": lambda tmp: (
        ["import", "liggghts", "a.dump", "p.dump", "--young", "-1e8", "--poisson", "0.2",
         "-o", "x.h5"], ["--young", "-100000000"]),
    "etc_contrasts_negative": lambda tmp: (
        ["etc", _pack_scene(tmp), "--contrasts", "-1,2"], ["--contrasts", "positive", "-1,2"]),
}


def snapshot(folder: Path) -> dict:
    return {p: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")}


@pytest.mark.parametrize("row", ROWS)
def test_refusal_is_one_line_and_leaves_nothing(tmp_path, capsys, monkeypatch, row):
    monkeypatch.chdir(tmp_path)
    argv, words = ROWS[row](tmp_path)
    before = snapshot(tmp_path)
    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("tdem: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for w in words:
        assert w in err, (w, err)
    assert snapshot(tmp_path) == before        # nothing made, nothing changed


# --- tdem validate with a corrupt saved result --------------------------------------------------

def _fake_tree(tmp_path, monkeypatch, calls):
    """validation/ and docs/ in tmp_path with two fake cases (1 and 5), each saved once."""
    import types
    from validation import framework, run
    from validation.framework import CaseInfo, CaseResult
    monkeypatch.setattr(framework, "RESULTS", tmp_path / "results")
    monkeypatch.setattr(framework, "OUT", tmp_path / "out")
    monkeypatch.setattr(framework, "IMG", tmp_path / "img")
    monkeypatch.setattr(run, "DOC", tmp_path / "validation.md")
    monkeypatch.setattr(run, "README", tmp_path / "README.md")
    (tmp_path / "validation.md").write_text("# Validation\n")

    def case(n):
        def run_case(ctx):
            calls.append(n)
            return CaseResult(our_n="100", our_error=f"{n} %", wall_time="1 s", verdict="met",
                              section_md=f"Body {n}.", numbers={"n": n})
        return types.SimpleNamespace(
            CASE=CaseInfo(number=n, title=f"fake {n}", paper="p", paper_n="1", paper_error="1"),
            run=run_case, __file__=f"case{n}_fake.py")
    monkeypatch.setattr(run, "discover", lambda: {1: case(1), 5: case(5)})
    assert main(["validate"]) == 0
    calls.clear()
    return framework.RESULTS / "case5.json"


def _edit(field_fn):
    def write(p):
        d = json.loads(p.read_text())
        field_fn(d)
        p.write_text(json.dumps(d))
    return write


CORRUPT = {
    "truncated": lambda p: p.write_text(p.read_text()[:40]),
    "empty": lambda p: p.write_text(""),
    "a_list": lambda p: p.write_text("[1, 2]"),
    "missing_result": _edit(lambda d: d.pop("result")),
    "wrong_types": _edit(lambda d: (d["result"].update(our_error=12345),
                                    d.update(run_seconds="fast"))),
    "binary": lambda p: p.write_bytes(b"\xff\xfe\x00garbage"),
}


@pytest.mark.parametrize("argv", [["--list"], ["5"], ["--force", "1"]],
                         ids=["list", "run_5", "force_1"])
@pytest.mark.parametrize("how", CORRUPT)
def test_corrupt_saved_result_is_one_line(tmp_path, capsys, monkeypatch, how, argv):
    """Refused in one line naming case5.json and how to write it again, before any case runs:
    the documents and the other results stay as they were."""
    calls = []
    path = _fake_tree(tmp_path, monkeypatch, calls)
    CORRUPT[how](path)
    before = snapshot(tmp_path)
    capsys.readouterr()
    code = main(["validate", *argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "case5.json" in err and "tdem validate 5 --force" in err and "expected" in err
    assert calls == [] and snapshot(tmp_path) == before


def test_force_rewrites_a_corrupt_saved_result(tmp_path, capsys, monkeypatch):
    calls = []
    path = _fake_tree(tmp_path, monkeypatch, calls)
    good = json.loads(path.read_text())
    path.write_text("{")
    assert main(["validate", "5", "--force"]) == 0 and calls == [5]
    again = json.loads(path.read_text())
    assert again["result"] == good["result"]
    assert main(["validate", "--list"]) == 0


# --- signals -------------------------------------------------------------------------------------

def test_sigterm_ends_a_run_as_ctrl_c_does(tmp_path):
    """SIGTERM into a running explicit run: one line, exit 143, nothing written and no lock
    (before: killed silently, thermal.h5.lock left)."""
    scene = tmp_path / "s.toml"
    scene.write_text(f'packing = "{LOW}"\nlaw = "pipe"\n' + BED_THERMAL
                     + '[solver]\nmethod = "explicit"\nend_time = 1e6\n'
                       'output_times = [5e5, 1e6]\n')
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "run", str(scene), "--out",
                             str(out), "--quiet", "--threads", "1"], stderr=subprocess.PIPE,
                            text=True)
    lock = out / "thermal.h5.lock"
    while not lock.exists() and proc.poll() is None:
        time.sleep(0.01)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=120)[1]
    assert proc.returncode == 143, err
    assert err.startswith("tdem: terminated (SIGTERM): ") and err.count("\n") == 1, err
    assert "not written" in err
    assert not lock.exists() and not (out / "thermal.h5").exists()
    assert not out.exists() or not any(out.iterdir())


def _default_sigint():
    # a test run started in the background (`make test &`, nohup) inherits SIGINT ignored, and
    # Python then installs no KeyboardInterrupt handler: give the child the default disposition
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_a_signal_after_the_command_returned_is_one_line_and_its_status():
    """Ctrl-C when the command has returned and the interpreter is ending (an atexit callback
    stands for the moment): before, "Exception ignored ... KeyboardInterrupt" and exit 0."""
    code = ("import atexit, os, signal, sys\n"
            "from tdem.cli import main\n"
            "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), sum(range(10**6))))\n"
            "sys.argv = ['tdem', 'laws']\n"
            "sys.exit(main())\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, preexec_fn=_default_sigint)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr == "tdem: interrupted\n"
    assert "pipe" in proc.stdout            # the command itself ran to its end


def test_an_interrupt_swallowed_by_a_finaliser_is_not_exit_0(capsys, monkeypatch):
    """A KeyboardInterrupt raised inside a __del__ is printed as "Exception ignored" and lost
    by Python; the command then returned 0. Now the signal is remembered: one line, 130."""
    from tdem import cli
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: None)

    class Finaliser:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)
            math.fsum(float(k) for k in range(10_000))    # the handler runs in here

    def command(args):
        x = Finaliser()
        del x
        print("done")
    monkeypatch.setattr(cli, "_cmd_laws", command)
    # a test run in the background (nohup, `make test &`) has SIGINT ignored, where Ctrl-C
    # rightly does nothing; this test is about a Ctrl-C that arrives: Python's default handler
    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        previous = signal.getsignal(signal.SIGINT)
        assert main(["laws"]) == 130
        got = capsys.readouterr()
        assert got.out == "done\n" and got.err == "tdem: interrupted\n"
        assert signal.getsignal(signal.SIGINT) is previous     # put back for the caller
    finally:
        signal.signal(signal.SIGINT, outer)
