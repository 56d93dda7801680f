"""The PETSc backend (issue 25): `tdem run SCENE --ranks N` gives the in-process answer.

Each case runs a scene in-process (tdem's numba / scipy solvers) and on MPI ranks through PETSc
(`thermal_kernel/solvers/petsc_backend.py`, under mpirun in .venv-mpi) and compares the two
thermal.h5 files: explicit within 1e-12 of the temperature change (the same updates summed in
another order), implicit and steady within 1e-10 (CG to a relative residual of 1e-12), the
boundary heat flows and ledger energies alike, and the flags identical; 1, 2 and 3 ranks agree.
The scenes: the 300-sphere YADE bed between two held walls (with rattlers), and the 400-sphere
dense box with every row kind the solvers see -- held particles, exchange rows (a wall
temperature), constant power (a flux) and a moving source switched on and off mid-run.

What could fail: a row of the matrix given to the wrong rank or renumbered wrongly (every
temperature off), a held particle not eliminated (the implicit matrix not SPD, or held
temperatures drifting), the ledger's partial sums counted twice or missed on a rank, the source
added on one rank only, a flag lost in the output.
"""
import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main
from thermal_kernel.solvers.mpi_launch import missing

DATA = Path(__file__).resolve().parent / "data"
BED = DATA / "bed_small_4.05e+07Pa.h5"
DENSE = DATA / "dense_box.h5"
WHY = missing()

# slow, the whole module (issue 25): each case runs mpirun (1-3 ranks of .venv-mpi, ~1.5 s to
# start); ~100 s in all (22 tests, 2026-12-02, load ~5; 27 since the validation cases on ranks,
# ~55 s at load ~3)
pytestmark = [pytest.mark.petsc, pytest.mark.slow,
              pytest.mark.skipif(WHY is not None, reason=f"PETSc backend unavailable: {WHY} "
                                 "(Debian: apt-get install python3-petsc4py python3-mpi4py "
                                 "openmpi-bin; `make test` installs them and builds .venv-mpi)")]

TIMES = "end_time = 2.0\noutput_times = [0.5, 1.0, 2.0]\n"
SOLVERS = {
    "steady": 'method = "steady"\n',
    "explicit": 'method = "explicit"\n' + TIMES,
    "backward_euler": 'method = "implicit"\n' + TIMES + "dt = 0.02\n",
    "rannacher": 'method = "implicit"\n' + TIMES + "dt = 0.1\ntheta = 0.5\n",
    "tr_bdf2": 'method = "implicit"\n' + TIMES + 'dt = 0.1\ntheta = 0.5\nscheme = "tr-bdf2"\n',
}
# relative to the largest temperature change (explicit: the same sums in another order;
# implicit, steady: CG to 1e-12 relative residual against a direct solve in-process)
RTOL = {"steady": 1e-10, "explicit": 1e-12, "backward_euler": 1e-10, "rannacher": 1e-10,
        "tr_bdf2": 1e-10}

DENSE_ROWS = f'''packing = "{DENSE}"
law = "haddad"
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[material.1]
conductivity = 165.0
[initial]
temperature = 298.15
[[boundary]]
kind = "temperature"
on = "xmin"
value = 308.15
[[boundary]]
kind = "wall_temperature"
on = "xmax"
value = 290.0
wall_conductivity = 20.0
[[boundary]]
kind = "flux"
on = "ymin"
value = 2000.0
[[boundary]]
kind = "source"
shape = "sphere"
value = 1e7
radius_m = 0.003
centre_m = [0.004, 0.0075, 0.0075]
velocity_m_s = [0.002, 0, 0]
start_time = 0.2
stop_time = 1.4
'''
DENSE_TIMES = "end_time = 2.0\noutput_times = [0.5, 1.0, 2.0]\n"
# the dense box's [neighbours] criterion (issue 23): the gap giving bulk Z 7 (every dumped row:
# 8.10, 163 bulk particles); 1 mean diameter from the faces
NEIGHBOURS_Z = "[neighbours]\ntarget_z_with_gaps = 7.0\nbulk_margin_diameters = 1.0\n"


def _with_neighbours(rows, law, table):
    """A scene's rows with another law and a [neighbours] table."""
    return rows.replace('law = "haddad"\n', f'law = "{law}"\n{table}', 1)


def _scene(tmp_path, name, text):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _run(scene, out, ranks=None):
    args = ["run", str(scene), "--out", str(out), "--quiet"]
    if ranks is not None:
        args += ["--ranks", str(ranks)]
    assert main(args) == 0
    return _read(out / "thermal.h5")


def _read(path):
    with h5py.File(path, "r") as f:
        return {"T": f["temperature"][:], "T0": f["initial_temperature"][:],
                "capacity": f["capacity"][:],
                "flow": f["boundary_heat_flow"][:], "energy": f["boundary_energy"][:],
                "source": f["source_energy"][:], "attrs": dict(f.attrs)}


def _assert_same(a, b, rtol):
    change = max(float(np.abs(a["T"] - a["T0"][None, :]).max()), 1e-300)
    assert np.abs(a["T"] - b["T"]).max() <= rtol * change
    scale = max(float(np.abs(a["flow"]).max()), 1e-300)
    assert np.abs(a["flow"] - b["flow"]).max() <= max(rtol, 1e-9) * scale
    if a["energy"].size:
        scale = max(float(np.abs(a["energy"]).max()), 1e-300)
        assert np.abs(a["energy"] - b["energy"]).max() <= max(rtol, 1e-9) * scale
        np.testing.assert_allclose(a["source"], b["source"], rtol=1e-12, atol=0)
    for key in ("flags", "max_principle_checked", "method", "steps", "n_conducting_contacts",
                "n_floating_clusters", "n_rattlers", "packing_sha256", "scene", "law_params"):
        assert a["attrs"][key] == b["attrs"][key], key
    assert b["attrs"]["backend"] == "petsc"
    # the capacities gathered from the ranks, and the maximum principle's bounds from the
    # extremes and rates of the network (exact operations: the same numbers)
    np.testing.assert_array_equal(a["capacity"], b["capacity"])
    np.testing.assert_array_equal(a["attrs"]["max_principle_bounds_k"],
                                  b["attrs"]["max_principle_bounds_k"])


@pytest.fixture(scope="module")
def bed_runs(tmp_path_factory):
    """Each solver on the bed, in-process and on 2 ranks."""
    tmp = tmp_path_factory.mktemp("petsc_bed")
    runs = {}
    for name, solver in SOLVERS.items():
        scene = _scene(tmp, name, f'packing = "{BED}"\nlaw = "pipe"\n{BED_THERMAL}'
                                  f"[solver]\n{solver}")
        runs[name] = (scene, _run(scene, tmp / f"{name}_in"),
                      _run(scene, tmp / f"{name}_r2", ranks=2))
    return tmp, runs


@pytest.mark.parametrize("name", list(SOLVERS))
def test_two_ranks_give_the_in_process_answer(bed_runs, name):
    _, runs = bed_runs
    _, inproc, petsc = runs[name]
    _assert_same(inproc, petsc, RTOL[name])
    assert petsc["attrs"]["ranks"] == 2
    # the physics checks of the output, as in-process: the run conserves energy and keeps to
    # the maximum principle (the bed has no source or power: the plain principle is checked)
    assert petsc["attrs"]["ledger_residual_relative"] <= 1e-9
    assert petsc["attrs"]["max_principle_checked"] == 1
    assert "max_principle" not in petsc["attrs"]["flags"]


def test_the_output_has_every_attribute_of_an_in_process_run(bed_runs):
    _, runs = bed_runs
    for _, inproc, petsc in runs.values():
        assert set(inproc["attrs"]) <= set(petsc["attrs"])
        assert set(petsc["attrs"]) - set(inproc["attrs"]) == {
            "backend", "ranks", "cut_contacts", "linear_solver", "run_seconds"}


@pytest.mark.parametrize("name", ["steady", "explicit"])
def test_one_two_and_three_ranks_agree(bed_runs, name):
    tmp, runs = bed_runs
    scene, inproc, two = runs[name]
    for ranks in (1, 3):
        other = _run(scene, tmp / f"{name}_r{ranks}", ranks=ranks)
        _assert_same(inproc, other, RTOL[name])
        _assert_same(two, other, RTOL[name])


@pytest.mark.parametrize("name,solver,rtol", [
    ("explicit", 'method = "explicit"\n' + DENSE_TIMES, 1e-12),
    ("tr_bdf2", 'method = "implicit"\n' + DENSE_TIMES + 'dt = 0.05\nscheme = "tr-bdf2"\n'
     'theta = 0.5\n', 1e-10),
])
def test_exchange_power_and_a_moving_source_on_two_ranks(tmp_path, name, solver, rtol):
    scene = _scene(tmp_path, name, DENSE_ROWS + f"[solver]\n{solver}")
    inproc = _run(scene, tmp_path / "in")
    petsc = _run(scene, tmp_path / "r2", ranks=2)
    _assert_same(inproc, petsc, rtol)
    assert inproc["source"][-1] > 0          # the source did heat the box
    assert petsc["attrs"]["ledger_residual_relative"] <= 1e-9


def test_a_bad_scene_on_the_ranks_is_one_line_and_exit_2(tmp_path, capsys):
    scene = _scene(tmp_path, "bad", f'packing = "{BED}"\nlaw = "pipe"\nlaw_params = {{ct = 1}}\n'
                                    f'{BED_THERMAL}[solver]\nmethod = "steady"\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--ranks", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"tdem: error: {scene}: law_params.ct: unknown parameter of law 'pipe' "
                   "(known: none)"]
    assert not (tmp_path / "o" / "thermal.h5").exists()


# the boundary kinds run on each rank's particles (rank_build.py: RanksWhole): each refusal
# that depends on every particle (a count, a flag, the phases present, the lowest particle)
BAD_BOUNDARIES = {
    "held twice": '[[boundary]]\nkind = "temperature"\non = "xmin"\nvalue = 300.0\n'
                  'name = "again"\n',
    "flux on held": '[[boundary]]\nkind = "flux"\non = "xmin"\nvalue = 10.0\n',
    "no such phase": '[[boundary]]\nkind = "phase_temperature"\nphase = 7\nvalue = 300.0\n',
}


@pytest.mark.parametrize("case", [*BAD_BOUNDARIES, "source away", "capacity"])
def test_a_boundary_refused_on_the_ranks_is_the_in_process_line(tmp_path, capsys, case):
    """Each rank runs the boundary kinds on its own particles: a refusal that depends on
    every particle -- every particle of a face already held (the boundary named by the lowest
    particle), no particle of a phase (the phases present, over every rank), a source that
    reaches no centre, a capacity out of range (counted over every rank, the lowest particle
    named) -- is on 3 ranks the in-process run's one line, exit 2, no output. What could fail:
    a rank's own count or first particle in the message, a rank raising alone (a hang)."""
    text = DENSE_ROWS + BAD_BOUNDARIES.get(case, "")
    if case == "capacity":
        text = text.replace("[material.1]\n", "[material.1]\ndensity = 1e-320\n", 1)
    if case == "source away":
        text = text.replace("centre_m = [0.004, 0.0075, 0.0075]", "centre_m = [0.5, 0.5, 0.5]")
    scene = _scene(tmp_path, "bad", text + '[solver]\nmethod = "steady"\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "i")]) == 2
    inproc = capsys.readouterr().err.strip().splitlines()
    assert len(inproc) == 1 and inproc[0].startswith(f"tdem: error: {scene}: "), inproc
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--ranks", "3"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == inproc
    assert not (tmp_path / "o" / "thermal.h5").exists()


def test_fewer_particles_than_ranks_give_the_in_process_answer(tmp_path):
    """A chain of 3 spheres on 4 ranks (one rank's block empty: it reads no particle, holds no
    contact, runs the boundary kinds on none and still joins every reduction): a held face
    and a flux (its r^2 shares summed over the ranks) give the in-process steady
    temperatures, which are the chain's series solution: T_k = T_0 + k q A / H, H the pipe
    law's equal conductances."""
    from thermal_kernel.packing import Packing, write_packing
    r = np.full(3, 1e-3)
    x = np.array([[1e-3, 5e-3, 5e-3], [2.9e-3, 5e-3, 5e-3], [4.8e-3, 5e-3, 5e-3]])
    pair = np.array([[0, 1], [1, 2]])
    branch = x[pair[:, 1]] - x[pair[:, 0]]
    overlap = 2e-3 - np.linalg.norm(branch, axis=1)
    lo, hi = np.zeros(3), np.array([5.8e-3, 1e-2, 1e-2])
    write_packing(tmp_path / "chain.h5", Packing(
        position=x, radius=r, phase=np.zeros(3, np.int32), pair=pair, overlap=overlap,
        normal_force=overlap * 1e6, branch=branch, domain_lo=lo, domain_hi=hi,
        attrs=dict(generator="test", seed=0, solid_fraction=float(
            np.sum(4 / 3 * np.pi * r ** 3) / np.prod(hi - lo)), mean_coordination=4 / 3,
            pressure_pa=float("nan"), young_pa=1e9, poisson=0.3, density=2500.0)))
    scene = _scene(tmp_path, "chain", f'packing = "{tmp_path / "chain.h5"}"\nlaw = "pipe"\n'
                   '[material]\nconductivity = 10.0\ndensity = 2500.0\nheat_capacity = 800.0\n'
                   '[initial]\ntemperature = 300.0\n[[boundary]]\nkind = "temperature"\n'
                   'on = "xmin"\nvalue = 400.0\n[[boundary]]\nkind = "flux"\non = "xmax"\n'
                   'value = 1000.0\n[solver]\nmethod = "steady"\n')
    inproc = _run(scene, tmp_path / "in")
    petsc = _run(scene, tmp_path / "r4", ranks=4)
    _assert_same(inproc, petsc, RTOL["steady"])
    from thermal_kernel.packing import read_packing
    from thermal_kernel.problem import build_problem
    from thermal_kernel.scene import load_scene
    h = build_problem(load_scene(scene), read_packing(tmp_path / "chain.h5"))[0].conductance_w_k
    assert h[0] == h[1] > 0
    t = petsc["T"][-1]
    np.testing.assert_allclose(t - 400.0, np.arange(3) * 1000.0 * 1e-2 * 1e-2 / h[0],
                               rtol=1e-10)


# ------------------------------------------------------------------ the per-rank build
def test_the_morton_order_sorted_on_the_ranks_is_the_whole_sort():
    """thermal_kernel/solvers/partition.py on 1-4 ranks (tests/mpi_partition_check.py, under
    mpirun): the Morton order sorted on the ranks (a sample sort, no rank holding every key)
    equals morton_order of every centre, and the routes between the ranks' blocks and the
    file's order (places, gather on rank 0, scatter from it, to and from the directories)
    equal indexing with the whole order; on ties (equal keys across ranks), a flat axis, a
    cluster in one corner and fewer particles than ranks. What could fail: a tie split in
    index order the wrong way at a splitter, a bounding box reduced otherwise than the whole
    one (other keys), a block one row off after the rebalance, an empty rank."""
    import subprocess

    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    check = Path(__file__).resolve().parent / "mpi_partition_check.py"
    for ranks in (1, 2, 3, 4):
        done = subprocess.run(["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, str(mpi_python()),
                               str(check)], env=mpi_env(), capture_output=True, text=True)
        assert done.returncode == 0, (ranks, done.stdout[-3000:], done.stderr[-3000:])
        assert f"partition OK {ranks}" in done.stdout, (ranks, done.stdout[-3000:])


def test_the_steady_solve_on_the_ranks_fills_floating_clusters_as_in_process():
    """The steady solve on 1-3 ranks with rank 0 holding only the network's summary and its
    untied particles (tests/mpi_steady_check.py, under mpirun): floating clusters and rattlers
    spread over the ranks' blocks, with a zero-net power, a net power and a powered rattler,
    give the in-process temperatures (the untied ones within 1e-12 of the span), the same
    no-steady-state list and flags, the flows and the stored energy. What could fail: the
    untied particles' powers gathered in another order, the stored energy counting them twice
    or not at all, a flow through an untied particle."""
    import subprocess

    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    check = Path(__file__).resolve().parent / "mpi_steady_check.py"
    for ranks in (1, 2, 3):
        done = subprocess.run(["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, str(mpi_python()),
                               str(check)], env=mpi_env(), capture_output=True, text=True)
        assert done.returncode == 0, (ranks, done.stdout[-3000:], done.stderr[-3000:])
        assert f"steady OK {ranks}" in done.stdout, (ranks, done.stdout[-3000:])


@pytest.mark.parametrize("ranks", [2, 3])
def test_each_rank_builds_its_own_rows_as_the_whole_build_does(tmp_path, ranks):
    """thermal_kernel/rank_build.py against the whole build on rank 0 (tests/
    mpi_rank_build_check.py, under mpirun): each rank's rows of the matrix and of the boundary
    terms, rank 0's network (degrees, clusters, bounds, flags, the held rows) bit for bit, and
    the steady temperatures within 1e-12 of the change, on the bed (rattlers), the dense box
    (every row kind) and the dense box with a ``[neighbours]`` criterion (the gap chosen for a
    bulk Z with collectives over the ranks' slices: the gap, rows kept and bulk Z's equal to the
    whole build's bit for bit; the terreros law, which reads the kept rows' neighbour counts).
    Since the build reads per rank, no rank holds the whole packing.
    What could fail: a contact lost or counted twice between the slices and the owners, the
    law given other neighbour counts, a diagonal summed in another order, clusters numbered
    otherwise than in-process, a gap one ulp off or a tie split between ranks."""
    import subprocess

    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    check = Path(__file__).resolve().parent / "mpi_rank_build_check.py"
    steady = '[solver]\nmethod = "steady"\n'
    for name, text in (("bed", f'packing = "{BED}"\nlaw = "pipe"\n{BED_THERMAL}{steady}'),
                       ("dense", DENSE_ROWS + steady),
                       ("neighbours", _with_neighbours(DENSE_ROWS, "terreros",
                                                       NEIGHBOURS_Z) + steady)):
        scene = _scene(tmp_path, name, text)
        done = subprocess.run(["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, str(mpi_python()),
                               str(check), str(scene)], env=mpi_env(), capture_output=True,
                              text=True, cwd=tmp_path)
        assert done.returncode == 0, (name, done.stdout[-3000:], done.stderr[-3000:])
        assert f"rank_build OK {ranks} " in done.stdout, (name, done.stdout[-3000:])


def test_the_whole_build_on_rank_0_gives_the_same_temperatures(bed_runs):
    """mpi_run --whole-build (rank 0 builds the whole network and sends the rows): the same
    matrix as the per-rank build, so the same steady temperatures (to round-off: PETSc's
    reductions need not sum in the same order from one run to the next)."""
    import subprocess

    from thermal_kernel.solvers.mpi_launch import command, mpi_env
    tmp, runs = bed_runs
    scene, _, per_rank = runs["steady"]
    out = tmp / "steady_whole_r2"
    cmd = command(scene, 2, out=out, quiet=True) + ["--whole-build"]
    subprocess.run(cmd, env=mpi_env(), check=True, cwd=tmp)
    whole = _read(out / "thermal.h5")
    change = float(np.abs(per_rank["T"] - per_rank["T0"][None, :]).max())
    assert np.abs(whole["T"] - per_rank["T"]).max() <= 1e-12 * change
    assert whole["attrs"]["cut_contacts"] == per_rank["attrs"]["cut_contacts"]


def test_a_neighbours_scene_runs_on_the_ranks_as_in_process(tmp_path, capsys):
    """``tdem run --ranks 2`` of a [neighbours] scene (built on the ranks: mpi_run has no
    whole-build case for it any more): thermal.h5's ``neighbours`` attribute (the gap, rows
    kept, bulk Z's, as JSON) is the in-process run's string, the steady temperatures within
    the solver tolerance; a target above what the dump holds is the in-process one line,
    exit 2."""
    steady = '[solver]\nmethod = "steady"\n'
    scene = _scene(tmp_path, "nb", _with_neighbours(DENSE_ROWS, "haddad", NEIGHBOURS_Z) + steady)
    inproc = _run(scene, tmp_path / "in")
    petsc = _run(scene, tmp_path / "r2", ranks=2)
    _assert_same(inproc, petsc, RTOL["steady"])
    assert petsc["attrs"]["neighbours"] == inproc["attrs"]["neighbours"]
    chosen = json.loads(petsc["attrs"]["neighbours"])
    assert chosen["mode"] == "target_z_with_gaps" and chosen["n_kept"] < chosen["n_dumped"]
    bad = _scene(tmp_path, "bad", _with_neighbours(
        DENSE_ROWS, "haddad", NEIGHBOURS_Z.replace("7.0", "9.5")) + steady)
    capsys.readouterr()
    assert main(["run", str(bad), "--out", str(tmp_path / "o"), "--ranks", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "neighbours.target_z_with_gaps: 9.5 is above the bulk Z" in err[0]
    assert main(["run", str(bad), "--out", str(tmp_path / "i")]) == 2     # in-process: alike
    assert capsys.readouterr().err.strip().splitlines() == err
    assert not (tmp_path / "o" / "thermal.h5").exists()


def test_a_bad_contact_row_read_by_the_last_rank_is_one_line(tmp_path, capsys):
    """The last rank reads the last contact rows: a tensile force there is rank 0's one line
    (the file, the field, the file's row), exit 2, as the in-process reader says it."""
    import shutil
    bad = tmp_path / "bad.h5"
    shutil.copy(DENSE, bad)
    with h5py.File(bad, "r+") as f:
        m = f["contacts/normal_force"].shape[0]
        f["contacts/normal_force"][m - 1] = -1.0
    scene = _scene(tmp_path, "s", DENSE_ROWS.replace(str(DENSE), str(bad))
                   + '[solver]\nmethod = "steady"\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--ranks", "3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"tdem: error: {bad}: contacts/normal_force: contact {m - 1} has a tensile "
                   "(negative) force -1.0; expected >= 0"]
    assert main(["run", str(scene), "--out", str(tmp_path / "i")]) == 2     # in-process: alike
    assert capsys.readouterr().err.strip().splitlines() == err
    assert not (tmp_path / "o" / "thermal.h5").exists()


@pytest.mark.parametrize("extra,message", [
    (["--ranks", "0"], "tdem: error: --ranks: expected a number of MPI ranks >= 1, got 0"),
    (["--ranks", "2", "--threads", "2"],
     'tdem: error: --threads: not with the PETSc backend (--ranks, or solver.backend = '
     '"petsc"); expected an in-process run for it'),
])
def test_options_the_backend_does_not_take_are_one_line(tmp_path, capsys, extra, message):
    scene = _scene(tmp_path, "s", f'packing = "{BED}"\nlaw = "pipe"\n{BED_THERMAL}'
                                  f'[solver]\n{SOLVERS["explicit"]}')
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), *extra]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [message]


# ------------------------------------------------------------------ progress, checkpoints
def test_checkpoints_and_progress_on_two_ranks(bed_runs, capfd, name="rannacher"):
    """--checkpoint-every on the ranks: rank 0 writes the in-process checkpoint after each
    output time, the answer is the in-process one, the checkpoint is removed at the end; and
    rank 0 shows the in-process progress bar, labelled with the method."""
    tmp, runs = bed_runs
    scene, inproc, _ = runs[name]
    out = tmp / f"{name}_ck"
    assert main(["run", str(scene), "--out", str(out), "--ranks", "2",
                 "--checkpoint-every", "1"]) == 0
    _assert_same(inproc, _read(out / "thermal.h5"), RTOL[name])
    assert not (out / "thermal.checkpoint.h5").exists()
    err = capfd.readouterr().err
    assert "implicit(rannacher):" in err and "step" in err


def test_a_run_resumes_on_two_ranks_from_an_in_process_checkpoint(bed_runs, monkeypatch, capfd):
    """An in-process run stopped (Ctrl-C) after its first checkpoint resumes on 2 ranks to
    the uninterrupted in-process answer: the state, the step count (Rannacher's start-up steps
    are not taken again) and the ledger carried over."""
    import thermal_kernel.run as run_mod
    from thermal_kernel.scene import load_scene
    tmp, runs = bed_runs
    scene, inproc, _ = runs["rannacher"]
    out = tmp / "resumed"
    write = run_mod.write_checkpoint

    def write_then_stop(*args, **kw):
        write(*args, **kw)
        raise KeyboardInterrupt
    monkeypatch.setattr(run_mod, "write_checkpoint", write_then_stop)
    with pytest.raises(KeyboardInterrupt, match="checkpoint .* kept"):
        run_mod.run_scene(load_scene(scene, out_dir=out), quiet=True, checkpoint_every=1)
    ckpt = out / "thermal.checkpoint.h5"
    with h5py.File(ckpt) as f:
        assert list(f["outputs/times"][()]) == [0.5]
    capfd.readouterr()
    assert main(["run", str(scene), "--out", str(out), "--ranks", "2", "--resume",
                 "--quiet"]) == 0
    assert "resuming from" in capfd.readouterr().out
    resumed = _read(out / "thermal.h5")
    _assert_same(inproc, resumed, RTOL["rannacher"])
    assert resumed["attrs"]["ledger_residual_relative"] <= 1e-9
    assert not ckpt.exists()


# ----------------------------------------------------------------------------- campaign
CAMPAIGN = f'''[campaign]
laws = ["pipe"]
packings = ["{BED}"]
n_bins = 4
{BED_THERMAL}
[solver]
method = "implicit"
theta = 0.5
dt = 2.0
end_time = 200.0
output_times = [5.0, 10.0, 20.0, 50.0, 100.0, 200.0]
'''


def test_a_campaign_honours_the_petsc_backend(tmp_path):
    """`tdem campaign` on a scene with solver.backend = "petsc" runs its cases on the ranks
    (thermal.h5 says so) and gives the in-process campaign's temperatures, gamma and tau."""
    import json
    plain = _scene(tmp_path, "plain", CAMPAIGN)
    petsc = _scene(tmp_path, "petsc", CAMPAIGN.replace('[solver]\n',
                                                       '[solver]\nbackend = "petsc"\n'))
    sums = {}
    for name, path in (("plain", plain), ("petsc", petsc)):
        assert main(["campaign", str(path), "--out", str(tmp_path / name)]) == 0
        case = tmp_path / name / "cases" / "bed_small_4.05e+07Pa_pipe"
        sums[name] = (_read(case / "thermal.h5"),
                      json.loads((case / "post" / "summary.json").read_text()))
    (a, sa), (b, sb) = sums["plain"], sums["petsc"]
    change = float(np.abs(a["T"] - a["T0"][None, :]).max())
    assert np.abs(a["T"] - b["T"]).max() <= 1e-10 * change
    assert a["attrs"]["flags"] == b["attrs"]["flags"]
    assert "backend" not in a["attrs"] and b["attrs"]["backend"] == "petsc"
    assert b["attrs"]["ranks"] == 1
    for key in ("gamma", "gamma_steady", "tau_s"):
        assert sa[key] is not None and abs(sb[key] - sa[key]) <= 1e-8 * abs(sa[key]), key


def test_campaign_ranks_errors_are_one_line(tmp_path, capsys):
    path = _scene(tmp_path, "c", CAMPAIGN)
    assert main(["campaign", str(path), "--out", str(tmp_path / "o"), "--ranks", "0"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "tdem: error: --ranks: expected a number of MPI ranks >= 1, got 0"]
    assert main(["campaign", str(path), "--out", str(tmp_path / "o"), "--ranks", "2",
                 "--threads", "1"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "tdem: error: --threads: not with --ranks (each rank runs one thread); expected an "
        "in-process campaign for it"]
    petsc = _scene(tmp_path, "p", CAMPAIGN.replace('[solver]\n', '[solver]\nbackend = "petsc"\n'))
    assert main(["campaign", str(petsc), "--out", str(tmp_path / "o"), "--threads", "1"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f'tdem: error: {petsc}: solver.backend: "petsc" runs the cases on MPI ranks of one '
        'thread each; expected no --threads with it (or backend = "in-process")']
    assert not (tmp_path / "o").exists()


def test_a_run_on_ranks_ended_by_sigterm_keeps_the_in_process_checkpoint(tmp_path):
    """SIGTERM to `tdem run --ranks 2` after its first checkpoint: the in-process run's line
    and exit status, mpirun and the ranks ended, the lock removed, and the checkpoint rank 0
    wrote is the in-process one (state and step count of an in-process run to that time)."""
    import os
    import shutil
    import signal
    import subprocess
    import sys
    import time
    from thermal_kernel.network import assemble
    from thermal_kernel.packing import read_packing
    from thermal_kernel.problem import build_problem
    from thermal_kernel.scene import load_scene
    from thermal_kernel.solvers import run_explicit
    # ~2e5 steps: ended long before its end, after the first output time (~20 steps)
    scene = _scene(tmp_path, "s", f'packing = "{BED}"\nlaw = "pipe"\n{BED_THERMAL}[solver]\n'
                                  'method = "explicit"\nend_time = 2e4\n'
                                  'output_times = [2.0, 2e4]\n')
    out = tmp_path / "o"
    ckpt = out / "thermal.checkpoint.h5"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "run", str(scene), "--out",
                             str(out), "--ranks", "2", "--checkpoint-every", "1", "--quiet"],
                            stderr=subprocess.PIPE, text=True)
    while not ckpt.exists() and proc.poll() is None:
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGTERM)
    err = proc.communicate()[1]
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == (
        f"tdem: terminated (SIGTERM): {out / 'thermal.h5'} not written; checkpoint {ckpt} kept "
        "(--resume continues from it)")
    assert sorted(p.name for p in out.iterdir()) == ["thermal.checkpoint.h5"]   # no lock
    if shutil.which("pgrep"):                      # no rank left (their command names out)
        assert subprocess.run(["pgrep", "-f", str(out)], capture_output=True).returncode == 1
    s = load_scene(scene, out_dir=out)
    net = assemble(build_problem(s, read_packing(s.packing))[0])
    ref = run_explicit(net, s.initial_temperature, [2.0], safety=s.solver.safety).state
    with h5py.File(ckpt) as f:
        state = f["state"]
        assert list(f["outputs/times"][()]) == [2.0]
        assert state.attrs["step"] == ref.step and state.attrs["time_s"] == 2.0
        change = float(np.abs(ref.temperature_k - s.initial_temperature).max())
        assert np.abs(state["temperature_k"][()] - ref.temperature_k).max() <= 1e-12 * change
        np.testing.assert_allclose(state["boundary_energy_j"][()], ref.boundary_energy_j,
                                   rtol=1e-9)


# ------------------------------------------------------------------ validation on the ranks
def _case4_quick(ranks):
    """Case 4's quick instance (`tdem validate 4 --quick`, ``--ranks`` when ranks > 0): its
    row's numbers."""
    from thermal_kernel.run import ranks_of_run_in_memory
    from validation import case4_slab
    from validation.framework import Context
    with ranks_of_run_in_memory(ranks):
        return case4_slab.run(Context(number=4, quick=True)).numbers["rows"][0]


def test_validation_case4_quick_on_two_ranks_gives_the_in_process_numbers():
    """`tdem validate 4 --quick --ranks 2`: case 4's slab on tests/data/dense_box.h5 (Haddad,
    [neighbours] bulk Z 7.5, two held faces), its explicit run to the paper's three Fourier
    numbers and its steady profile run by run_in_memory on 2 ranks, gives the in-process
    case's numbers: the same steps and neighbour choice, the profile's temperatures and errors
    within 1e-12 of ΔT (explicit), the steady profile within 1e-10 of ΔT; its C_t flux test
    runs on the ranks too: C_t within 1e-10."""
    from validation.case4_slab import T1, T2
    inproc, ranks = _case4_quick(0), _case4_quick(2)
    for key in ("n_particles", "steps", "neighbour_gap", "bulk_z_with_gaps", "length_held_m"):
        assert ranks[key] == inproc[key], key
    for key in ("ct_held", "ct_domain"):
        assert abs(ranks[key] - inproc[key]) <= 1e-10 * inproc[key], key
    a, b = np.array(inproc["profile"]), np.array(ranks["profile"])
    np.testing.assert_array_equal(a[:, :3], b[:, :3])           # Fo, t, x / L
    assert np.abs(a[:, 3:] - b[:, 3:]).max() <= 1e-12 * (T2 - T1)   # T_dem, T_exact, error
    assert abs(ranks["max_err_over_dT"] - inproc["max_err_over_dT"]) <= 1e-12
    assert np.abs(np.subtract(ranks["steady_pct"], inproc["steady_pct"])).max() <= 1e-10 * 100


def test_run_in_memory_on_two_ranks_takes_a_start_factors_and_phases():
    """run_in_memory(..., ranks=2) with what validation passes beside the scene -- a start per
    particle, a conductance factor per dumped row, a packing changed in memory (here its phases
    flipped; cases 3 and 8-10) -- gives the in-process run: temperatures within 1e-12 of the
    change (explicit), flows, flags identical, the problem and network the in-process build's.
    Refused before any rank starts, one line: a scene changed after it was read (the ranks read
    its text)."""
    import dataclasses

    from thermal_kernel.packing import read_packing
    from thermal_kernel.run import run_in_memory
    from thermal_kernel.scene import SceneError, load_scene
    scene = load_scene(DATA / "rows.toml", text=DENSE_ROWS + '[solver]\nmethod = "explicit"\n'
                       + DENSE_TIMES)
    rng = np.random.default_rng(25)
    packing = read_packing(DENSE)
    packing = dataclasses.replace(packing, phase=(1 - packing.phase).astype(np.int32))
    kw = dict(initial_temperature_k=298.15 + rng.uniform(-5.0, 5.0, packing.n_particles),
              conductance_factor=rng.uniform(0.5, 2.0, packing.pair.shape[0]))
    inproc = run_in_memory(scene, packing, **kw)
    petsc = run_in_memory(scene, packing, ranks=2, **kw)
    a, b = inproc.result, petsc.result
    change = np.abs(a.temperature_k - inproc.initial_temperature_k).max()
    assert np.abs(a.temperature_k - b.temperature_k).max() <= 1e-12 * change
    np.testing.assert_array_equal(inproc.initial_temperature_k, petsc.initial_temperature_k)
    assert np.abs(a.boundary_heat_flow_w - b.boundary_heat_flow_w).max() <= 1e-9 * np.abs(
        a.boundary_heat_flow_w).max()
    assert a.flags == b.flags and a.steps == b.steps and a.dt == b.dt
    assert b.info["backend"] == "petsc" and b.info["ranks"] == 2
    np.testing.assert_array_equal(inproc.problem.conductance_w_k, petsc.problem.conductance_w_k)
    with pytest.raises(SceneError, match="changed after it was read"):
        run_in_memory(dataclasses.replace(scene, initial_temperature=300.0), packing, ranks=2)


def test_validate_passes_its_ranks_to_the_cases(monkeypatch):
    """`tdem validate 4 --quick --ranks 2` reaches run_cases with ranks=2 (the cases' scenes
    then run on the ranks, the test above); without --ranks, in-process (None)."""
    import validation.run as vrun
    seen = []
    monkeypatch.setattr(vrun, "run_cases", lambda numbers, cases, **kw: seen.append(kw["ranks"])
                        or 0)
    assert main(["validate", "4", "--quick", "--ranks", "2"]) == 0
    assert main(["validate", "4", "--quick"]) == 0
    assert seen == [2, None]


def test_run_in_memory_on_two_ranks_continues_a_run_from_its_state():
    """Case 2's two stages on 2 ranks: a Rannacher run to its first output at dt / 10, its
    result.state (the ranks' final state, mpi_run --state-out), then the run continued from it
    with dt (the ranks resume from it as from a checkpoint): each stage within 1e-10 of the
    in-process one's temperature change, the same steps (the start-up not repeated), the same
    start of the ledger, flags identical."""
    from thermal_kernel.run import run_in_memory
    from thermal_kernel.scene import load_scene

    def scene(solver):
        return load_scene(DATA / "rows.toml", text=DENSE_ROWS + '[solver]\nmethod = "implicit"'
                          '\ntheta = 0.5\n' + solver)
    first_scene = scene("end_time = 0.5\noutput_times = [0.5]\ndt = 0.01\n")
    rest_scene = scene("end_time = 2.0\noutput_times = [1.0, 2.0]\ndt = 0.1\n")
    runs = {}
    for ranks in (0, 2):
        first = run_in_memory(first_scene, DENSE, ranks=ranks)
        runs[ranks] = (first, run_in_memory(rest_scene, DENSE, ranks=ranks,
                                            start_state=first.result.state))
    for inproc, petsc in zip(runs[0], runs[2]):
        a, b = inproc.result, petsc.result
        change = np.abs(a.temperature_k - inproc.initial_temperature_k).max()
        assert np.abs(a.temperature_k - b.temperature_k).max() <= 1e-10 * change
        np.testing.assert_array_equal(inproc.initial_temperature_k, petsc.initial_temperature_k)
        assert a.steps == b.steps and a.state.step == b.state.step and a.flags == b.flags
        np.testing.assert_array_equal(a.times, b.times)


def test_calibrate_on_two_ranks_gives_the_in_process_ct(tmp_path, capsys):
    """`tdem calibrate SCENE --ranks 2`: each flux test's steady solve on the ranks (the scene
    read from its text with the faces held 300 K higher, since a scene refuses the test's 0 K):
    C_t, lambda_e and Q of each axis within 1e-10 of the in-process ones (CG to 1e-12 against
    a direct solve), the same faces; a scene changed after it was read is refused in one line."""
    import dataclasses

    from thermal_kernel.calibrate import calibrate_axes, flux_test
    from thermal_kernel.run import ranks_of_run_in_memory
    from thermal_kernel.scene import SceneError, load_scene
    path = tmp_path / "calib.toml"
    path.write_text(DENSE_ROWS.split("[[boundary]]")[0].replace('law = "haddad"',
                    'law = "haddad"\n[law_params]\nct = 0.806')
                    + '[solver]\nmethod = "steady"\n')
    scene = load_scene(path)
    from thermal_kernel.packing import read_packing
    packing = read_packing(DENSE)
    inproc, _, ct = calibrate_axes(scene, packing)
    with ranks_of_run_in_memory(2):
        ranks, _, ct_ranks = calibrate_axes(scene, packing)
        with pytest.raises(SceneError, match="changed after it was read"):
            flux_test(dataclasses.replace(scene, law="haddad", initial_temperature=301.0),
                      packing, "x")
    assert [r.axis for r in ranks] == [r.axis for r in inproc] and len(inproc) == 3
    for a, b in zip(inproc, ranks):
        assert (a.n_hot, a.n_cold) == (b.n_hot, b.n_cold)
        for key in ("ct", "effective_w_mk", "heat_flow_w"):
            assert abs(getattr(b, key) - getattr(a, key)) <= 1e-10 * abs(getattr(a, key)), key
    assert abs(ct_ranks - ct) <= 1e-10 * ct
    assert main(["calibrate", str(path), "--packing", str(DENSE), "--ranks", "2"]) == 0
    assert f"ct = {ct:.6f}" in capsys.readouterr().out
