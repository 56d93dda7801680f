"""tdem_post.window: a campaign case run again on other output times (003's 0.2-7 s) and fitted
like the case (issue 15). On the committed 300-sphere bed (no YADE): the window run is the
case's scene with the new times, its fit is written to window.json and kept on a second call;
the early window's gamma differs from the long window's (it sees the wall layers only)."""
import json

import pandas as pd
import pytest

from tdem.committed_beds import BEDS, NO_PACK


# slow: a campaign case, then its window fit;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_window_fit_of_a_campaign_case(tmp_path, monkeypatch, capsys):
    from tdem import campaign as camp
    from tdem_post.window import main, window_fit
    monkeypatch.setattr(camp, "build_packings", lambda *a, **k: BEDS[:1])
    path = tmp_path / "c.toml"
    path.write_text(NO_PACK + "theta = 0.5\n")
    camp.run_campaign(path, tmp_path / "out", threads=1, quiet=True)
    case = tmp_path / "out" / "cases" / f"{BEDS[0].stem}_pipe"
    r = window_fit(case, times=(0.5, 1.0, 2.0), threads=1)
    assert r["times_s"] == [0.5, 1.0, 2.0] and r["dt_s"] == 0.05
    # gamma_paper reads the fitted diffusivity in 003's convention (alpha = gamma_paper k_p /
    # (rho_p c_p)): over gamma it is rho_p c_p over the run's bed capacity, the same ratio in the
    # window's fit as in the case's (same bed, same law)
    case_post = json.loads((case / "post" / "summary.json").read_text())
    assert r["gamma_window"] > 0 and r["gamma_paper_window"] / r["gamma_window"] == \
        pytest.approx(case_post["gamma_paper"] / case_post["gamma"], rel=1e-12)
    table = pd.read_csv(tmp_path / "out" / "results.csv")
    assert r["gamma_case"] == table.gamma.iloc[0]
    assert len(r["gamma_window_per_time"]) == 3
    assert abs(r["gamma_window"] / r["gamma_case"] - 1) > 0.01
    assert json.loads((case / "window.json").read_text()) == r
    assert (case / "window" / "thermal.h5").exists()
    capsys.readouterr()
    assert main([str(case)]) == 0                       # kept: printed from window.json
    assert f"{r['gamma_window']:.4g}" in capsys.readouterr().out
    # the comparison figure of docs/campaign.md reads the campaign and its window fits
    from tdem_post.paper_compare import plot
    plot(tmp_path / "out", tmp_path / "cmp.png", diag_out=None)
    assert (tmp_path / "cmp.png").stat().st_size > 10_000
