"""The scaffolding validation/framework.py gives every case: the convergence fit, the run cache,
the scene text, the figure with its CSV and the section's tables and figure links (one home
each, issue 26)."""
import math

import numpy as np
import pytest

from thermal_kernel.scene import load_scene
from validation.framework import ROOT, cached, figure_csv, figure_md, fit_order, md_table, \
    scene_toml


def test_fit_order_recovers_a_power_law_and_skips_what_has_no_log():
    n = np.array([1e3, 1e4, 1e5, 1e6])
    p, c = fit_order(n, -3.0 * n ** -0.5)               # |err|: the sign does not matter
    assert p == pytest.approx(-0.5, abs=1e-12) and c == pytest.approx(3.0, rel=1e-10)
    with_bad = fit_order(np.append(n, [2e6, 3e6, 0.0]),
                         np.append(3.0 * n ** -0.5, [0.0, math.nan, 1.0]))
    assert with_bad == pytest.approx((p, c), rel=1e-12)
    assert all(math.isnan(v) for v in fit_order([1e3, 1e4], [0.1, 0.0]))


def test_figure_csv_writes_the_figure_and_its_numbers_or_neither(tmp_path):
    png = tmp_path / "validation_case0_demo.png"
    with figure_csv(png, "label,x,y", 1, 2, figsize=(4, 2)) as ((a, b), csv):
        a.plot([0.0, 1.0], [1.0, 2.0])
        b.plot([0.0, 1.0], [2.0, 1.0])
        csv += [("a,b", 1, 1 / 3), ("c", 2, 2.0)]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the csv module's quoting, floats to 10 digits, ints as they are, "\r\n" unless told
    assert png.with_suffix(".csv").read_bytes() == \
        b'label,x,y\r\n"a,b",1,0.3333333333\r\nc,2,2\r\n'
    other = tmp_path / "other.png"
    with figure_csv(other, ["t", "T"], figsize=(3, 2), digits=None, line_end="\n") as (ax, csv):
        csv.append((0.1 + 0.2, "5.000"))
    assert other.with_suffix(".csv").read_text() == "t,T\n0.30000000000000004,5.000\n"
    failed = tmp_path / "failed.png"
    with pytest.raises(ZeroDivisionError):
        with figure_csv(failed, ["x"], figsize=(3, 2)) as (ax, csv):
            csv.append((1.0,))
            csv.append((1.0 / 0,))
    assert not failed.exists() and not failed.with_suffix(".csv").exists()


def test_md_table_and_figure_md_write_the_sections_markdown():
    table = md_table(["", "A", "B"], [("tdem 400", 1.5, "2 %"), ["FV", "—", ""]])
    assert table.splitlines() == ["| | A | B |", "|---|---|---|", "| tdem 400 | 1.5 | 2 % |",
                                  "| FV | — |  |"]
    assert md_table(["N"], []) == "| N |\n|---|"
    png = ROOT / "docs" / "img" / "validation_case0_x.png"
    assert figure_md("case 0", png) == \
        "![case 0](img/validation_case0_x.png)\n\n(data: `img/validation_case0_x.csv`)"


def test_cached_makes_once_per_version_and_keeps_the_field(tmp_path):
    made = []

    def make():
        made.append(1)
        return {"n": 7, "_field": (np.arange(3.0), np.ones(3))}

    path = tmp_path / "run.json"
    first = cached(path, make, 1, arrays=("r", "t"))
    again = cached(path, make, 1, arrays=("r", "t"))
    assert len(made) == 1 and again["n"] == 7 and again["version"] == 1
    np.testing.assert_array_equal(again["_field"][0], first["_field"][0])
    assert "_field" not in path.read_text()               # the arrays live in run.npz
    cached(path, make, 2)
    assert len(made) == 2                                  # a new version of the case: made again


def test_scene_toml_is_the_scene_a_user_would_write(tmp_path):
    text = scene_toml(tmp_path / "p.h5", "haddad", law_params=dict(ct=0.806), neighbours=None,
                      material=dict(conductivity=33.0, density=7800.0, heat_capacity=0.9),
                      initial=dict(temperature=303.15),
                      boundary=[dict(kind="temperature", name="cold", on="ymin", value=298.15),
                                dict(kind="temperature", name="hot", on="ymax", value=308.15)],
                      solver=dict(method="steady"))
    scene = load_scene(tmp_path / "s.toml", text=text)
    assert scene.packing == tmp_path / "p.h5" and scene.law_params == {"ct": 0.806}
    assert scene.neighbours is None and scene.material(0).conductivity == 33.0
    assert [(b.name, b.on, b.value) for b in scene.boundaries] == [
        ("cold", "ymin", 298.15), ("hot", "ymax", 308.15)]
    assert scene.solver.method == "steady" and scene.initial_temperature == 303.15


def test_tdem_validate_gives_the_cases_its_threads(monkeypatch, capsys):
    # the case modules' own entry points are gone: `tdem validate N --threads T` is theirs
    import types

    from tdem.cli import main
    from validation import run
    from validation.framework import CaseInfo, CaseResult
    seen = []

    def run_case(ctx):
        seen.append((ctx.number, ctx.quick, ctx.threads))
        return CaseResult(our_n="1", our_error="0 %", wall_time="1 s", verdict="met",
                          section_md="")
    fake = types.SimpleNamespace(CASE=CaseInfo(number=3, title="t", paper="p", paper_n="1",
                                               paper_error="1"), run=run_case,
                                 __file__="case3_fake.py")
    monkeypatch.setattr(run, "discover", lambda: {3: fake})
    import numba
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 4)    # any machine: 2 is allowed
    assert main(["validate", "3", "--quick", "--threads", "2"]) == 0
    assert main(["validate", "3", "--quick"]) == 0
    assert seen == [(3, True, 2), (3, True, 1)]
    assert main(["validate", "3", "--quick", "--threads", "0"]) == 2
    assert "--threads: expected an integer from 1" in capsys.readouterr().err


def test_a_cases_extra_step_runs_through_tdem_validate(monkeypatch, capsys):
    import types

    from tdem.cli import main
    from validation import run
    from validation.framework import Action, CaseInfo
    done = []
    fake = types.SimpleNamespace(
        CASE=CaseInfo(number=3, title="t", paper="p", paper_n="1", paper_error="1"),
        run=lambda ctx: None, __file__="case3_fake.py",
        ACTIONS={"rebuild": Action(lambda ctx: done.append((ctx.number, ctx.quick)), "again")})
    monkeypatch.setattr(run, "discover", lambda: {3: fake, 4: fake})
    assert main(["validate", "3", "--action", "rebuild", "--quick"]) == 0
    assert done == [(3, True)]
    assert main(["validate", "3", "--action", "extend"]) == 2
    assert "case 3 has no step 'extend' (its steps: rebuild: again)" in capsys.readouterr().err
    assert main(["validate", "3", "4", "--action", "rebuild"]) == 2 and done == [(3, True)]
