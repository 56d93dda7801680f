"""Dump the scene of any YADE script as a tdem packing (``packing.h5``, docs/packing-format.md).

Use it from your own script, run with Debian's YADE, at any point of the simulation::

    import sys
    sys.path.insert(0, "/path/to/tdem/yade_scripts")      # what `tdem yade-path` prints
    import tdem_yade
    ...                                                    # your scene, O.run(...)
    tdem_yade.dump("packing.h5", young_pa=70e9, poisson=0.3)

What it reads (docs/import.md):
- particles: every body whose shape is a ``Sphere`` (``utils.sphere``); ``phase`` numbers the
  spheres' materials in order of their material id (0 = the first);
- walls (``walls="auto"``): ``Wall`` bodies (``utils.wall``), ``Facet`` bodies grouped into planes
  (coplanar facets of one ``facetBox`` face are one plane) and the faces of ``Box`` bodies
  (``utils.box``) that the spheres touch or face; each becomes a plane of the format, named
  ``xmin`` ... ``zmax`` when it is normal to an axis (``plane_<k>`` otherwise; ``wall_names``
  renames them by body id, e.g. ``{plate.id: "plate"}``); ``walls="none"`` leaves them and their
  contacts out;
- periodic cells (``O.periodic``): the cell becomes the periodic domain ``[0, size]``; centres
  are wrapped into it and branch vectors take YADE's ``cellDist`` image;
- contacts: real interactions with ``ScGeom`` geometry. The overlap is recomputed from the dumped
  positions (r_i + r_j - |branch|; for a wall, r - the centre's distance to its plane), so that the
  file's geometry is consistent; YADE's ``penetrationDepth`` is one step older, and the largest
  difference is recorded (``overlap_vs_yade_max_m``). The normal force is YADE's own
  ``phys.normalForce`` along ``geom.normal`` (compression > 0), whatever the law: Hertz-Mindlin,
  linear Cundall, frictional or cohesive. A tensile (cohesive) force is written as 0 and counted
  (``tensile_contacts_clipped``). Only touching contacts are kept unless ``gaps=True`` (then the
  real interactions with overlap <= 0 are kept as gaps, force 0). A sphere touching two facets
  of one plane (on the diagonal of a ``facetBox`` face) has two YADE interactions and one wall
  contact in the file, whose force is their sum (what YADE applies; ``wall_interactions_merged``
  counts them).

What it measures: ``solid_fraction`` (sphere volume inside the domain over its volume; the
domain is bounded by the axis-normal walls or the periodic cell, and along an axis with neither by
the spheres' bounding box, which is then recorded as inferred), ``mean_coordination`` (2 M / N,
touching sphere-sphere contacts), ``pressure_pa`` when not given (periodic cell: -trace/3 of
YADE's ``utils.getStress()``; walls: the normal force on the wall named ``plate`` (see
``wall_names``) over the domain's face area, else the mean of that over the axis-normal walls).
Everything inferred is listed in the attribute ``inferred`` and printed by ``tdem info``. The
stated contact law is checked against the forces (``force_law*``,
``thermal_kernel/contact_check.py``): Hertz (``MindlinPhys``) against 4/3 E* sqrt(R*) delta^1.5
with the given ``young_pa``/``poisson``, linear laws against k_n delta with YADE's own k_n.

What it refuses, in one line (``tdem_yade: error: ...``, exit status 2; with
``exit_on_error=False`` a ``DumpError`` is raised instead): clumps, non-spherical particles,
contact geometries other than ScGeom, sheared periodic cells, a wall with spheres on both sides,
an empty scene; a wrong call (the file name is the only positional argument; an unknown
argument is named); poisson outside (-1, 0.5), or not given under a law other than
Hertz-Mindlin; a negative pressure; wall_names that are not {wall body id: new name}; attrs that
would replace an attribute dump writes, or hold objects; a non-finite position; two spheres
overlapping without a YADE interaction (a scene that never ran), a solid fraction above 1; an
unwritable folder or a full disk (the file is built in memory and written at once; nothing is
left). Standard library + numpy + h5py + yade (scipy for the overlap search, skipped without
it) on Debian's Python; the file is written by the same single writer as tdem's generators
(``thermal_kernel/packing_h5.py``).
"""
import importlib.util
import math
import os
import sys
import time

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
GENERATOR = "yade_scripts/tdem_yade.py"


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_writer = _load("tdem_packing_h5", os.path.join(_HERE, os.pardir, "thermal_kernel",
                                                "packing_h5.py"))
# the kernel's numpy-only modules import as the package they are (tests/test_layers.py YADE_SAFE):
# the repository's root goes on the path, after the user's own entries
_ROOT = os.path.dirname(_HERE)
if _ROOT not in sys.path:
    sys.path.append(_ROOT)
from thermal_kernel import contact_check as _check  # noqa: E402
from thermal_kernel import packing_stats as _stats  # noqa: E402

WALL_SHAPES = ("Wall", "Facet", "Box")
HERTZ_PHYS = ("MindlinPhys",)
LINEAR_PHYS = ("FrictPhys", "ViscoFrictPhys", "CohFrictPhys", "NormShearPhys")
AXIS_TOL = 1e-9          # |n . e_a| > 1 - AXIS_TOL: the plane is normal to axis a


class DumpError(ValueError):
    """The scene cannot be represented in the format; the message is one line."""


# dump(path, *, ...): the keyword arguments and their defaults (checked by _arguments, so that a
# wrong call is one line like every other refusal, not a Python traceback inside YADE)
DEFAULTS = dict(young_pa=None, poisson=None, density=None, walls="auto", wall_names=None,
                pressure_pa=None, seed=0, gaps=False, attrs=None, quiet=False,
                exit_on_error=True)
# root attributes dump() itself writes: attrs={...} may not replace them
OWN_ATTRS = ("format", "format_version", "generator", "seed", "solid_fraction",
             "mean_coordination", "pressure_pa", "young_pa", "poisson", "density", "source",
             "yade_version", "yade_iteration", "yade_time_s", "yade_dt_s", "contact_law",
             "contact_phys", "overlap_source", "overlap_vs_yade_max_m",
             "tensile_contacts_clipped", "wall_interactions_merged", "inferred", "wall_seconds",
             "force_law", "force_law_contacts", "force_law_ratio_median",
             "force_law_mismatch_p95", "force_law_mismatch_max")
# Two spheres overlapping by more than this fraction of the smaller radius without a YADE
# interaction between them are refused: the collider pairs every overlap at the next step, and
# no DEM step moves a sphere by 1 % of its radius; such an overlap is a scene that never ran
# (O.run) or two spheres put in one place.
UNLISTED_OVERLAP_RTOL = 1e-2


def dump(*args, **kwargs):
    """dump(path, *, young_pa=None, poisson=None, density=None, walls="auto", wall_names=None,
    pressure_pa=None, seed=0, gaps=False, attrs=None, quiet=False, exit_on_error=True)

    Write the current YADE scene (``O``) to ``path`` as a tdem packing; return a dict of
    the measured numbers (n_particles, n_contacts, solid_fraction, mean_coordination,
    pressure_pa, inferred, force law check). ``path`` is the only positional argument.

    young_pa, poisson, density: the real material (Pa, -, kg/m^3) the thermal laws will use;
    when not given they are read from the spheres' material and recorded as inferred (a linear
    law's FrictMat ``poisson`` is k_s/k_n, not Poisson's ratio: give ``poisson`` then).
    walls: "auto" (Wall, Facet and Box bodies become planes) or "none".
    wall_names: {body id: name} to name the plane a body makes (e.g. a loading plate "plate").
    pressure_pa: the confining pressure (Pa, >= 0; NaN: none); measured when None (see the
    module docstring). seed: the integer seed of your generator (recorded). attrs: extra root
    attributes to record ({name: number or string}; the names dump writes itself are refused).

    A refusal prints one line ``tdem_yade: error: ...`` and exits with status 2, or, with
    ``exit_on_error=False``, raises :class:`DumpError` (also for a wrong call).
    """
    exit_on_error = kwargs.get("exit_on_error", True)
    try:
        path, kw = _arguments(args, kwargs)
        exit_on_error = kw["exit_on_error"]
        return _dump(path, kw["young_pa"], kw["poisson"], kw["density"], kw["walls"],
                     kw["wall_names"], kw["pressure_pa"], kw["seed"], kw["gaps"], kw["attrs"],
                     kw["quiet"])
    except DumpError as e:
        if exit_on_error is False:
            raise
        print(f"tdem_yade: error: {e}", file=sys.stderr, flush=True)
        raise SystemExit(2) from None


def _arguments(args, kwargs):
    """(path, {argument: value}) of a dump() call, each argument's type checked; DumpError.
    The checks run in the call's order (the first fault is the one reported): the file name, the
    argument names, the flags, seed and numbers here, then wall_names and attrs."""
    if not args and "path" not in kwargs:
        raise DumpError("dump(): missing the file name: dump('packing.h5', young_pa=..., "
                        "poisson=...)")
    if len(args) > 1:
        raise DumpError(f"dump(): {len(args)} positional arguments; the file name is the only "
                        "one, give the others by name (young_pa=..., poisson=..., ...)")
    if args and "path" in kwargs:
        raise DumpError("dump(): the file name given twice (positionally and as path=)")
    kwargs = dict(kwargs)
    path = args[0] if args else kwargs.pop("path")
    unknown = sorted(k for k in kwargs if k not in DEFAULTS)
    if unknown:
        import difflib
        close = difflib.get_close_matches(unknown[0], DEFAULTS, n=1)
        raise DumpError(f"dump(): unknown argument {unknown[0]!r}"
                        + (f" (did you mean {close[0]}?)" if close else "")
                        + f"; expected {', '.join(DEFAULTS)}")
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise DumpError(f"dump(): the file name must be a string, got {path!r}")
    path = os.fspath(path)
    kw = dict(DEFAULTS, **kwargs)
    for key in ("gaps", "quiet", "exit_on_error"):
        if not isinstance(kw[key], (bool, np.bool_)):
            raise DumpError(f"{path}: {key}: expected True or False, got {kw[key]!r}")
    seed = kw["seed"]
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise DumpError(f"{path}: seed: expected an integer, got {seed!r}")
    kw["seed"] = int(seed)
    for key in ("young_pa", "poisson", "density", "pressure_pa"):
        value = kw[key]
        if value is None:
            continue
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float,
                                                                         np.integer,
                                                                         np.floating)):
            raise DumpError(f"{path}: {key}: expected a number, got {value!r}")
        kw[key] = float(value)
    pressure = kw["pressure_pa"]
    if pressure is not None and not math.isnan(pressure) and not (math.isfinite(pressure)
                                                                  and pressure >= 0):
        raise DumpError(f"{path}: pressure_pa: expected a pressure >= 0 in Pa (or NaN: none), "
                        f"got {pressure!r}")
    kw["wall_names"] = _wall_names(path, kw["wall_names"])
    kw["attrs"] = _extra_attrs(path, kw["attrs"])
    return path, kw


def _wall_names(path, names):
    """dump()'s wall_names checked: {body id (int): wall name (str)}, one name per wall."""
    if names is None:
        names = {}
    if not isinstance(names, dict):
        raise DumpError(f"{path}: wall_names: expected a dict {{body id: name}} (e.g. "
                        f"{{lid.id: 'plate'}}), got {type(names).__name__} {names!r}")
    for body, name in names.items():
        if isinstance(body, (bool, np.bool_)) or not isinstance(body, (int, np.integer)):
            raise DumpError(f"{path}: wall_names: key {body!r}: expected a body id (an integer)")
        if not isinstance(name, str) or not name.strip():
            raise DumpError(f"{path}: wall_names[{body}]: expected a wall name (a non-empty "
                            f"string), got {name!r}")
    given = list(names.values())
    dup = next((x for x in given if given.count(x) > 1), None)
    if dup is not None:
        raise DumpError(f"{path}: wall_names: the name {dup!r} is given to two bodies; expected "
                        "one name per wall")
    return {int(b): str(x) for b, x in names.items()}


def _extra_attrs(path, extra):
    """dump()'s attrs checked: {new attribute name: number or string}, none of OWN_ATTRS."""
    if extra is None:
        extra = {}
    if not isinstance(extra, dict):
        raise DumpError(f"{path}: attrs: expected a dict {{name: value}}, got "
                        f"{type(extra).__name__}")
    checked = {}
    for key, value in extra.items():
        if not isinstance(key, str) or not key:
            raise DumpError(f"{path}: attrs: key {key!r}: expected an attribute name (a string)")
        if key in OWN_ATTRS:
            raise DumpError(f"{path}: attrs[{key!r}]: an attribute dump() writes itself (from "
                            "the scene or its own arguments); expected a new name for an extra "
                            "attribute")
        if isinstance(value, (np.generic,)):
            value = value.item()
        if not isinstance(value, (str, bool, int, float)):
            raise DumpError(f"{path}: attrs[{key!r}]: a value of type "
                            f"{type(value).__name__}; expected a number or a string")
        checked[key] = value
    return checked


def _fail(path, what):
    raise DumpError(f"{path}: {what}")


def _vec(v):
    return np.array([float(v[0]), float(v[1]), float(v[2])])


def _rot(ori, v):
    """Quaternion ``ori`` (YADE's) applied to the vector v."""
    from yade.minieigenHP import Vector3
    return _vec(ori * Vector3(float(v[0]), float(v[1]), float(v[2])))


def _dump(path, young_pa, poisson, density, walls_mode, wall_names, pressure_pa, seed, gaps,
          extra, quiet):
    """What dump() does, phase by phase (each refuses in one line, DumpError): the call's
    target, the bodies, the periodic cell, the wall planes, the contacts, the walls' names, the
    domain and solid fraction, the material, the pressure, the force-law check; then the
    attributes, the file (_write_file) and the summary it returns."""
    import yade
    from yade.wrapper import Omega
    O = Omega()
    t0 = time.time()
    _check_target(path, O, walls_mode, wall_names)
    spheres, wall_bodies, index, raw, radius, yade_id, phase = _bodies(path, O)
    n = len(spheres)
    inferred = []
    periodic, hsize, position = _periodic_cell(path, O, raw, walls_mode, wall_bodies)
    walls, body_wall, box_faces = _wall_planes(path, position, radius, walls_mode, periodic,
                                               wall_bodies, inferred)
    (pair, p_over, p_force, p_branch, p_yade, w_part, w_wall, w_over, w_force, w_yade,
     phys_kinds, linear_kn, clipped, merged) = _contacts(
        path, O, index, raw, radius, position, periodic, hsize, walls_mode, gaps, walls,
        body_wall, box_faces)
    walls, w_wall = _name_walls(path, walls, w_wall, wall_names)
    lo, hi, solid_fraction, touching, mean_z = _domain(
        path, position, radius, periodic, hsize, walls, w_part, w_wall, w_over, pair, p_over,
        yade_id, inferred)
    young_pa, poisson, density, laws, hertz, linear = _material(
        path, O, spheres[0].material, phys_kinds, young_pa, poisson, density, inferred)
    if pressure_pa is None:
        pressure_pa = _pressure(periodic, walls, w_wall, w_force, lo, hi, inferred)
    law = _law_check(hertz, linear, phys_kinds, linear_kn, pair, radius, p_force, p_over,
                     touching, young_pa, poisson)

    over_diff = np.abs(np.concatenate([p_over - np.array(p_yade, float),
                                       w_over - np.array(w_yade, float)]))
    script = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else "?"
    out_attrs = dict(
        generator=GENERATOR, seed=int(seed), solid_fraction=solid_fraction,
        mean_coordination=mean_z, pressure_pa=float(pressure_pa), young_pa=float(young_pa),
        poisson=float(poisson), density=float(density),
        source=f"YADE script {script}", yade_version=str(yade.config.version),
        yade_iteration=int(O.iter), yade_time_s=float(O.time), yade_dt_s=float(O.dt),
        contact_law=", ".join(laws) or "none", contact_phys=", ".join(
            f"{k} ({v})" for k, v in sorted(phys_kinds.items())) or "none",
        overlap_source="positions (r_i + r_j - |branch|; walls: r - distance to the plane)",
        overlap_vs_yade_max_m=float(over_diff.max()) if over_diff.size else 0.0,
        tensile_contacts_clipped=int(clipped),
        # YADE interactions of one sphere with several facets of one plane, merged (force summed)
        wall_interactions_merged=int(merged),
        inferred="; ".join(inferred) if inferred else "none",
        wall_seconds=time.time() - t0,
    )
    out_attrs.update(law)
    out_attrs.update(extra)
    _write_file(path, position, radius, phase, pair, p_over, p_force, p_branch, walls, w_part,
                w_wall, w_over, w_force, lo, hi, periodic, out_attrs, yade_id)
    summary = dict(n_particles=n, n_contacts=int(touching.sum()), n_wall_contacts=len(w_part),
                   walls=[w["name"] for w in walls], solid_fraction=solid_fraction,
                   mean_coordination=mean_z, pressure_pa=float(pressure_pa),
                   inferred=inferred, **law)
    if not quiet:
        line = _check.describe(out_attrs)
        print(f"tdem_yade: wrote {path}: N {n}, contacts {summary['n_contacts']}, wall contacts "
              f"{len(w_part)} ({', '.join(summary['walls']) or 'no walls'}), phi "
              f"{solid_fraction:.4f}, Z {mean_z:.3f}, p {pressure_pa:.4g} Pa; force law {line}",
              flush=True)
    return summary


def _write_file(path, position, radius, phase, pair, p_over, p_force, p_branch, walls, w_part,
                w_wall, w_over, w_force, lo, hi, periodic, attrs, yade_id):
    """The packing file through the one writer (thermal_kernel/packing_h5.py), with the contact
    radii sqrt(R* overlap) (R* = r_i r_j / (r_i + r_j); against a wall R* = r). Built in memory,
    then written at once under <path>.tmp and renamed: a full or read-only disk is one OSError
    (one line here), and no file is left."""
    wall_rows = [dict(name=w["name"], kind=w["kind"], point=w["point"], normal=w["normal"],
                      radius=w["radius"]) for w in walls]
    r_star = np.zeros(len(p_over))
    if len(p_over):
        r_i, r_j = radius[pair[:, 0]], radius[pair[:, 1]]
        r_star = r_i * r_j / (r_i + r_j)
    try:
        image = _writer.packing_image(
            position, radius, phase, pair, p_over, p_force, p_branch, wall_rows, w_part,
            w_wall, w_over, w_force, lo, hi, (periodic,) * 3, attrs,
            contact_radius=np.sqrt(r_star * np.clip(p_over, 0, None)),
            wall_contact_radius=np.sqrt(radius[w_part] * np.clip(w_over, 0, None)),
            yade_id=yade_id)
        _writer.write_bytes_atomic(path, image)
    except OSError as e:
        _fail(path, f"cannot write the file: {e.strerror or e}")


def _add_wall(walls, point, normal, body_id):
    """A plane wall appended to ``walls`` (its name given later); its index."""
    walls.append(dict(name=None, kind="plane", point=np.asarray(point, float),
                      normal=np.asarray(normal, float), radius=math.nan, body=body_id))
    return len(walls) - 1


def _check_target(path, O, walls_mode, wall_names):
    """The file name, its folder, walls= and the bodies wall_names= names."""
    if walls_mode not in ("auto", "none"):
        _fail(path, f"walls: expected 'auto' or 'none', got {walls_mode!r}")
    if os.path.isdir(path):
        _fail(path, "is a folder; expected a packing file name (packing.h5)")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        _fail(path, f"the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        _fail(path, f"the folder {folder} is not writable")
    if walls_mode == "none" and wall_names:
        _fail(path, "wall_names given with walls='none' (no wall is written)")
    for body_id in wall_names:             # each named body must be a wall body of the scene
        body = O.bodies[body_id] if 0 <= body_id < len(O.bodies) else None
        if body is None:
            _fail(path, f"wall_names: body {body_id}: no such body in the scene "
                        f"({len(O.bodies)} bodies)")
        shape = type(body.shape).__name__ if body.shape is not None else "None"
        if shape not in WALL_SHAPES:
            _fail(path, f"wall_names: body {body_id} is a {shape}, not a wall body "
                        f"({', '.join(WALL_SHAPES)}); expected the id of a wall, e.g. "
                        "{lid.id: 'plate'}")


def _bodies(path, O):
    """The spheres (refusing clumps and other shapes), the wall bodies, and the spheres'
    positions, radii, YADE ids and phases (their materials in id order)."""
    spheres, wall_bodies = [], []
    for b in O.bodies:
        if b is not None and b.isClump:
            members = len(b.shape.members)
            _fail(path, f"body {b.id} is a clump of {members} spheres: the format holds single "
                        "spheres, a clump would need its members' rigid link and a conductance "
                        "inside the clump (release it: O.bodies.releaseFromClump, or dump before "
                        "clumping)")
    for b in O.bodies:
        if b is None:
            continue
        shape = type(b.shape).__name__ if b.shape is not None else "None"
        if shape == "Sphere":
            if b.isClumpMember:
                _fail(path, f"body {b.id} is a member of clump {b.clumpId}: the format holds "
                            "free spheres only (release the clump first)")
            spheres.append(b)
        elif shape in WALL_SHAPES:
            wall_bodies.append(b)
        else:
            _fail(path, f"body {b.id} has shape {shape}: the format holds spheres (and plane "
                        f"walls) only; a {shape} particle would need its surface and contact "
                        "geometry, for which the format has no field")
    if not spheres:
        _fail(path, "the scene has no spheres (utils.sphere bodies) to dump")
    index = {b.id: k for k, b in enumerate(spheres)}
    raw = np.array([_vec(b.state.pos) for b in spheres])
    radius = np.array([float(b.shape.radius) for b in spheres])
    bad = np.flatnonzero(~np.all(np.isfinite(raw), axis=1))
    if bad.size:
        b = spheres[int(bad[0])]
        _fail(path, f"body {b.id} has position {np.round(raw[bad[0]], 12).tolist()}: expected "
                    "finite numbers (a sphere that left the simulation? NaN from a blown-up "
                    "step?)")
    bad = np.flatnonzero(~(np.isfinite(radius) & (radius > 0)))
    if bad.size:
        _fail(path, f"body {spheres[int(bad[0])].id} has radius {radius[bad[0]]!r}: expected a "
                    "finite radius > 0")
    yade_id = np.array([b.id for b in spheres], dtype=np.int64)
    mat_ids = [b.material.id if b.material is not None else -1 for b in spheres]
    phase_of = {m: k for k, m in enumerate(sorted(set(mat_ids)))}
    phase = np.array([phase_of[m] for m in mat_ids], dtype=np.int32)
    return spheres, wall_bodies, index, raw, radius, yade_id, phase


def _periodic_cell(path, O, raw, walls_mode, wall_bodies):
    """(periodic, hSize, positions wrapped into the cell)."""
    periodic = bool(O.periodic)
    hsize = None
    if periodic:
        h = np.array([[float(O.cell.hSize[i, j]) for j in range(3)] for i in range(3)])
        if np.max(np.abs(h - np.diag(np.diag(h)))) > 1e-12 * np.max(np.abs(h)):
            _fail(path, "O.cell.hSize is sheared (off-diagonal terms): the format's periodic "
                        "domain is an axis-aligned box; dump before shearing or with an "
                        "orthogonal cell")
        hsize = h
        cell = np.diag(h).copy()
        position = raw - np.floor(raw / cell) * cell
        position[position >= cell] = 0.0
        if walls_mode == "auto" and wall_bodies:
            _fail(path, f"body {wall_bodies[0].id}: walls in a periodic cell are not "
                        "represented (the format's walls bound a non-periodic axis); use "
                        "walls='none'")
    else:
        position = raw.copy()
    return periodic, hsize, position


def _wall_planes(path, position, radius, walls_mode, periodic, wall_bodies, inferred):
    """The planes of the wall bodies (Wall; coplanar Facets as one plane; the faces of a Box
    the spheres face): the wall list, body id -> wall, Box body -> its faces."""
    n = len(radius)
    walls = []              # dicts: name, kind, point, normal, radius
    body_wall = {}          # body id -> wall index (Wall, Facet)
    box_faces = {}          # body id -> list of (wall index or None, point, outward normal)
    rmax = float(radius.max())

    def side_normal(point, normal, body_id):
        """The plane's normal oriented towards the spheres; refuse spheres on both sides."""
        s = (position - point) @ normal
        pos_side = np.count_nonzero(s > -radius)
        neg_side = np.count_nonzero(s < radius)
        if pos_side == n:
            return normal
        if neg_side == n:
            return -normal
        _fail(path, f"body {body_id}: spheres on both sides of its plane (point "
                    f"{np.round(point, 9).tolist()}, normal {np.round(normal, 9).tolist()}): "
                    "the format's plane wall bounds the domain on one side")

    def add_wall(point, normal, body_id):
        return _add_wall(walls, point, normal, body_id)

    if walls_mode == "auto" and not periodic:
        facets = []
        for b in wall_bodies:
            shape = type(b.shape).__name__
            if shape == "Wall":
                axis = int(b.shape.axis)
                normal = np.zeros(3)
                normal[axis] = 1.0
                point = np.zeros(3)
                point[axis] = float(b.state.pos[axis])
                body_wall[b.id] = add_wall(point, side_normal(point, normal, b.id), b.id)
            elif shape == "Facet":
                v = [_vec(b.state.pos) + _rot(b.state.ori, x) for x in b.shape.vertices]
                normal = np.cross(v[1] - v[0], v[2] - v[0])
                normal /= np.linalg.norm(normal)
                facets.append((b.id, v[0], side_normal(v[0], normal, b.id)))
            else:  # Box: six faces; kept when every sphere faces them (or one touches them)
                faces = []
                c = _vec(b.state.pos)
                for axis in range(3):
                    e = np.zeros(3)
                    e[axis] = 1.0
                    out = _rot(b.state.ori, e)
                    ext = float(b.shape.extents[axis])
                    for sign in (1.0, -1.0):
                        point, normal = c + sign * ext * out, sign * out
                        facing = np.all((position - point) @ normal > -radius)
                        faces.append([add_wall(point, normal, b.id) if facing else None,
                                      point, normal])
                box_faces[b.id] = faces
        # coplanar facets -> one plane
        scale = max(1.0, float(np.abs(position).max()) + rmax)
        groups = []
        for body_id, point, normal in facets:
            for g in groups:
                if np.dot(g[1], normal) > 1 - 1e-9 and abs(np.dot(point - g[0], normal)) \
                        < 1e-9 * scale:
                    g[2].append(body_id)
                    break
            else:
                groups.append((point, normal, [body_id]))
        for point, normal, ids in groups:
            w = add_wall(point, normal, ids[0])
            walls[w]["bodies"] = ids
            for body_id in ids:
                body_wall[body_id] = w
    elif walls_mode == "none" and wall_bodies:
        inferred.append(f"walls: none: {len(wall_bodies)} wall bodies and their contacts left "
                        "out")
    return walls, body_wall, box_faces


def _contacts(path, O, index, raw, radius, position, periodic, hsize, walls_mode, gaps, walls,
              body_wall, box_faces):
    """The sphere-sphere and sphere-wall rows of YADE's real interactions (overlaps from the
    positions, YADE's normal forces; a sphere on two facets of one plane: one row)."""
    pair, p_over, p_force, p_branch, p_yade = [], [], [], [], []
    w_part, w_wall, w_over, w_force, w_yade = [], [], [], [], []
    phys_kinds = {}
    linear_kn = []
    clipped = merged = 0
    wall_row = {}                # (particle, wall) -> row: one row per sphere and plane
    for i in O.interactions.all():
        if not i.isReal:
            continue
        a, b = i.id1, i.id2
        ia, ib = index.get(a), index.get(b)
        if ia is None and ib is None:
            continue
        other = b if ia is not None and ib is None else a if ib is not None and ia is None \
            else None
        if other is not None and (walls_mode == "none" or periodic):
            continue
        geom_name = type(i.geom).__name__
        if not hasattr(i.geom, "penetrationDepth"):
            _fail(path, f"interaction ({a}, {b}) has geometry {geom_name}: expected ScGeom "
                        "(Ig2_*_ScGeom functors), whose penetration depth and normal the dump "
                        "reads")
        phys_name = type(i.phys).__name__
        phys_kinds[phys_name] = phys_kinds.get(phys_name, 0) + 1
        force = float(np.dot(_vec(i.phys.normalForce), _vec(i.geom.normal)))
        depth_yade = float(i.geom.penetrationDepth)
        if other is None:                              # sphere - sphere
            if ia > ib:
                ia, ib = ib, ia
                a, b = b, a
            branch = _branch(i, a, raw[ib] - raw[ia], hsize if periodic else None)
            overlap = radius[ia] + radius[ib] - float(np.linalg.norm(branch))
            if overlap <= 0 and not gaps:
                continue
            if force < 0:
                clipped += 1
            force = max(force, 0.0) if overlap > 0 else 0.0
            pair.append((ia, ib))
            p_over.append(overlap)
            p_force.append(force)
            p_branch.append(branch)
            p_yade.append(depth_yade)
            if phys_name not in HERTZ_PHYS and hasattr(i.phys, "kn"):
                linear_kn.append((len(pair) - 1, float(i.phys.kn)))
        else:                                          # sphere - wall body
            k = ia if ia is not None else ib
            w = _wall_of(O.bodies[other], position[k], walls, body_wall, box_faces)
            dist = float((position[k] - walls[w]["point"]) @ walls[w]["normal"])
            overlap = radius[k] - dist
            if overlap <= 0 and not gaps:
                continue
            if force < 0:
                clipped += 1
            force = max(force, 0.0) if overlap > 0 else 0.0
            row = wall_row.get((k, w))
            if row is not None:          # a sphere on the edge of two facets of one plane:
                w_force[row] += force    # YADE applies both forces; one contact, their sum
                w_yade[row] = max(w_yade[row], depth_yade)
                merged += 1
                continue
            wall_row[(k, w)] = len(w_part)
            w_part.append(k)
            w_wall.append(w)
            w_over.append(overlap)
            w_force.append(force)
            w_yade.append(depth_yade)

    pair = np.array(pair, dtype=np.int64).reshape(-1, 2)
    p_over = np.array(p_over, float)
    p_force = np.array(p_force, float)
    p_branch = np.array(p_branch, float).reshape(-1, 3)
    w_part = np.array(w_part, dtype=np.int64)
    w_over = np.array(w_over, float)
    w_force = np.array(w_force, float)
    return (pair, p_over, p_force, p_branch, p_yade, w_part, w_wall, w_over, w_force, w_yade,
            phys_kinds, linear_kn, clipped, merged)


def _branch(i, a, branch, hsize):
    """The branch vector of interaction ``i`` from sphere ``a``, across the periodic cell
    (``hsize``; None: not periodic) by YADE's cellDist."""
    if hsize is None:
        return branch
    dist = np.array([int(x) for x in i.cellDist], float)
    sign = 1.0 if a == i.id1 else -1.0
    return branch + sign * (hsize @ dist)


def _wall_of(body, centre, walls, body_wall, box_faces):
    """The wall (index) a wall body's contact with the sphere at ``centre`` is on: a Box's
    face the sphere faces most (made a wall when first touched), else the body's plane."""
    if type(body.shape).__name__ != "Box":
        return body_wall[body.id]
    faces = box_faces[body.id]
    best = int(np.argmax([float((centre - f[1]) @ f[2]) for f in faces]))
    if faces[best][0] is None:
        faces[best][0] = _add_wall(walls, faces[best][1], faces[best][2], body.id)
    return faces[best][0]


def _name_walls(path, walls, w_wall, wall_names):
    """The walls kept (used, named or axis-normal), renumbered and named."""
    used = set(w_wall)
    keep = [k for k, w in enumerate(walls)
            if k in used or w["body"] in wall_names or _axis_of(w["normal"]) is not None
            or any(b in wall_names for b in w.get("bodies", ()))]
    renumber = {old: new for new, old in enumerate(keep)}
    walls = [walls[k] for k in keep]
    w_wall = np.array([renumber[w] for w in w_wall], dtype=np.int32)
    given_of, auto_of = [], []
    for k, w in enumerate(walls):
        ids = [w["body"]] + list(w.get("bodies", ()))
        given_of.append(next(((b, wall_names[b]) for b in ids if b in wall_names), None))
        axis = _axis_of(w["normal"])
        auto_of.append(f"{'xyz'[axis]}{'min' if w['normal'][axis] > 0 else 'max'}"
                       if axis is not None else f"plane_{k}")
    named = {g[0] for g in given_of if g is not None}
    for body_id in wall_names:
        if body_id not in named:
            _fail(path, f"wall_names: body {body_id} makes no wall of the file (its planes face "
                        "no sphere); expected the id of a wall the spheres touch or face")
    for k, g in enumerate(given_of):
        if g is None:
            continue
        clash = next((m for m in range(len(walls)) if m != k and given_of[m] is None
                      and auto_of[m] == g[1]), None)
        if clash is not None:
            _fail(path, f"wall_names: body {g[0]} named {g[1]!r}, the name of another wall "
                        f"(the plane of body {walls[clash]['body']}, normal "
                        f"{np.round(walls[clash]['normal'], 9).tolist()}); expected a name no "
                        "other wall has")
    taken = set()
    for k, w in enumerate(walls):
        name = given_of[k][1] if given_of[k] is not None else auto_of[k]
        base, j = name, 2
        while name in taken:
            name, j = f"{base}_{j}", j + 1
        taken.add(name)
        w["name"] = name
    return walls, w_wall


def _domain(path, position, radius, periodic, hsize, walls, w_part, w_wall, w_over, pair,
            p_over, yade_id, inferred):
    """(lo, hi, solid fraction, touching, mean Z): thermal_kernel/packing_stats.py; refuses
    unlisted overlaps and a solid fraction above 1."""
    n = len(radius)
    planes = [(w["name"], axis, "min" if w["normal"][axis] > 0 else "max", w["point"][axis])
              for w in walls for axis in (_axis_of(w["normal"]),) if axis is not None]
    lo, hi, free = _stats.domain_box(position, radius, planes, (periodic,) * 3, np.zeros(3),
                                     np.diag(hsize) if periodic else None)
    if free:
        inferred.append(free)
    bounding = np.array([_axis_of(walls[w]["normal"]) is not None for w in w_wall], bool)
    solid_fraction = _stats.solid_fraction(radius, lo, hi, radius[w_part][bounding],
                                           w_over[bounding])
    _unlisted_overlaps(path, position, radius, yade_id, pair, hsize if periodic else None)
    if solid_fraction > 1.0:
        _fail(path, f"the spheres' volume is {solid_fraction:.4g} times the domain's: a solid "
                    "fraction above 1 (overlapping spheres, or a scene that never ran?)")
    touching = p_over > 0
    mean_z = 2.0 * int(touching.sum()) / n
    return lo, hi, solid_fraction, touching, mean_z


def _material(path, O, mat, phys_kinds, young_pa, poisson, density, inferred):
    """young_pa, poisson and density (given, else the spheres' material, recorded as inferred),
    the engines' contact laws and the counts of Hertz and linear interactions."""
    hertz = sum(v for k, v in phys_kinds.items() if k in HERTZ_PHYS)
    linear = sum(v for k, v in phys_kinds.items() if k in LINEAR_PHYS)
    if young_pa is None:
        if mat is None or not hasattr(mat, "young"):
            _fail(path, "young_pa: not given and the spheres' material has no 'young'; pass "
                        "young_pa=...")
        young_pa = float(mat.young)
        inferred.append(f"young_pa: the spheres' material young ({young_pa:.6g} Pa)")
    laws = []
    for e in O.engines:
        if type(e).__name__ == "InteractionLoop":
            laws += [type(f).__name__ for f in e.lawDispatcher.functors]
    if poisson is None:
        # FrictMat's poisson is Poisson's ratio only under Hertz-Mindlin; under a linear law
        # (Cundall-Strack, cohesive ...) it is k_s/k_n. Known from the interactions, or, before
        # any contact exists, from the engines' contact laws.
        mindlin = hertz > 0 if phys_kinds else any("Mindlin" in x for x in laws)
        if linear or not mindlin:
            what = ("linear (" + ", ".join(sorted(k for k in phys_kinds if k in LINEAR_PHYS))
                    + ")") if linear else ("not Hertz-Mindlin (contact laws: "
                                           + (", ".join(laws) or "none") + ")")
            _fail(path, f"poisson: not given, and the contact law is {what}: FrictMat "
                        "'poisson' is Poisson's ratio only for Hertz-Mindlin (k_s/k_n for a "
                        "linear law); pass poisson=...")
        if mat is None or not hasattr(mat, "poisson"):
            _fail(path, "poisson: not given and the spheres' material has no 'poisson'; pass "
                        "poisson=...")
        poisson = float(mat.poisson)
        inferred.append(f"poisson: the spheres' material poisson ({poisson:.6g})")
    if density is None:
        if mat is None or not hasattr(mat, "density"):
            _fail(path, "density: not given and the spheres' material has none; pass "
                        "density=...")
        density = float(mat.density)
        inferred.append(f"density: the spheres' material density ({density:.6g} kg/m^3)")
    for key, value in (("young_pa", young_pa), ("density", density)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            _fail(path, f"{key}: expected a finite number > 0, got {value!r}")
    if not (isinstance(poisson, (int, float)) and -1.0 < poisson < 0.5):
        _fail(path, f"poisson: expected Poisson's ratio in (-1, 0.5), got {poisson!r}"
                    + (" (the spheres' material)" if any(x.startswith("poisson:")
                                                        for x in inferred) else ""))
    return young_pa, poisson, density, laws, hertz, linear


def _pressure(periodic, walls, w_wall, w_force, lo, hi, inferred):
    """The confining pressure when not given: the cell's mean stress, else the walls'."""
    if periodic:
        from yade import utils
        s = utils.getStress()
        pressure_pa = -float(s[0, 0] + s[1, 1] + s[2, 2]) / 3.0
        if pressure_pa >= 0:
            inferred.append("pressure_pa: -trace/3 of utils.getStress() (the cell's mean "
                            "stress)")
        else:
            inferred.append(f"pressure_pa: NaN (the cell's mean stress is tensile: "
                            f"-trace/3 of utils.getStress() = {pressure_pa:.6g} Pa; no "
                            "confining pressure)")
            pressure_pa = math.nan
    else:
        pressure_pa, how = _stats.wall_pressure(
            [(w["name"], _axis_of(w["normal"])) for w in walls], w_wall, w_force, lo, hi)
        inferred.append(f"pressure_pa: {how}" if how else
                        "pressure_pa: NaN (no periodic cell, no axis-normal wall)")
    return pressure_pa


def _law_check(hertz, linear, phys_kinds, linear_kn, pair, radius, p_force, p_over, touching,
               young_pa, poisson):
    """The force-law attributes: Hertz (thermal_kernel/packing_stats.py), linear k_n delta with
    YADE's k_n, or not checked."""
    if hertz >= linear and hertz:
        law = _stats.hertz_check(p_force[touching], radius[pair[touching, 0]],
                                 radius[pair[touching, 1]], p_over[touching], young_pa, poisson,
                                 "hertz (E* from young_pa, poisson; particle-particle contacts)")
    elif linear:
        kn = np.zeros(len(p_over))
        for c, value in linear_kn:
            kn[c] = value
        law = _check.check(p_force[touching], (kn * np.clip(p_over, 0, None))[touching],
                           "linear (k_n delta, YADE's k_n per contact; particle-particle)")
    else:
        law = {"force_law": "unknown (" + ", ".join(sorted(phys_kinds)) + "): not checked"
               if phys_kinds else "none (no contacts)", "force_law_contacts": 0}
    return law


def _unlisted_overlaps(path, position, radius, yade_id, pair, hsize):
    """Refuse two spheres overlapping by more than UNLISTED_OVERLAP_RTOL of the smaller radius
    with no YADE interaction between them (scipy's k-d tree; skipped without scipy)."""
    try:
        from scipy.spatial import cKDTree
    except ImportError:        # Debian's YADE comes with python3-scipy; be safe without it
        return
    if len(radius) < 2:
        return
    box = None
    if hsize is not None:
        box = np.diag(hsize).copy()
        if np.any(4.0 * radius.max() > box):
            return             # a cell thinner than two diameters: the image is ambiguous
    tree = cKDTree(position, boxsize=box)
    cand = tree.query_pairs(2.0 * float(radius.max()), output_type="ndarray").astype(np.int64)
    if not cand.size:
        return
    cand.sort(axis=1)
    a, b = cand[:, 0], cand[:, 1]
    d = position[b] - position[a]
    if box is not None:
        d -= box * np.round(d / box)
    r_min = np.minimum(radius[a], radius[b])
    over = radius[a] + radius[b] - np.linalg.norm(d, axis=1)
    deep = np.flatnonzero(over > UNLISTED_OVERLAP_RTOL * r_min)
    if not deep.size:
        return
    n = len(radius)
    listed = set((pair[:, 0] * n + pair[:, 1]).tolist())
    for k in deep[np.argsort(-over[deep] / r_min[deep], kind="stable")]:
        if int(a[k] * n + b[k]) not in listed:
            _fail(path, f"bodies {int(yade_id[a[k]])} and {int(yade_id[b[k]])} overlap by "
                        f"{over[k]:.6g} m (radii {radius[a[k]]:.6g}, {radius[b[k]]:.6g} m) with "
                        "no YADE interaction between them: the collider has not seen them (run "
                        "at least one step, O.run(1, True), before dump) or they were put in "
                        "one place")


def _axis_of(normal):
    return _stats.axis_of(normal, AXIS_TOL)
