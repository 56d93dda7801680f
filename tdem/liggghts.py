"""``tdem import liggghts``: a LIGGGHTS packing (text dumps) -> ``packing.h5`` (docs/import.md).

Three dumps of one timestep, as ``runs/liggghts/bed.in`` writes them (any number of MPI ranks;
LIGGGHTS gathers every rank's rows into one file):

- atoms: ``dump custom`` with the columns ``id x y z radius`` (``type`` -> phase, ``mass`` ->
  density; any order; unscaled, SI);
- pairs: ``dump local`` of ``compute pair/gran/local id force_normal delta``: 7 columns, in the
  order LIGGGHTS writes them whatever the order of the keywords (measured with 3.8.0): id1, id2,
  periodic flag (1: the contact crosses a periodic boundary), the normal force vector on the
  first atom (N), the overlap delta (m, r_i + r_j - distance);
- walls (optional): ``dump local`` of ``compute wall/gran/local id force_normal delta``: mesh id
  (the order of the meshes in ``fix wall/gran ... meshes``), triangle id, atom id, normal force
  vector (N), overlap (m).

Walls are planes normal to an axis, named with ``--walls`` in mesh order
(``zmin,plate:zmax``: mesh 0 is ``zmin``, mesh 1 ``plate``, the upper bound along z). Their
position is ``name:side=COORD`` when given, otherwise inferred from their contacts (the median of
x +- (r - delta) over them) or, with no contact, from the spheres' extreme (recorded in the
attribute ``inferred``). Without a walls dump, wall contacts are taken from the geometry
(overlap r - distance > 0) with Hertz forces at the stated modulus, also recorded.
The overlap written is LIGGGHTS' ``delta``; the largest difference to r_i + r_j - |branch| from the
dumped positions is recorded (``overlap_vs_positions_max_m``): with the default ``%g`` dump
format positions carry 6 digits and it reaches ~1 % of an overlap.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .errors import UserError

AXES = {f"{a}{s}": (k, s) for k, a in enumerate("xyz") for s in ("min", "max")}
PAIR_COLUMNS = ("id1", "id2", "periodic", "fx", "fy", "fz", "delta")
WALL_COLUMNS = ("mesh", "triangle", "atom", "fx", "fy", "fz", "delta")
PAIR_HINT = "compute pair/gran/local id force_normal delta"
WALL_HINT = "compute wall/gran/local id force_normal delta"


class Snapshot:
    def __init__(self, timestep, bounds, boundary, columns, data):
        self.timestep = timestep
        self.bounds = bounds          # (3, 2) lo, hi
        self.boundary = boundary      # ['pp', 'pp', 'ff']
        self.columns = columns
        self.data = data              # (rows, columns) float


def read_dump(path, kind, timestep=None) -> Snapshot:
    """One snapshot of a LAMMPS/LIGGGHTS text dump (``kind``: 'ATOMS' or 'ENTRIES'); the last
    one, or the one at ``timestep``. Raises UserError naming the file and the item."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: file not found" if not path.exists()
                        else f"{path}: is a folder; expected a LIGGGHTS dump file")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a text dump (binary?); expected a LIGGGHTS text dump "
                        "(dump custom / dump local)") from None
    starts = [k for k, line in enumerate(lines) if line.strip() == "ITEM: TIMESTEP"]
    if not starts:
        raise UserError(f"{path}: ITEM: TIMESTEP: not found; expected a LIGGGHTS text dump "
                        f"(dump {'custom' if kind == 'ATOMS' else 'local'})")
    snaps = []
    for k, start in enumerate(starts):
        end = starts[k + 1] if k + 1 < len(starts) else len(lines)
        snaps.append((start, end))
    steps = []
    for start, _end in snaps:
        try:
            steps.append(int(lines[start + 1].split()[0]))
        except (IndexError, ValueError):
            raise UserError(f"{path}: ITEM: TIMESTEP (line {start + 2}): expected an integer "
                            "timestep") from None
    if timestep is None:
        pick = len(snaps) - 1
    elif timestep in steps:
        pick = steps.index(timestep)
    else:
        raise UserError(f"{path}: --timestep: no snapshot at timestep {timestep} (timesteps: "
                        f"{', '.join(map(str, steps[:10]))}{' ...' if len(steps) > 10 else ''})")
    start, end = snaps[pick]
    block = lines[start:end]
    item = {}
    for k, line in enumerate(block):
        if line.startswith("ITEM:"):
            item[line[5:].strip().split()[0] if line[5:].strip() else ""] = k
    count_key = "NUMBER" if kind in ("ATOMS", "ENTRIES") else kind
    if count_key not in item or kind not in item or "BOX" not in item:
        missing = [x for x in ("NUMBER", "BOX", kind) if x not in item]
        what = {"NUMBER": f"ITEM: NUMBER OF {'ATOMS' if kind == 'ATOMS' else 'ENTRIES'}",
                "BOX": "ITEM: BOX BOUNDS", kind: f"ITEM: {kind}"}[missing[0]]
        other = "ENTRIES" if kind == "ATOMS" else "ATOMS"
        hint = (f" (this is a dump {'local' if other == 'ENTRIES' else 'custom'} file: the "
                "arguments are ATOMS PAIRS [WALLS])") if other in item else ""
        raise UserError(f"{path}: {what}: missing at timestep {steps[pick]}{hint}")
    try:
        n = int(block[item["NUMBER"] + 1].split()[0])
    except (IndexError, ValueError):
        raise UserError(f"{path}: ITEM: NUMBER OF ...: expected an integer count") from None
    box_line = block[item["BOX"]].split()
    boundary = box_line[3:6] if len(box_line) >= 6 else ["ff"] * 3
    try:
        bounds = np.array([[float(v) for v in block[item["BOX"] + 1 + a].split()[:2]]
                           for a in range(3)])
    except (IndexError, ValueError):
        raise UserError(f"{path}: ITEM: BOX BOUNDS: expected three lines 'lo hi'") from None
    if bounds.shape != (3, 2):
        raise UserError(f"{path}: ITEM: BOX BOUNDS: expected three lines 'lo hi' (a triclinic "
                        "box is not supported)")
    header = block[item[kind]].split()[2:]
    rows = block[item[kind] + 1:item[kind] + 1 + n]
    if len(rows) < n:
        raise UserError(f"{path}: ITEM: {kind}: expected {n} rows (ITEM: NUMBER OF ...), got "
                        f"{len(rows)} (a truncated file?)")
    try:
        data = np.array([[float(v) for v in r.split()] for r in rows], dtype=float) \
            if n else np.zeros((0, len(header)))
    except ValueError:
        raise UserError(f"{path}: ITEM: {kind}: a row that is not numbers") from None
    if data.ndim != 2 or (n and data.shape[1] != len(header)):
        raise UserError(f"{path}: ITEM: {kind}: rows do not all have the {len(header)} columns "
                        f"of the header ({' '.join(header)})")
    if not np.all(np.isfinite(data)):
        r = int(np.argwhere(~np.isfinite(data))[0][0])
        raise UserError(f"{path}: ITEM: {kind}: non-finite value (NaN or inf) in row {r}")
    return Snapshot(steps[pick], bounds, boundary, header, data)


def parse_walls(text):
    """``zmin,plate:zmax,ymax=0.012`` -> [(name, axis, side, coord or None)] in mesh order."""
    out = []
    if not text:
        return out
    for k, item in enumerate(text.split(",")):
        item = item.strip()
        coord = None
        if "=" in item:
            item, value = item.split("=", 1)
            try:
                coord = float(value)
            except ValueError:
                raise UserError(f"--walls: wall {k} ({item}): expected a coordinate in m after "
                                f"'=', got {value!r}") from None
        name, _, side = item.partition(":")
        side = side or name
        if side not in AXES:
            raise UserError(f"--walls: wall {k} ({name or '?'}): expected a side xmin ... zmax "
                            f"(a name that is one, or name:side, e.g. plate:zmax), got "
                            f"{side!r}")
        if not name or any(name == o[0] for o in out):
            raise UserError(f"--walls: wall {k}: expected a unique name, got {name!r}")
        out.append((name, *AXES[side], coord))
    return out


def _columns(snap, path, wanted, hint):
    if len(snap.columns) != len(wanted):
        raise UserError(f"{path}: ITEM: ENTRIES: expected {len(wanted)} columns ({' '.join(wanted)}"
                        f": `{hint}`), got {len(snap.columns)} ({' '.join(snap.columns)})")
    return {name: snap.data[:, k] for k, name in enumerate(wanted)}


def import_liggghts(atoms_path, pairs_path, walls_path, out, *, walls="", young=None,
                    poisson=None, density=None, pressure=None, seed=0, timestep=None,
                    law="hertz"):
    """Read the dumps, build the packing, write it (validated) to ``out``; return the packing.
    Phase by phase, each refusing in one line (UserError): the options, the three snapshots,
    the atoms, the pairs, the walls' rows and positions, then the statistics
    (thermal_kernel/packing_stats.py) and the file."""
    from thermal_kernel import packing_stats
    from thermal_kernel.packing import Packing

    out, wall_spec = _options(atoms_path, pairs_path, walls_path, out, walls, young, poisson,
                              density, pressure, law)
    a, p, w = _snapshots(atoms_path, pairs_path, walls_path, timestep, wall_spec)
    (ids, index, position, radius, types, phase, density, periodic, lo_box, hi_box,
     inferred) = _atoms(atoms_path, a, density)
    n = len(radius)
    period = hi_box - lo_box
    i, j, delta, force, branch, diff, duplicates, gaps = _pairs(
        atoms_path, pairs_path, p, ids, index, position, radius, periodic, lo_box, period)
    wall_names, w_part, w_wall, w_over, w_force, merged = _wall_rows(
        atoms_path, walls_path, w, wall_spec, index)
    wall_point, wall_normal = _wall_positions(walls_path, a, w, wall_spec, ids, position, radius,
                                              periodic, w_part, w_wall, w_over, inferred)
    if w is None and wall_spec:
        w_part, w_wall, w_over, w_force = _geometric_wall_contacts(
            wall_spec, wall_point, wall_normal, position, radius, young, poisson, inferred)

    # --- domain, phi, Z, pressure, force law (thermal_kernel/packing_stats.py) -----------------
    planes = [(name, axis, side, wall_point[k][axis])
              for k, (name, axis, side, _) in enumerate(wall_spec)]
    lo, hi, free = packing_stats.domain_box(position, radius, planes, periodic, lo_box, hi_box)
    if free:
        inferred.append(free)
    solid_fraction = packing_stats.solid_fraction(radius, lo, hi, radius[w_part], w_over)
    mean_z = 2.0 * len(i) / n
    if pressure is None:
        pressure = _wall_pressure(wall_spec, w_wall, w_force, lo, hi, inferred)
    r_star = radius[i] * radius[j] / (radius[i] + radius[j])
    check = _force_law_check(law, force, radius[i], radius[j], delta, young, poisson)
    attrs = dict(
        generator="tdem import liggghts", seed=int(seed), solid_fraction=solid_fraction,
        mean_coordination=mean_z, pressure_pa=float(pressure), young_pa=float(young),
        poisson=float(poisson), density=float(density),
        source=f"LIGGGHTS dumps {Path(atoms_path).name}, {Path(pairs_path).name}"
               + (f", {Path(walls_path).name}" if walls_path else "")
               + f" at timestep {a.timestep}",
        liggghts_timestep=int(a.timestep),
        # phase k is the k-th type present (boundary kind phase_temperature's liggghts_type)
        liggghts_atom_types=" ".join(str(int(t)) for t in np.unique(types)),
        overlap_source="LIGGGHTS delta (compute pair/gran/local, wall/gran/local)",
        overlap_vs_positions_max_m=diff,
        pair_rows_duplicate=duplicates, pair_rows_not_touching=gaps,
        wall_rows_merged=merged,
        inferred="; ".join(inferred) if inferred else "none",
    )
    attrs.update(check)
    packing = Packing(
        position=position, radius=radius, phase=phase, pair=np.column_stack([i, j]),
        overlap=delta, normal_force=force, branch=branch, wall_name=wall_names,
        wall_kind=["plane"] * len(wall_spec),
        wall_point=np.array(wall_point).reshape(-1, 3),
        wall_normal=np.array(wall_normal).reshape(-1, 3),
        wall_radius=np.full(len(wall_spec), np.nan), wall_particle=w_part, wall_index=w_wall,
        wall_overlap=w_over, wall_normal_force=w_force, domain_lo=lo, domain_hi=hi,
        periodic=periodic, attrs=attrs, contact_radius=np.sqrt(r_star * delta),
        wall_contact_radius=np.sqrt(radius[w_part] * np.clip(w_over, 0, None)), yade_id=None)
    _write_checked(packing, out)
    return packing


def _wall_pressure(wall_spec, w_wall, w_force, lo, hi, inferred) -> float:
    """The pressure from the walls' contact forces (packing_stats.wall_pressure); how it was
    found, or that there is none, appended to ``inferred``."""
    from thermal_kernel import packing_stats
    pressure, how = packing_stats.wall_pressure(
        [(name, axis) for name, axis, _, _ in wall_spec], w_wall, w_force, lo, hi)
    inferred.append(f"pressure_pa: {how}" if how else
                    "pressure_pa: NaN (no wall, no --pressure-pa)")
    return pressure


def _force_law_check(law, force, ri, rj, delta, young, poisson) -> dict:
    """The force-law check's attributes: Hertz at --young, --poisson (``law`` "hertz") or
    none."""
    from thermal_kernel import packing_stats
    if law == "hertz":
        return packing_stats.hertz_check(
            force, ri, rj, delta, young, poisson,
            "hertz (E* from --young, --poisson; particle-particle contacts)")
    return {"force_law": "none given (--law none): not checked", "force_law_contacts": 0}


def _write_checked(packing, out) -> None:
    """The packing built in memory and validated by the reader before anything is written;
    then written at once under a temporary name and renamed (an OSError, e.g. a full disk,
    leaves no file)."""
    from thermal_kernel.atomic import write_bytes_atomic
    from thermal_kernel.packing import PackingError, packing_image, read_packing_image
    image = packing_image(packing)
    try:
        read_packing_image(image, out)
    except PackingError as e:
        raise UserError(f"{e} (the LIGGGHTS dumps describe an impossible packing; nothing "
                        "written)") from None
    write_bytes_atomic(out, image)




def _options(atoms_path, pairs_path, walls_path, out, walls, young, poisson, density, pressure,
             law):
    """(the output path, the parsed --walls) once every option is checked."""
    for key, value, low, high in (("--young", young, 0, math.inf),
                                  ("--poisson", poisson, -1, 0.5)):
        if value is None:
            raise UserError(f"{key}: required (LIGGGHTS dumps carry no material; give the "
                            "values of your input's fix property/global)")
        if not (math.isfinite(value) and low < value < high):
            raise UserError(f"{key}: expected a number in ({low}, {high}), got {value!r}")
    if density is not None and not (math.isfinite(density) and density > 0):
        raise UserError(f"--density: expected a density > 0 in kg/m^3, got {density!r}")
    if pressure is not None and not (math.isfinite(pressure) and pressure >= 0):
        raise UserError(f"--pressure-pa: expected a pressure >= 0 in Pa, got {pressure!r} (leave "
                        "it out to measure it from the walls' forces)")
    out = Path(out)
    for what, given in (("atoms", atoms_path), ("pairs", pairs_path), ("walls", walls_path)):
        if given is not None and out.exists() and Path(given).exists() \
                and out.resolve() == Path(given).resolve():
            raise UserError(f"{out}: -o: is the {what} dump given as input; expected a new "
                            "file name for the packing (the dump would be overwritten)")
    if out.suffix.lower() != ".h5":
        raise UserError(f"{out}: -o: expected a file name ending in .h5")
    if out.is_dir() or not out.parent.is_dir():
        raise UserError(f"{out}: -o: " + ("is a folder; expected a .h5 file name" if out.is_dir()
                                          else f"the folder {out.parent} does not exist"))
    wall_spec = parse_walls(walls)
    if law not in ("hertz", "none"):
        raise UserError(f"--law: expected hertz or none, got {law!r}")
    return out, wall_spec


def _snapshots(atoms_path, pairs_path, walls_path, timestep, wall_spec):
    """The atoms, pairs and (optional) walls snapshots, of one timestep."""
    a = read_dump(atoms_path, "ATOMS", timestep)
    p = read_dump(pairs_path, "ENTRIES", a.timestep if timestep is None else timestep)
    w = read_dump(walls_path, "ENTRIES", a.timestep) if walls_path else None
    for snap, path in ((p, pairs_path), (w, walls_path)):
        if snap is not None and snap.timestep != a.timestep:
            raise UserError(f"{path}: ITEM: TIMESTEP: {snap.timestep}, but the atoms dump is at "
                            f"{a.timestep}; expected the three dumps of one timestep")
    if w is not None and not wall_spec:
        raise UserError(f"{walls_path}: --walls: a walls dump needs the walls named in mesh "
                        "order (e.g. --walls zmin,plate:zmax)")
    return a, p, w


def _atoms(atoms_path, a, density):
    """The atoms sorted by id: ids, id -> row, positions (wrapped on periodic axes), radii,
    types and phases, the density (given, else from the masses), the box."""
    col = {c: k for k, c in enumerate(a.columns)}
    for c in ("xs", "xu", "xsu"):
        if c in col and "x" not in col:
            raise UserError(f"{atoms_path}: ITEM: ATOMS: column {c}: expected unscaled, wrapped "
                            "x y z (dump custom ... id type x y z radius)")
    for c in ("id", "x", "y", "z", "radius"):
        if c not in col:
            raise UserError(f"{atoms_path}: ITEM: ATOMS: missing column {c!r} (expected `dump "
                            f"custom ... id type x y z radius`; got {' '.join(a.columns)})")
    d = a.data
    n = d.shape[0]
    if n == 0:
        raise UserError(f"{atoms_path}: ITEM: ATOMS: no atoms at timestep {a.timestep}")
    _integers(atoms_path, "id", d[:, col["id"]], "atom id")
    if "type" in col:
        _integers(atoms_path, "type", d[:, col["type"]], "atom type")
    order = np.argsort(d[:, col["id"]], kind="stable")
    d = d[order]
    ids = d[:, col["id"]].astype(np.int64)
    if np.any(np.diff(ids) == 0):
        dup = int(ids[np.flatnonzero(np.diff(ids) == 0)[0]])
        raise UserError(f"{atoms_path}: ITEM: ATOMS: atom id {dup} appears twice")
    index = {int(i): k for k, i in enumerate(ids)}
    position = d[:, [col["x"], col["y"], col["z"]]].copy()
    radius = d[:, col["radius"]].copy()
    if np.any(radius <= 0):
        raise UserError(f"{atoms_path}: radius: atom {int(ids[np.argmin(radius)])} has radius "
                        f"{float(radius.min())!r} m; expected > 0")
    box_size = float(np.max(a.bounds[:, 1] - a.bounds[:, 0]))
    if np.any(radius > box_size):
        k = int(np.argmax(radius))
        raise UserError(f"{atoms_path}: radius: atom {int(ids[k])} has radius {radius[k]:.6g} m, "
                        f"larger than the dump's box (BOX BOUNDS, largest extent {box_size:.6g} "
                        "m); expected spheres that fit in the simulation box")
    types = d[:, col["type"]].astype(np.int64) if "type" in col else np.ones(n, np.int64)
    phase = np.searchsorted(np.unique(types), types).astype(np.int32)
    inferred = []
    if density is None:
        if "mass" not in col:
            raise UserError("--density: required (or dump the atoms' mass column, from which "
                            "it is computed)")
        rho = d[:, col["mass"]] / (4 / 3 * np.pi * radius ** 3)
        density = float(np.median(rho))
        inferred.append(f"density: median mass / sphere volume of the atoms ({density:.6g} "
                        "kg/m^3)")
    periodic = np.array([b.startswith("p") for b in a.boundary])
    lo_box, hi_box = a.bounds[:, 0], a.bounds[:, 1]
    period = hi_box - lo_box
    if periodic.any():                   # wrap (dump custom x y z is wrapped; be sure)
        for ax in np.flatnonzero(periodic):
            position[:, ax] = lo_box[ax] + np.mod(position[:, ax] - lo_box[ax], period[ax])
    return (ids, index, position, radius, types, phase, density, periodic, lo_box, hi_box,
            inferred)


def _pairs(atoms_path, pairs_path, p, ids, index, position, radius, periodic, lo_box, period):
    """The touching pairs (i < j, one row each; delta checked against the positions): i, j,
    delta, |F|, branch, the largest delta - geometry difference, duplicate and gap rows."""
    from thermal_kernel.packing import OVERLAP_RTOL, abs_max
    n = len(radius)
    cols = _columns(p, pairs_path, PAIR_COLUMNS, PAIR_HINT)
    _integers(pairs_path, "id1/id2 (columns 1-2)", np.concatenate([cols["id1"], cols["id2"]]),
              "atom id")
    i_id, j_id = cols["id1"].astype(np.int64), cols["id2"].astype(np.int64)
    unknown = [x for x in np.concatenate([i_id, j_id]) if int(x) not in index]
    if unknown:
        raise UserError(f"{pairs_path}: id1/id2 (columns 1-2): atom id {int(unknown[0])} is not "
                        f"in {atoms_path}; expected the pairs of the same timestep")
    i = np.array([index[int(x)] for x in i_id], np.int64)
    j = np.array([index[int(x)] for x in j_id], np.int64)
    swap = i > j
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    delta = cols["delta"]
    force = np.linalg.norm(np.column_stack([cols["fx"], cols["fy"], cols["fz"]]), axis=1)
    if np.any(i == j):
        raise UserError(f"{pairs_path}: id1/id2: row {int(np.flatnonzero(i == j)[0])} is a self "
                        "contact")
    key = i * n + j
    uniq, first, counts = np.unique(key, return_index=True, return_counts=True)
    duplicates = int((counts - 1).sum())
    if duplicates:                      # (not seen with LIGGGHTS 3.8.0 on 2 ranks; kept safe)
        for k in np.flatnonzero(counts > 1):
            rows = np.flatnonzero(key == uniq[k])
            if np.ptp(delta[rows]) > 1e-9 * max(abs(delta[rows]).max(), 1e-300):
                raise UserError(f"{pairs_path}: pair ({int(ids[i[rows[0]]])}, "
                                f"{int(ids[j[rows[0]]])}) appears {len(rows)} times with "
                                "different overlaps; expected one row per contact")
    keep = np.sort(first)
    i, j, delta, force = i[keep], j[keep], delta[keep], force[keep]
    touching = delta > 0
    gaps = int((~touching).sum())
    i, j, delta, force = i[touching], j[touching], delta[touching], force[touching]
    branch = position[j] - position[i]
    for ax in np.flatnonzero(periodic):
        branch[:, ax] -= period[ax] * np.round(branch[:, ax] / period[ax])
    geo = radius[i] + radius[j] - np.linalg.norm(branch, axis=1)
    diff = float(np.abs(geo - delta).max()) if len(delta) else 0.0
    # the overlap LIGGGHTS states must be the one of the dumped spheres (the default 6-digit
    # dump format costs ~1e-5 of a radius; the reader's tolerance is OVERLAP_RTOL of it)
    r_min = np.minimum(radius[i], radius[j])
    tol = OVERLAP_RTOL * r_min + 1e-12 * (abs_max(position) + r_min)
    off = np.abs(geo - delta) > tol
    if off.any():
        c = int(np.flatnonzero(off)[0])
        raise UserError(f"{pairs_path}: delta (column 7): pair ({int(ids[i[c]])}, "
                        f"{int(ids[j[c]])}) has delta {delta[c]:.6g} m, but the atoms' centres "
                        f"are {np.linalg.norm(branch[c]):.6g} m apart (r_i + r_j - distance = "
                        f"{geo[c]:.6g} m); expected the overlap of the two atoms of "
                        f"{Path(atoms_path).name} (within {OVERLAP_RTOL:g} of the smaller radius)")
    _unlisted_overlaps(atoms_path, pairs_path, position, radius, ids, i, j, periodic, lo_box,
                       period)
    return i, j, delta, force, branch, diff, duplicates, gaps


def _wall_rows(atoms_path, walls_path, w, wall_spec, index):
    """The walls dump's touching rows, one per (atom, mesh) (forces summed, the largest
    overlap): wall names, atom, wall, overlap, force, rows merged."""
    wall_names = [s[0] for s in wall_spec]
    w_part = np.zeros(0, np.int64)
    w_wall = np.zeros(0, np.int32)
    w_over = np.zeros(0)
    w_force = np.zeros(0)
    merged = 0
    if w is not None:
        wc = _columns(w, walls_path, WALL_COLUMNS, WALL_HINT)
        _integers(walls_path, "mesh (column 1)", wc["mesh"], "mesh id")
        _integers(walls_path, "atom (column 3)", wc["atom"], "atom id")
        mesh = wc["mesh"].astype(np.int64)
        if mesh.size and (mesh.min() < 0 or mesh.max() >= len(wall_spec)):
            bad = int(mesh[(mesh < 0) | (mesh >= len(wall_spec))][0])
            raise UserError(f"{walls_path}: mesh (column 1): mesh id {bad}, but --walls names "
                            f"{len(wall_spec)} mesh(es) ({', '.join(wall_names)}); expected one "
                            "name per mesh of fix wall/gran, in its order")
        atom = wc["atom"].astype(np.int64)
        missing = [x for x in atom if int(x) not in index]
        if missing:
            raise UserError(f"{walls_path}: atom (column 3): atom id {int(missing[0])} is not in "
                            f"{atoms_path}")
        part = np.array([index[int(x)] for x in atom], np.int64)
        fw = np.linalg.norm(np.column_stack([wc["fx"], wc["fy"], wc["fz"]]), axis=1)
        dw = wc["delta"]
        ok = dw > 0
        part, mesh, fw, dw = part[ok], mesh[ok], fw[ok], dw[ok]
        # one row per (atom, mesh): an atom on the edge of two triangles of one mesh
        wkey = part * len(wall_spec) + mesh
        uk, inv = np.unique(wkey, return_inverse=True)
        merged = int(len(wkey) - len(uk))
        w_part = (uk // len(wall_spec)).astype(np.int64)
        w_wall = (uk % len(wall_spec)).astype(np.int32)
        w_force = np.bincount(inv, weights=fw, minlength=len(uk))
        w_over = np.zeros(len(uk))
        np.maximum.at(w_over, inv, dw)
    return wall_names, w_part, w_wall, w_over, w_force, merged


def _wall_positions(walls_path, a, w, wall_spec, ids, position, radius, periodic, w_part,
                    w_wall, w_over, inferred):
    """Each wall's point and inward normal: given, else where its contacts put it, else at the
    spheres' extreme; contacts off their wall refused."""
    from thermal_kernel.packing import OVERLAP_RTOL, abs_max
    wall_point, wall_normal = [], []
    top = abs_max(position)                 # max |x|, once (the walls' tolerances)
    for k, (name, axis, side, coord) in enumerate(wall_spec):
        sign = 1.0 if side == "min" else -1.0       # the normal points into the domain
        normal = np.zeros(3)
        normal[axis] = sign
        if periodic[axis]:
            raise UserError(f"--walls: {name}: a wall normal to {'xyz'[axis]}, a periodic axis "
                            f"of the dump (BOX BOUNDS {a.boundary[axis]})")
        rows = np.flatnonzero(w_wall == k) if w is not None else np.zeros(0, np.int64)
        if rows.size:        # where each contact of the walls dump puts the wall
            q = w_part[rows]
            implied = position[q, axis] - sign * (radius[q] - w_over[rows])
            median = float(np.median(implied))
            tol = OVERLAP_RTOL * radius[q] + 1e-12 * (top + radius[q])
            if coord is not None and abs(median - coord) > float(np.median(tol)):
                raise UserError(
                    f"--walls: {name}={coord:g} contradicts {walls_path}: its "
                    f"{rows.size} contacts with mesh {k} put the wall at {'xyz'[axis]} = "
                    f"{median:.9g} m (x -+ (r - delta), median); expected the wall where the "
                    f"dump's contacts are (leave '={coord:g}' out to take it from them)")
            if coord is None:
                coord = median
                inferred.append(f"wall {name}: {'xyz'[axis]} = {coord:.9g} m from its "
                                f"{int(rows.size)} contacts (x -+ (r - delta))")
            off = np.abs(implied - coord) > tol
            if off.any():
                c = int(np.flatnonzero(off)[0])
                dist = sign * (position[q[c], axis] - coord)
                raise UserError(
                    f"{walls_path}: atom (column 3): atom {int(ids[q[c]])} touches {name} "
                    f"(mesh {k}, delta {w_over[rows[c]]:.6g} m), but its centre is "
                    f"{dist:.6g} m from the wall at {'xyz'[axis]} = {coord:.9g} m (radius "
                    f"{radius[q[c]]:.6g} m); expected contacts on atoms at the wall (r - "
                    f"distance = delta, within {OVERLAP_RTOL:g} of the radius)")
        if coord is None:
            ext = position[:, axis] - sign * radius
            coord = float(ext.min() if sign > 0 else ext.max())
            inferred.append(f"wall {name}: {'xyz'[axis]} = {coord:.9g} m from the spheres' "
                            "extreme (no contact)")
        point = np.zeros(3)
        point[axis] = coord
        wall_point.append(point)
        wall_normal.append(normal)
    return wall_point, wall_normal


def _geometric_wall_contacts(wall_spec, wall_point, wall_normal, position, radius, young,
                             poisson, inferred):
    """Without a walls dump: the wall contacts from the positions, Hertz forces."""
    from thermal_kernel import contact_check
    e_star = contact_check.effective_modulus(young, poisson)
    rows_p, rows_w, rows_d = [], [], []
    for k, (_name, axis, _side, _) in enumerate(wall_spec):
        dist = (position[:, axis] - wall_point[k][axis]) * wall_normal[k][axis]
        over = radius - dist
        hit = np.flatnonzero(over > 0)
        rows_p.append(hit)
        rows_w.append(np.full(len(hit), k, np.int32))
        rows_d.append(over[hit])
    w_part = np.concatenate(rows_p).astype(np.int64)
    w_wall = np.concatenate(rows_w).astype(np.int32)
    w_over = np.concatenate(rows_d)
    w_force = contact_check.hertz_force(radius[w_part], w_over, e_star)
    inferred.append("wall contacts: from the positions (r - distance > 0), forces Hertz "
                    "4/3 E* sqrt(r) delta^1.5 at --young/--poisson (no walls dump)")
    return w_part, w_wall, w_over, w_force


def _integers(path, column, values, what):
    """Ids and types are integers: 26.5 is refused, not truncated to 26."""
    bad = np.flatnonzero(values != np.round(values))
    if bad.size:
        raise UserError(f"{path}: {column}: {what} {values[bad[0]]:g} (row {int(bad[0])}) is not "
                        "an integer; expected integer ids")


# An overlap the pairs dump does not list, beyond this fraction of the smaller radius, is
# refused: at `run 0` LIGGGHTS lists every pair in contact, and no DEM step moves a sphere by
# 1 % of its radius, so such an overlap is two atoms in one place (a copy, a merged file).
UNLISTED_OVERLAP_RTOL = 1e-2


def _unlisted_overlaps(atoms_path, pairs_path, position, radius, ids, i, j, periodic, lo_box,
                       period):
    from scipy.spatial import cKDTree
    if len(radius) < 2:
        return
    x = position.copy()
    box = None
    if periodic.any():
        # cKDTree's periodic box: periodic axes wrapped into [0, period), the others unbounded
        box = np.where(periodic, period, 0.0)
        x[:, periodic] = np.mod(x[:, periodic] - lo_box[periodic], period[periodic])
        x[x >= np.where(periodic, period, np.inf)] = 0.0
        if np.any(2 * 2 * radius.max() > period[periodic]):
            return              # a cell thinner than two diameters: minimum image is ambiguous
    tree = cKDTree(x, boxsize=box)
    cand = tree.query_pairs(2.0 * float(radius.max()), output_type="ndarray").astype(np.int64)
    if not cand.size:
        return
    cand.sort(axis=1)
    a, b = cand[:, 0], cand[:, 1]
    d = x[b] - x[a]
    if box is not None:
        for ax in np.flatnonzero(periodic):
            d[:, ax] -= period[ax] * np.round(d[:, ax] / period[ax])
    over = radius[a] + radius[b] - np.linalg.norm(d, axis=1)
    deep = over > UNLISTED_OVERLAP_RTOL * np.minimum(radius[a], radius[b])
    if not deep.any():
        return
    n = len(radius)
    listed = set((np.minimum(i, j) * n + np.maximum(i, j)).tolist())
    for k in np.flatnonzero(deep)[np.argsort(-over[deep] / np.minimum(radius[a], radius[b])[deep],
                                             kind="stable")]:        # the deepest first
        if int(a[k] * n + b[k]) not in listed:
            raise UserError(
                f"{atoms_path}: x y z radius: atoms {int(ids[a[k]])} and {int(ids[b[k]])} "
                f"overlap by {over[k]:.6g} m (centres {np.linalg.norm(d[k]):.6g} m apart, radii "
                f"{radius[a[k]]:.6g} and {radius[b[k]]:.6g} m), but {Path(pairs_path).name} "
                "lists no contact between them; expected every overlapping pair in the pairs "
                "dump (two atoms in one place?)")
