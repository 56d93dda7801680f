"""One effective conductivity (thermal_kernel.effective, issue 17 sec. 3): k_eff = |Q_in| L /
(A |dT|) from one steady solve, heat in = heat out refused above BALANCE_TOLERANCE, the length
convention stated. Checks:
- a chain of n particles joined by n-1 equal conductances H between two held ends: Q = H dT /
  (n-1), the series formula, to 1e-12 (round-off of the direct solve);
- a third boundary that takes heat (a flux boundary) breaks the balance: refused in one line,
  from the function and from `tdem post` (exit 2);
- post states "held_centres" and calibrate / the ETC sweep "domain", with their own L."""
import math

import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main
from thermal_kernel.effective import (BALANCE_TOLERANCE, LENGTH_CONVENTIONS, BalanceError,
                                      effective_conductivity)
from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.network import assemble, make_problem
from thermal_kernel.packing import write_packing

PITCH, DELTA = 4e-3, 4e-6
RADIUS = (PITCH + DELTA) / 2


def _chain(n=6, h=2.0, leak=0.0):
    """n particles in a line, H = h between neighbours, 0 held at 400 K, n-1 at 300 K; with
    ``leak`` W drawn out of the middle particle (a third boundary)."""
    pair = np.array([(i, i + 1) for i in range(n - 1)])
    power = ((np.array([n // 2]), np.array([-leak]), np.array([2])) if leak else ())
    prob = make_problem(np.ones(n), pair, np.full(n - 1, h),
                        fixed=(np.array([0, n - 1]), np.array([400.0, 300.0]),
                               np.array([0, 1])), power=power,
                        boundary_names=("hot", "cold", "leak") if leak else ("hot", "cold"))
    return assemble(prob)


def test_a_chain_gives_the_series_conductance():
    n, h = 6, 2.0
    r = effective_conductivity(_chain(n, h), "hot", "cold", t_in=400.0, t_out=300.0,
                               length_m=0.5, area_m2=0.25, length_convention="domain",
                               initial_k=np.full(n, 350.0), where="chain")
    q = h / (n - 1) * 100.0                       # series: (n-1) conductances H
    assert r.q_in_w == pytest.approx(q, rel=1e-12) and r.q_out_w == pytest.approx(-q, rel=1e-12)
    assert r.k_eff_w_mk == pytest.approx(q * 0.5 / (0.25 * 100.0), rel=1e-12)
    assert r.balance <= 1e-12 and r.delta_t_k == 100.0 and r.length_convention == "domain"
    assert r.n_rattlers == 0 and r.n_floating_clusters == 0
    np.testing.assert_allclose(r.temperature_k, np.linspace(400, 300, n), rtol=1e-12)
    # the hot and cold ends swapped: the same k_eff (|Q|, |dT|)
    s = effective_conductivity(_chain(n, h), "cold", "hot", t_in=300.0, t_out=400.0,
                               length_m=0.5, area_m2=0.25, length_convention="held_centres",
                               initial_k=np.full(n, 350.0))
    assert s.k_eff_w_mk == r.k_eff_w_mk and s.q_in_w == r.q_out_w


def test_an_unbalanced_heat_flow_is_refused_in_one_line():
    net = _chain(leak=0.05)                       # 0.4 W flows in, 0.05 W of it leaks
    with pytest.raises(BalanceError) as e:
        effective_conductivity(net, "hot", "cold", t_in=400.0, t_out=300.0, length_m=1.0,
                               area_m2=1.0, length_convention="domain",
                               initial_k=np.full(6, 350.0), where="chain.toml")
    msg = str(e.value)
    assert msg.startswith("chain.toml: steady heat balance: ") and "\n" not in msg
    assert f"expected at most {BALANCE_TOLERANCE:g}" in msg
    # below the tolerance passes: a leak of 1e-9 of the flow
    r = effective_conductivity(_chain(leak=0.4e-9), "hot", "cold", t_in=400.0, t_out=300.0,
                               length_m=1.0, area_m2=1.0, length_convention="domain",
                               initial_k=np.full(6, 350.0))
    assert 0 < r.balance < BALANCE_TOLERANCE
    with pytest.raises(ValueError, match="length_convention"):
        effective_conductivity(_chain(), "hot", "cold", t_in=400.0, t_out=300.0, length_m=1.0,
                               area_m2=1.0, length_convention="walls", initial_k=350.0)


def _lattice_scene(tmp_path, extra=""):
    write_packing(tmp_path / "lattice.h5", simple_cubic_packing(
        (3, 3, 9), spacing_m=PITCH, radius_m=RADIUS, young_pa=5e10, poisson=0.2))
    scene = tmp_path / "steady.toml"
    scene.write_text('packing = "lattice.h5"\nlaw = "haddad"\n[law_params]\nct = 0.8\n'
                     + BED_THERMAL.replace('on = "plate"', 'on = "zmax"') + extra
                     + '[solver]\nmethod = "steady"\n')
    return scene


def test_post_refuses_a_steady_etc_that_does_not_balance(tmp_path, capsys):
    """A flux boundary on xmin draws heat out of the bed: the two held walls no longer carry
    the same heat, and the steady ETC is refused (exit 2, one line) instead of printed."""
    scene = _lattice_scene(tmp_path, '[[boundary]]\nkind = "flux"\non = "xmin"\n'
                                     'value = -2000.0\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["post", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "steady heat balance" in err and "no k_eff" in err
    assert not (tmp_path / "out" / "post" / "summary.json").exists()


def test_each_caller_states_its_length_convention(tmp_path, capsys):
    """post: the held sets' centre planes (8 pitches on 9 layers); calibrate's flux test: the
    domain's extent (9 pitches); both the lattice's closed form for their own L."""
    from tdem_post.post_run import analyse
    from thermal_kernel.calibrate import flux_test
    from thermal_kernel.packing import read_packing
    from thermal_kernel.scene import load_scene
    scene = _lattice_scene(tmp_path)
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    r = analyse(tmp_path / "out" / "thermal.h5")
    h = 205.0 * 0.8 * math.pi * RADIUS ** 2 / PITCH
    assert r.steady.length_convention == "held_centres" in LENGTH_CONVENTIONS
    assert r.steady.length_m == pytest.approx(8 * PITCH, rel=1e-12)
    assert r.gamma_steady == pytest.approx(h / (PITCH * 205.0), rel=1e-9)
    test = flux_test(load_scene(scene), read_packing(tmp_path / "lattice.h5"), "z")
    assert test.effective.length_convention == "domain"
    packing = read_packing(tmp_path / "lattice.h5")
    assert test.length_m == float(packing.domain_hi[2] - packing.domain_lo[2])
    # 8 contacts in series over the domain's 9 pitches (+ the radii beyond the end centres)
    assert test.effective_w_mk == pytest.approx(h / 8 * test.length_m / test.area_m2 * 9,
                                                rel=1e-9)
    assert test.effective_w_mk == test.effective.k_eff_w_mk
