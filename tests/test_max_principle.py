"""Every run checks the maximum principle and the energy ledger (thermal_kernel.solvers.
check_physics, called by thermal_kernel.run.run_scene) and flags a violation in thermal.h5's
`flags` attribute and in one line on stderr.

Asserted: plain Crank-Nicolson on the stiff 300-sphere bed (dt = 5 s, ~50x the fastest time
constant) is flagged, with the temperature, particle and time in the line; the default
second-order scheme and backward Euler on the same case are not; a run with a heat source is
not checked for the maximum principle; a result whose ledger does not close is flagged; the
check's bounds are exactly the range of the initial and boundary temperatures."""
import dataclasses
from pathlib import Path

import h5py
import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL
from thermal_kernel.network import assemble, make_problem
from thermal_kernel.run import run_scene
from thermal_kernel.scene import load_scene
from thermal_kernel.solvers import MAX_PRINCIPLE_RTOL, check_physics, run_implicit

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

BED = Path(__file__).parent / "data" / "bed_small_4.05e+07Pa.h5"


def run(tmp_path, solver, name="s"):
    scene = tmp_path / f"{name}.toml"
    scene.write_text(f'packing = "{BED}"\nlaw = "pipe"\n' + BED_THERMAL + "[solver]\n"
                     'method = "implicit"\ndt = 5.0\nend_time = 5.0\n' + solver)
    summary = run_scene(load_scene(scene, out_dir=tmp_path / name), quiet=True)
    with h5py.File(summary.output) as f:
        attrs = dict(f.attrs)
        T = f["temperature"][()]
    return summary, attrs, T


def test_ringing_crank_nicolson_is_flagged_in_the_file_and_on_the_terminal(tmp_path, capfd):
    summary, attrs, T = run(tmp_path, 'theta = 0.5\nscheme = "theta"\n')
    assert T.max() > 500.0 + 0.3 * 200.0                      # it does ring (595.6 K)
    assert "max_principle" in attrs["flags"].split(",")
    assert "max_principle" in summary.result.flags
    assert attrs["max_principle_checked"] == 1
    np.testing.assert_array_equal(attrs["max_principle_bounds_k"], [300.0, 500.0])
    assert attrs["max_principle_excess_relative"] == pytest.approx((T.max() - 500.0) / 200.0)
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("tdem: warning")]
    assert len(lines) == 1
    p = int(np.argmax(T[-1]))
    assert f"particle {p}" in lines[0] and f"T = {T.max():.6g} K" in lines[0]
    assert "energy_ledger" not in attrs["flags"]               # its ledger closes


@pytest.mark.parametrize("solver", ['theta = 0.5\n', 'theta = 1.0\n'])
def test_default_scheme_and_backward_euler_are_not_flagged(tmp_path, capfd, solver):
    summary, attrs, T = run(tmp_path, solver)
    assert T.min() >= 300.0 and T.max() <= 500.0 + MAX_PRINCIPLE_RTOL * 200.0
    assert "max_principle" not in attrs["flags"] and "energy_ledger" not in attrs["flags"]
    assert attrs["max_principle_checked"] == 1
    assert attrs["ledger_residual_relative"] < 1e-9
    assert "tdem: warning" not in capfd.readouterr().err


def small_problem(source=None, power=()):
    c = np.array([1.0, 2.0, 1.5, 1.0])
    pair = np.array([[0, 1], [1, 2], [2, 3]])
    h = np.array([1.0, 0.5, 2.0])
    return make_problem(c, pair, h, fixed=([0], [400.0], [0]), power=power, source=source,
                        boundary_names=("hot", "heater"))


def test_check_bounds_source_and_ledger():
    net = assemble(small_problem())
    T0 = np.array([350.0, 320.0, 310.0, 330.0])
    r = run_implicit(net, T0, [10.0, 20.0], dt=20.0, theta=0.5)   # one plain CN step: rings
    c = check_physics(net, T0, r)
    assert c.bounds_k == (310.0, 400.0)                       # initial 310..350, held 400
    excess = max(r.temperature_k.max() - 400.0, 310.0 - r.temperature_k.min(), 0.0) / 90.0
    assert c.overshoot_relative == pytest.approx(excess)
    assert excess > 0.1 and "max_principle" in c.flags       # measured 0.18 of the span
    good = run_implicit(net, T0, [10.0, 20.0], dt=20.0, theta=1.0)
    assert check_physics(net, T0, good).flags == ()
    # a ledger that does not close (1 J of stored energy from nowhere) is flagged
    bad = dataclasses.replace(good, stored_energy_j=good.stored_energy_j + 1.0)
    assert check_physics(net, T0, bad).flags == ("energy_ledger",)
    # with power injected the maximum principle does not apply: not checked
    net_p = assemble(small_problem(power=([3], [5.0], [1])))
    hot = run_implicit(net_p, T0, [50.0], dt=1.0, theta=1.0)
    assert hot.temperature_k.max() > 400.0
    c = check_physics(net_p, T0, hot)
    assert not c.max_principle_checked and c.flags == ()
