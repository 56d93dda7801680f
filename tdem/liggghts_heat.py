"""LIGGGHTS' own conduction beside tdem's (issue 27): the pieces the side-by-side test
(tests/test_liggghts_conduction.py) and the peers benchmark (bench/bench_peers.py) share.

``runs/liggghts_heat/pack.in`` settles a bed and dumps it; :func:`write_data` turns that dump
into a LIGGGHTS data file whose bottom and top layers are types 2 and 3 (held: outside
``fix heat/gran/conduction``'s group, LIGGGHTS keeps their temperature); ``heat.in`` heats it
and dumps the temperatures, which :func:`read_temperatures` reads back.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from .errors import UserError
from .liggghts import read_dump

INPUTS = Path(__file__).resolve().parent.parent / "runs" / "liggghts_heat"
FREE, HOT, COLD = 1, 2, 3              # LIGGGHTS atom types of heat.in


def scene_text(packing, law, *, conductivity, density, heat_capacity, young_pa, poisson,
               t_initial, t_hot, t_cold, solver, law_params=""):
    """tdem's scene of heat.in's bed: the hot and cold layers held by their LIGGGHTS types
    (phase_temperature), ``solver`` the [solver] table's lines, ``law_params`` a
    [law_params] table or nothing. SI units."""
    return (f'packing = "{packing}"\nlaw = "{law}"\n{law_params}[material]\n'
            f"conductivity = {conductivity!r}\ndensity = {density!r}\n"
            f"heat_capacity = {heat_capacity!r}\nyoung_pa = {young_pa!r}\n"
            f"poisson = {poisson!r}\n[initial]\ntemperature = {t_initial!r}\n"
            + "".join(f'[[boundary]]\nkind = "phase_temperature"\nliggghts_type = {kind}\n'
                      f"value = {value!r}\n" for kind, value in ((HOT, t_hot), (COLD, t_cold)))
            + f"[solver]\n{solver}")


def mpi_env() -> dict:
    env = dict(os.environ)
    if os.geteuid() == 0:            # Open MPI refuses root unless told
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return env


def run_liggghts(script, cwd, ranks=1, variables=None, timeout=3600):
    """Run ``liggghts -in script`` in ``cwd`` on ``ranks`` MPI ranks (plain, without mpirun, for
    1); return its screen output. A failure raises UserError with the tail of the output."""
    cmd = ["liggghts", "-in", str(script)]
    for key, value in (variables or {}).items():
        cmd += ["-var", str(key), str(value)]
    if ranks > 1:
        cmd = ["mpirun", "-np", str(ranks), "--oversubscribe", *cmd]
    if shutil.which(cmd[0]) is None:
        raise UserError(f"{cmd[0]}: not installed (Debian: apt-get install liggghts openmpi-bin)")
    r = subprocess.run(cmd, cwd=cwd, env=mpi_env(), capture_output=True, text=True,
                       timeout=timeout, stdin=subprocess.DEVNULL)
    if r.returncode != 0:
        raise UserError(f"{script}: LIGGGHTS failed (exit {r.returncode}) in {cwd}: "
                        + (r.stdout[-1500:] + r.stderr[-500:]).replace("\n", " | "))
    return r.stdout


def write_data(packed_dump, out, layer_m=0.0012):
    """A LIGGGHTS data file (atom_style granular: id type diameter density x y z) of the spheres
    of ``packed_dump`` (dump custom id type x y z radius mass), the box of the dump, 3 atom
    types: centres within ``layer_m`` of the bed's bottom (lowest z - r) type 2, of its top
    (highest z + r) type 3, the others 1. Positions and diameters written with repr (exact);
    the density from mass / volume (one value per sphere, rounded to 12 digits: the dump's
    mass is LIGGGHTS' own 4/3 pi r^3 rho). Returns the types in id order."""
    snap = read_dump(packed_dump, "ATOMS")
    col = {c: k for k, c in enumerate(snap.columns)}
    d = snap.data[np.argsort(snap.data[:, col["id"]])]
    ids = d[:, col["id"]].astype(np.int64)
    x = d[:, [col["x"], col["y"], col["z"]]]
    r = d[:, col["radius"]]
    rho = d[:, col["mass"]] / (4.0 / 3.0 * np.pi * r ** 3)
    bottom, top = float((x[:, 2] - r).min()), float((x[:, 2] + r).max())
    types = np.full(ids.size, FREE, np.int64)
    types[x[:, 2] < bottom + layer_m] = HOT
    types[x[:, 2] > top - layer_m] = COLD
    lo, hi = snap.bounds[:, 0], snap.bounds[:, 1]
    lines = ["LIGGGHTS data file (tdem.liggghts_heat.write_data)", "",
             f"{ids.size} atoms", "3 atom types", ""]
    lines += [f"{float(lo[a])!r} {float(hi[a])!r} {n}lo {n}hi" for a, n in enumerate("xyz")]
    lines += ["", "Atoms", ""]
    lines += [f"{int(i)} {int(t)} {float(2.0 * ri)!r} {float(f'{p:.12g}')!r} {float(a)!r} "
              f"{float(b)!r} {float(c)!r}"
              for i, t, ri, p, (a, b, c) in zip(ids, types, r, rho, x)]
    Path(out).write_text("\n".join(lines) + "\n")
    return types


def read_temperatures(path):
    """Every snapshot of a ``dump custom id type f_Temp`` file: {timestep: (ids, types, T)},
    rows in id order (the ranks' rows come in any order)."""
    text = Path(path).read_text().splitlines()
    out = {}
    k = 0
    while k < len(text):
        if text[k].strip() != "ITEM: TIMESTEP":
            k += 1
            continue
        step = int(text[k + 1])
        n = int(text[k + 3])
        header = text[k + 8].split()[2:]
        rows = np.array([[float(v) for v in line.split()] for line in text[k + 9:k + 9 + n]])
        if rows.shape != (n, len(header)) or header[:2] != ["id", "type"]:
            raise UserError(f"{path}: ITEM: ATOMS at timestep {step}: expected {n} rows of "
                            "id type f_Temp")
        rows = rows[np.argsort(rows[:, 0])]
        out[step] = (rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64), rows[:, 2])
        k += 9 + n
    return out


_LOOP = re.compile(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps")
_PART = re.compile(r"^(Pair|Neigh|Comm|Outpt|Other|Modify)\s+time \(%\) = ([0-9.eE+-]+)",
                   re.M)


def loop_times(screen: str):
    """The last run's ``Loop time`` (s), its steps and its breakdown (Pair, Neigh, Comm, Outpt,
    Other: s) from LIGGGHTS' screen output."""
    loops = _LOOP.findall(screen)
    if not loops:
        raise UserError("LIGGGHTS output: no 'Loop time of ...' line")
    total, _procs, steps = loops[-1]
    last = screen.rsplit("Loop time of", 1)[1]
    parts = {name: float(v) for name, v in _PART.findall(last)}
    return float(total), int(steps), parts
