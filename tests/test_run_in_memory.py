"""The public in-memory path (thermal_kernel.run.run_in_memory, issue 26) against the file path
(run_scene -> thermal.h5): the same scene gives the same temperatures, flows and neighbour
choice, and nothing is written; its two options do what they say."""
from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from thermal_kernel.output import read_thermal
from thermal_kernel.packing import read_packing
from thermal_kernel.run import SceneRun, run_in_memory, run_scene
from thermal_kernel.scene import SceneError, load_scene

DATA = Path(__file__).parent / "data"

SCENE = f"""packing = "{DATA / 'dense_box.h5'}"
law = "haddad"
[law_params]
ct = 0.806
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 298.15
[[boundary]]
kind = "temperature"
name = "hot"
on = "xmin"
value = 308.15
[[boundary]]
kind = "temperature"
name = "cold"
on = "xmax"
value = 298.15
"""
SOLVERS = {
    "steady": '[neighbours]\ntarget_z_with_gaps = 7.5\n[solver]\nmethod = "steady"\n',
    "implicit": '[solver]\nmethod = "implicit"\nend_time = 0.5\ndt = 0.01\ntheta = 0.5\n'
                'output_times = [0.1, 0.25, 0.5]\n',
    "explicit": '[solver]\nmethod = "explicit"\nend_time = 0.2\noutput_times = [0.05, 0.2]\n',
}


def _scene(tmp_path, method):
    path = tmp_path / f"{method}.toml"
    path.write_text(SCENE + SOLVERS[method])
    return load_scene(path, out_dir=tmp_path / "out" / method)


@pytest.mark.parametrize("method", sorted(SOLVERS))
def test_in_memory_equals_the_file(tmp_path, method):
    scene = _scene(tmp_path, method)
    mem = run_in_memory(scene)
    assert isinstance(mem, SceneRun)
    assert not scene.output.exists()                     # nothing written
    written = run_scene(scene, quiet=True, threads=1)
    run = read_thermal(written.output)
    # the same numbers, bit for bit: the file's temperatures and the in-memory ones
    assert np.array_equal(mem.result.temperature_k, run.temperature)
    assert np.array_equal(mem.result.times, run.times)
    assert np.array_equal(mem.initial_temperature_k, run.initial_temperature)
    with h5py.File(written.output, "r") as f:
        assert np.array_equal(mem.result.boundary_heat_flow_w, f["boundary_heat_flow"][()])
        assert f.attrs["flags"] == ",".join(mem.result.flags)
        neighbours = json.loads(f.attrs["neighbours"])
        assert int(f.attrs["n_conducting_contacts"]) == mem.network.n_active_contacts
    assert np.array_equal(mem.final_temperature_k, written.run.final_temperature_k)
    assert mem.law_params == run.law_params
    if method == "steady":       # the criterion applied: its gap kept, fewer rows conduct
        assert mem.neighbours is not None and neighbours["gap"] == mem.neighbours.gap
        assert mem.network.n_active_contacts < mem.packing.n_contacts
    else:
        assert mem.neighbours is None and neighbours is None
    assert mem.result.boundary_names == ("hot", "cold")


def test_start_and_conductance_factor(tmp_path):
    scene = _scene(tmp_path, "steady")
    packing = read_packing(scene.packing)          # a packing already in memory
    base = run_in_memory(scene, packing)
    # a uniform factor scales every flow and leaves the held-face steady field as it is
    double = run_in_memory(scene, packing, conductance_factor=np.full(packing.n_contacts, 2.0))
    np.testing.assert_allclose(double.result.boundary_heat_flow_w,
                               2.0 * base.result.boundary_heat_flow_w, rtol=1e-9)
    np.testing.assert_allclose(double.final_temperature_k, base.final_temperature_k,
                               rtol=0, atol=1e-9)
    # the start: what the steady solve's untied particles (rattlers) keep
    untied = ~base.network.clusters.tied_particle
    assert untied.any()
    warm = run_in_memory(scene, packing, initial_temperature_k=303.15)
    assert np.all(warm.initial_temperature_k == 303.15)
    np.testing.assert_allclose(warm.final_temperature_k[untied], 303.15, atol=1e-9)
    np.testing.assert_allclose(base.final_temperature_k[untied], 298.15, atol=1e-9)
    tied = ~untied
    assert np.array_equal(warm.final_temperature_k[tied], base.final_temperature_k[tied])
    assert np.array_equal(warm.conducting, base.conducting)


def test_start_state_continues_a_run(tmp_path):
    """A Rannacher run continued from its first output time's state (start_state, the scene's
    later output times) equals the whole run bit for bit: temperatures, flows, ledger and steps
    (the start-up steps are not repeated); the checks judge it from the ledger's start. A steady
    scene, or a start given twice, is refused."""
    def scene(times, name):
        path = tmp_path / f"{name}.toml"
        path.write_text(SCENE + '[solver]\nmethod = "implicit"\nscheme = "rannacher"\n'
                        f'end_time = {times[-1]!r}\ndt = 0.01\noutput_times = {list(times)!r}\n')
        return load_scene(path, out_dir=tmp_path / name)
    packing = read_packing(DATA / "dense_box.h5")
    whole = run_in_memory(scene([0.1, 0.25, 0.5], "whole"), packing)
    first = run_in_memory(scene([0.1], "first"), packing)
    rest = run_in_memory(scene([0.25, 0.5], "rest"), packing, start_state=first.result.state)
    assert np.array_equal(np.vstack([first.result.temperature_k, rest.result.temperature_k]),
                          whole.result.temperature_k)
    for key in ("boundary_heat_flow_w", "boundary_energy_j", "stored_energy_j"):
        assert np.array_equal(getattr(rest.result, key), getattr(whole.result, key)[1:])
    assert first.result.steps + rest.result.steps == whole.result.steps
    assert np.array_equal(rest.initial_temperature_k, whole.initial_temperature_k)
    assert rest.result.flags == whole.result.flags
    with pytest.raises(SceneError, match="start_state"):
        run_in_memory(_scene(tmp_path, "steady"), packing, start_state=first.result.state)
    with pytest.raises(SceneError, match="start_state"):
        run_in_memory(scene([0.25, 0.5], "rest"), packing, start_state=first.result.state,
                      initial_temperature_k=300.0)
