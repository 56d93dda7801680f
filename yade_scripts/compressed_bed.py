"""Gravity-settled cylindrical bed compressed by a top plate (pipe-model paper 003, sec. 4.2).

    env -u VIRTUAL_ENV -u PYTHONPATH yade -n -j1 -x yade_scripts/compressed_bed.py PARAMS.json

PARAMS.json holds the keys of ``yade_scripts/bed_params.py`` (missing ones take the defaults);
``tdem pack`` writes it from a scene's [pack] table. Writes into ``output_dir``:

- ``settled.yade.gz`` and ``settled.h5``: the bed after settling under gravity (reused by a later
  run with ``reuse_settled = true``); ``settled.h5`` records the modulus it was settled with in
  ``young_pa_used`` (the softened one, see below) and is not meant for force-based laws;
- ``packing_<p>Pa.h5`` for every target pressure p (``%.4g``, e.g. ``packing_1.6e+06Pa.h5``),
  always relaxed at the real modulus: ``young_pa_used == young_pa``.

What it does, and why (measured figures in the report / docs):

1. A random, non-overlapping cloud (solid fraction ``cloud_solid_fraction``) fills the cylinder.
2. It settles under gravity with a softened modulus ``settle_young_pa`` (the critical time step
   grows as E^-1/2), first with little numerical damping (free fall), then with ``settle_damping``
   (default 0.7, stronger than the 0.4 of the loading stages: the bed only has to come to rest)
   and an adaptive time step (GlobalStiffnessTimeStepper: the real contact stiffness, much softer
   than the P-wave bound at low stress) until the unbalanced-force ratio is below the target.
   Every stage uses that stepper with ``timestep_safety`` (default 0.8, YADE's own default).
3. The top plate is driven down (kinematic) at the speed v_I at which the inertial number
   I = (v/H) d sqrt(rho_eff/p_ref) equals ``inertial_number`` (H the bed height, d the mean
   diameter, rho_eff the scaled density, p_ref = max(plate pressure, weight of the bed / plate
   area); default 3e-3; ``soft_inertial_number``, default 1e-2, while the modulus is softened,
   a state that is re-relaxed at the real modulus before any dump) until the plate pressure is
   90 % of the target. Then the plate is set free along z
   (mass = the bed's mass) and carries the target force as a dead load, its speed limited to
   v_I / 2: the bed relaxes under a constant plate load and the pressure converges to the target
   by itself.
4. Softening is confined to the start. The softened bed is loaded only to a preload
   (``preload_fraction`` x the first pressure, default 10 %; with the modulus first raised under
   gravity, if needed, so that the mean overlap there stays <= 2 % of r: E* >= 6000 p), and
   re-stiffened to the real modulus under that constant load (modulus x ``stiffen_factor`` per
   step, default 10: three steps from 5e7 to 5e10 Pa; every existing contact updated, the bed
   relaxed between steps; shared/FINDINGS.md:
   a softened network must be re-relaxed at the real stiffness). A network softened and
   re-stiffened under load keeps some lateral (cylinder) stress; loading on to the first
   pressure at the real modulus dilutes it (on the 2,000 bed at 0.28 bar, preloading at 10 %
   instead of re-stiffening at the target brought the bottom-wall pressure from above to below
   the plate pressure + weight and the cylinder/plate pressure ratio from 0.84 to 0.71).
5. At each target the bed is relaxed until |p - p_t| < ``pressure_tolerance`` p_t and YADE's
   unbalanced-force ratio (over the particles) < ``unbalanced_force_target``; then the packing is
   dumped and the plate is driven on to the next (higher) pressure from that state, at the real
   modulus.

Mass scaling: ``density_scaling`` S multiplies the masses and divides gravity, so the weights and
every static state are unchanged; it only stretches the time scale (the number of steps of every
stage stays the same), and it enters the inertial number through rho_eff = S rho.

Walls. Bottom and plate are YADE ``Wall`` planes; the cylinder is a prism of
``cylinder_segments`` full-height boxes whose cross-section has the area of the circle of radius
R_c (so the plate pressure F/(pi R_c^2) is exact). YADE's Hertz-Mindlin law gives a wall contact
the radius r/2 (Ig2_Wall_Sphere / Ig2_Box_Sphere set both contact radii to r), while a sphere on
a plane has R* = r; the simulated wall material therefore has a modulus E_w,sim chosen so that
4/3 E*_sim sqrt(r/2) = 4/3 E*(particle, real wall) sqrt(r): every dumped wall contact follows Hertz
with R* = r and the real particle/wall E* (the attribute ``wall_young_pa_simulated`` records it).
A particle near an edge between two boxes can touch both; each such contact is a row of its own
(wall index of ``cylinder``) in ``wall_contacts``.

Dumped contacts: pairs that overlap at the dumped positions (touching contacts only).
``overlap`` is r_i + r_j - |branch| from the dumped positions (plates: r - distance; cylinder
boxes: YADE's penetration depth), so |branch| = r_i + r_j - overlap holds exactly (YADE's own
depth is one step older); ``normal_force`` = kno * overlap^1.5 with YADE's Hertz coefficient kno
(checked against 4/3 E* sqrt(R*) at the dump), i.e. the elastic force; the viscous part of the
contact damping, zero at rest, is left out. Standard library + numpy + h5py + yade only.
"""
import json
import math
import os
import sys
import time

import numpy as np

if __name__ == "__main__":       # run by YADE (yade -x): the package yade_scripts is importable
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))

from yade_scripts import params as tdem_params  # noqa: E402
from yade_scripts.bed_geometry import (  # noqa: E402
    damping_ratio, dump_contacts, hertz_moduli, pressure_name, prism, random_cloud,
    wall_sim_modulus)
from yade_scripts.tdem_dump import write_packing  # noqa: E402

# YADE's names, bound by import_yade() when the script runs: importing this file needs no YADE.
yade = utils = O = Vector3 = Quaternion = None
FrictMat = ForceResetter = InsertionSortCollider = Bo1_Sphere_Aabb = Bo1_Box_Aabb = None
Bo1_Wall_Aabb = InteractionLoop = Ig2_Sphere_Sphere_ScGeom = Ig2_Box_Sphere_ScGeom = None
Ig2_Wall_Sphere_ScGeom = Ip2_FrictMat_FrictMat_MindlinPhys = None
Law2_ScGeom_MindlinPhys_Mindlin = NewtonIntegrator = GlobalStiffnessTimeStepper = None
MatchMaker = None


def import_yade():
    """Import YADE (only possible inside Debian's yade) and bind its names in this module."""
    global yade, utils, O, Vector3, Quaternion, FrictMat, ForceResetter, \
        InsertionSortCollider, Bo1_Sphere_Aabb, Bo1_Box_Aabb, Bo1_Wall_Aabb, InteractionLoop, \
        Ig2_Sphere_Sphere_ScGeom, Ig2_Box_Sphere_ScGeom, Ig2_Wall_Sphere_ScGeom, \
        Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin, NewtonIntegrator, \
        GlobalStiffnessTimeStepper, MatchMaker
    import yade
    from yade import utils
    from yade.wrapper import (
        Omega, FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb, Bo1_Box_Aabb,
        Bo1_Wall_Aabb, InteractionLoop, Ig2_Sphere_Sphere_ScGeom, Ig2_Box_Sphere_ScGeom,
        Ig2_Wall_Sphere_ScGeom, Ip2_FrictMat_FrictMat_MindlinPhys,
        Law2_ScGeom_MindlinPhys_Mindlin, NewtonIntegrator, GlobalStiffnessTimeStepper,
        MatchMaker)
    from yade.minieigenHP import Vector3, Quaternion
    O = Omega()


GENERATOR = "yade_scripts/compressed_bed.py"
# Parameters that define the settled bed; a saved one is reused only if all of them match.
SETTLE_KEYS = ("n_particles", "particle_radius_m", "radius_spread", "cylinder_radius_m",
               "cylinder_segments", "density", "young_pa", "poisson", "restitution", "friction",
               "wall_young_pa", "wall_poisson", "wall_friction", "gravity_m_s2",
               "settle_young_pa", "density_scaling", "damping", "settle_damping",
               "unbalanced_force_target",
               "timestep_safety", "cloud_solid_fraction", "seed")
CHUNK = 10            # steps between two plate updates / convergence checks
APPROACH = 0.9        # the plate is driven (kinematic) up to this fraction of the target...
PLATE_MASS = 1.0      # ...then carries the target force as a dead load, mass = this x bed mass
# Softening is limited so that the mean overlap under the first target stays <= SOFT_OVERLAP x r:
# Hertz beds here have mean overlap / r ~ 3.3 (p / E*)^(2/3) (measured on the 7,500 bed), so the
# plate approaches the first target with E* >= p (3.3 / SOFT_OVERLAP)^1.5.
SOFT_OVERLAP = 0.02


def usage_error(message):
    """A bad parameter: one line on stderr, exit status 2."""
    sys.stderr.write(f"error: {message}\n")
    sys.stderr.flush()
    sys.exit(2)


def run_error(message):
    """The run itself failed (e.g. did not converge): one line on stderr, exit status 1."""
    sys.stdout.flush()
    sys.stderr.write(f"error: {message}\n")
    sys.stderr.flush()
    sys.exit(1)


# ----------------------------------------------------------------------------- parameters

def read_params():
    if len(sys.argv) != 2:
        usage_error("usage: yade -n -j1 -x compressed_bed.py PARAMS.json")
    try:
        p = tdem_params.read_params_json(sys.argv[1], "bed")
    except tdem_params.ParamError as e:
        usage_error(str(e))
    except OSError as e:
        usage_error(f"{sys.argv[1]}: cannot read the parameter file ({e.strerror})")
    except ValueError as e:
        usage_error(f"{sys.argv[1]}: not valid JSON ({e})")
    # (the cross-field checks ran in read_params_json: bed_params.check, as in tdem pack)
    return p


# ----------------------------------------------------------------------------- the bed

class Bed:
    def __init__(self, p):
        self.p = p
        self.t_start = time.time()
        self.area = math.pi * p["cylinder_radius_m"] ** 2
        self.scale = p["density_scaling"]
        self.rho_eff = p["density"] * self.scale
        self.d_mean = 2.0 * p["particle_radius_m"]
        self.last_print = 0.0
        self.dead_load = 0.0      # permanent z force applied to the plate (N)
        self.steps_at_last_dump = 0
        self.wall_at_last_dump = time.time()
        self.i_target = p["inertial_number"]
        self.soft_imax = 0.0      # largest inertial number while softened (not in a dump's I)

    # --- building ---------------------------------------------------------------------------
    def build(self):
        p = self.p
        n = p["n_particles"]
        vertex, apothem, half_side = prism(p["cylinder_radius_m"], p["cylinder_segments"])
        pos, radii, height = random_cloud(n, p["particle_radius_m"], p["radius_spread"],
                                          apothem, p["cloud_solid_fraction"], p["seed"])
        self.log(f"cloud: {n} spheres, radii {radii.min():.4g}..{radii.max():.4g} m, "
                 f"height {height:.4g} m, cylinder prism of {p['cylinder_segments']} boxes "
                 f"(apothem {apothem:.5g} m, vertex radius {vertex:.5g} m)")
        O.reset()
        e0 = p["settle_young_pa"]
        self.young_now = e0
        pmat = O.materials.append(FrictMat(
            young=e0, poisson=p["poisson"], density=self.rho_eff,
            frictionAngle=math.atan(p["friction"])))
        wmat = O.materials.append(FrictMat(
            young=self.wall_modulus(e0), poisson=p["wall_poisson"], density=self.rho_eff,
            frictionAngle=math.atan(p["wall_friction"])))
        ids = O.bodies.append([utils.sphere(tuple(x), float(r), material=pmat)
                               for x, r in zip(pos, radii)])
        assert ids == list(range(n))
        top = float(np.max(pos[:, 2] + radii)) + 2.0 * p["particle_radius_m"]
        thick = p["particle_radius_m"]
        boxes = []
        for k in range(p["cylinder_segments"]):
            th = 2.0 * math.pi * k / p["cylinder_segments"]
            centre = ((apothem + thick) * math.cos(th), (apothem + thick) * math.sin(th),
                      0.5 * top)
            boxes.append(utils.box(centre, (thick, half_side, 0.5 * top + thick),
                                   orientation=Quaternion((0, 0, 1), th), fixed=True,
                                   material=wmat))
        box_ids = O.bodies.append(boxes)
        bottom = O.bodies.append(utils.wall((0, 0, 0), axis=2, sense=1, material=wmat))
        plate = O.bodies.append(utils.wall((0, 0, top), axis=2, sense=-1, material=wmat))
        fa = math.atan(p["friction"])
        fw = math.atan(p["wall_friction"])
        newton = NewtonIntegrator(damping=p["damping"],
                                  gravity=(0, 0, -p["gravity_m_s2"] / self.scale))
        O.engines = [
            ForceResetter(),
            InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Box_Aabb(), Bo1_Wall_Aabb()],
                                  verletDist=0.2 * p["particle_radius_m"]),
            InteractionLoop(
                [Ig2_Sphere_Sphere_ScGeom(), Ig2_Box_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom()],
                [Ip2_FrictMat_FrictMat_MindlinPhys(
                    betan=MatchMaker(algo="val", val=damping_ratio(p["restitution"])),
                    betas=MatchMaker(algo="val", val=damping_ratio(p["restitution"])),
                    frictAngle=MatchMaker(matches=((pmat, pmat, fa), (pmat, wmat, fw),
                                                   (wmat, wmat, fw))))],
                [Law2_ScGeom_MindlinPhys_Mindlin()]),
            GlobalStiffnessTimeStepper(active=False, timeStepUpdateInterval=10,
                                       timestepSafetyCoefficient=p["timestep_safety"]),
            newton,
        ]
        O.tags["tdem_bed"] = json.dumps(dict(
            n=n, pmat=pmat, wmat=wmat, bottom=bottom, plate=plate, boxes=box_ids,
            apothem=apothem, vertex=vertex, settle={k: p[k] for k in SETTLE_KEYS}))
        self.attach()

    def attach(self):
        """Find bodies, materials and engines of the current scene (built or loaded)."""
        info = json.loads(O.tags["tdem_bed"])
        self.n = info["n"]
        self.pmat, self.wmat = O.materials[info["pmat"]], O.materials[info["wmat"]]
        self.bottom_id, self.plate_id = info["bottom"], info["plate"]
        self.box_ids = set(info["boxes"])
        self.wall_index = {self.bottom_id: 0, self.plate_id: 1}
        for b in self.box_ids:
            self.wall_index[b] = 2
        self.plate = O.bodies[self.plate_id]
        self.newton = next(e for e in O.engines if isinstance(e, NewtonIntegrator))
        self.stepper = next(e for e in O.engines if isinstance(e, GlobalStiffnessTimeStepper))
        self.young_now = self.pmat.young
        radii = np.array([O.bodies[i].shape.radius for i in range(self.n)])
        self.radii = radii
        self.d_mean = 2.0 * float(np.mean(radii))
        masses = 4.0 / 3.0 * math.pi * radii ** 3 * self.p["density"]
        self.bed_mass = float(np.sum(masses))
        self.weight = self.bed_mass * self.p["gravity_m_s2"]
        self.p_weight = self.weight / self.area

    def wall_modulus(self, young_now):
        p = self.p
        soft = young_now / p["young_pa"]
        return wall_sim_modulus(young_now, p["poisson"], p["wall_young_pa"] * soft,
                                p["wall_poisson"])

    # --- helpers ----------------------------------------------------------------------------
    def log(self, text):
        print(f"[bed {time.time() - self.t_start:7.1f} s] {text}", flush=True)

    def positions(self):
        return np.array([tuple(O.bodies[i].state.pos) for i in range(self.n)])

    def plate_pressure(self):
        """Contact force on the plate / plate area (O.forces includes the applied dead load)."""
        # (O.forces.permF segfaults in YADE 2023.02a while no permanent force was ever set)
        return (O.forces.f(self.plate_id)[2] - self.dead_load) / self.area

    def plate_height(self):
        return self.plate.state.pos[2]

    def drive_plate(self, v):
        """Kinematic plate moving down at speed v."""
        plate = self.plate
        if plate.dynamic:
            plate.dynamic = False
            self.dead_load = 0.0
            O.forces.setPermF(self.plate_id, Vector3(0, 0, 0))
        plate.state.blockedDOFs = "xyzXYZ"
        plate.state.vel = Vector3(0, 0, -v)

    def load_plate(self, target):
        """Free plate (vertical motion only) carrying the force target x area, its own weight
        compensated: at rest the plate pressure is the target exactly."""
        plate = self.plate
        mass = PLATE_MASS * self.bed_mass * self.scale
        vel = Vector3(plate.state.vel)
        plate.dynamic = True
        plate.state.blockedDOFs = "xyXYZ"
        plate.state.mass = mass
        plate.state.inertia = Vector3(1, 1, 1) * mass * self.d_mean ** 2
        plate.state.vel = vel
        g = self.p["gravity_m_s2"] / self.scale
        self.dead_load = -target * self.area + mass * g
        O.forces.setPermF(self.plate_id, Vector3(0, 0, self.dead_load))

    def unbalanced(self):
        """YADE's unbalanced-force ratio over the particles. A loaded plate is left out: its
        horizontal motion is blocked, so the friction of the top particles leaves a horizontal
        force on it that is not an imbalance (its vertical balance is the pressure criterion)."""
        plate = self.plate
        if not plate.dynamic:
            return utils.unbalancedForce()
        vel = Vector3(plate.state.vel)
        plate.dynamic = False          # (zeroes its velocity and frees nothing else)
        ratio = utils.unbalancedForce()
        plate.dynamic = True           # (resets blockedDOFs)
        plate.state.blockedDOFs = "xyXYZ"
        plate.state.vel = vel
        return ratio

    def plate_speed(self):
        """Downward plate speed."""
        return -self.plate.state.vel[2]

    def inertial_speed(self, p_now):
        """Plate speed at which I = (v/H) d sqrt(rho_eff/p_ref) equals the target of the stage
        (``inertial_number`` at the real modulus, ``soft_inertial_number`` while softened)."""
        p_ref = max(p_now, self.p_weight)
        return (self.i_target * self.plate_height() / self.d_mean
                * math.sqrt(p_ref / self.rho_eff))

    def inertial_number(self, v, p_now):
        p_ref = max(p_now, self.p_weight)
        return abs(v) / self.plate_height() * self.d_mean * math.sqrt(self.rho_eff / p_ref)

    def progress(self, stage, text, force=False):
        now = time.time()
        if force or now - self.last_print >= self.p["progress_seconds"]:
            self.last_print = now
            self.log(f"{stage:<12s} step {O.iter:>8d}  t {O.time:.4e} s  dt {O.dt:.2e} s  {text}")

    def use_stepper(self, on):
        if on:
            self.stepper.active = True
            self.stepper.timeStepUpdateInterval = 10
        else:
            self.stepper.active = False
            O.dt = self.p["timestep_safety"] * utils.PWaveTimeStep()

    def run(self, steps):
        # O.step() runs synchronously; O.run(n, True) polls and idles ~40 ms per call.
        for _ in range(steps):
            O.step()
        if not all(math.isfinite(c) for c in self.plate.state.pos) or not math.isfinite(O.dt):
            run_error("the simulation diverged (non-finite state); lower timestep_safety")

    # --- stages -----------------------------------------------------------------------------
    def settle(self):
        p = self.p
        self.use_stepper(False)
        # During the fall the adaptive step is capped at twice the P-wave-based one (impacts);
        # the dense part at the bottom, where the real contacts are soft, sets it.
        self.stepper.maxDt = 2.0 * O.dt
        self.stepper.active = True
        self.newton.damping = min(0.1, p["damping"])
        self.log(f"settling: modulus {self.young_now:.4g} Pa, time step <= {2 * O.dt:.3g} s "
                 f"during the fall, then unbounded, damping {p['damping']}")
        ek_peak, start = 0.0, O.iter
        while True:       # free fall until the kinetic energy has dropped to 1 % of its peak
            self.run(200)
            ek = utils.kineticEnergy()
            ek_peak = max(ek_peak, ek)
            top = max(O.bodies[i].state.pos[2] for i in range(self.n))
            self.progress("settle-fall", f"kinetic {ek:.3e} J (peak {ek_peak:.3e})  "
                                         f"top {top:.4f} m")
            if ek_peak > 0 and ek < 0.01 * ek_peak and O.iter - start > 2000:
                break
            if O.iter - start > p["max_steps"]:
                run_error(f"max_steps: the fall did not end within {p['max_steps']} steps")
        self.newton.damping = p["settle_damping"]
        self.stepper.maxDt = 1e300
        self.use_stepper(True)
        start = O.iter
        while True:
            self.run(100)
            unb = utils.unbalancedForce()
            self.progress("settle", f"unbalanced {unb:.3e}  kinetic {utils.kineticEnergy():.3e} J")
            if unb < p["unbalanced_force_target"]:
                break
            if O.iter - start > p["max_steps"]:
                run_error(f"max_steps: settling did not reach unbalanced force "
                          f"{p['unbalanced_force_target']} within {p['max_steps']} steps "
                          f"(at {unb:.3g})")
        # The plate waits just above the bed; its height is the settled height.
        pos = self.positions()
        top = float(np.max(pos[:, 2] + self.radii))
        self.plate.state.pos = Vector3(0, 0, top)
        self.drive_plate(0.0)
        self.settled_height = top
        O.tags["tdem_settled_height"] = repr(top)
        self.newton.damping = p["damping"]
        self.progress("settle", f"settled: height {top:.5g} m, unbalanced {unb:.3e}", force=True)

    def load_settled(self, path):
        """Continue from a saved settled bed (already loaded into O by the caller)."""
        self.attach()
        self.settled_height = float(O.tags["tdem_settled_height"])
        self.log(f"reusing the settled bed {path} (height {self.settled_height:.5g} m, modulus "
                 f"{self.young_now:.4g} Pa)")

    def stiffen(self, factor):
        """Multiply the modulus of particles and walls by factor, in the materials (new contacts)
        and in every existing contact (Hertz kno and Mindlin kso ~ E; the damping ratio betan
        refers to the current stiffness and needs no update)."""
        self.young_now *= factor
        self.pmat.young = self.young_now
        self.wmat.young = self.wall_modulus(self.young_now)
        root = math.sqrt(factor)
        for i in O.interactions:
            ph = i.phys
            if ph is None:
                continue
            ph.kno *= factor
            ph.kso *= factor
        # the stiffer contacts need a shorter step now, before the stepper's next update
        self.stepper.active = False
        O.dt = O.dt / root
        self.stepper.active = True
        self.stage_inertial_number()

    def check_steps(self, start, stage, target, p_now, unb):
        if O.iter - start > self.p["max_steps"]:
            run_error(f"max_steps: stage {stage} at {target:.4g} Pa did not converge within "
                      f"{self.p['max_steps']} steps (pressure {p_now:.4g} Pa, unbalanced "
                      f"{unb:.3g})")

    def approach(self, target, imax):
        """Drive the plate down at the inertial-number speed limit up to APPROACH x target."""
        start = O.iter
        while True:
            p_now = self.plate_pressure()
            if p_now >= APPROACH * target:
                return imax
            v = self.inertial_speed(p_now)
            self.drive_plate(v)
            imax = max(imax, self.inertial_number(v, p_now))
            self.run(CHUNK)
            self.progress("approach", f"p {p_now:.4g} Pa ({p_now / target:.4f} of {target:.4g})"
                                      f"  v {v:.2e} m/s  H {self.plate_height():.5f} m  "
                                      f"E {self.young_now:.3g} Pa")
            self.check_steps(start, "approach", target, p_now, math.nan)

    def relax(self, target, stage, p_tol, unb_tol, imax):
        """The plate carries the target force as a dead load; run until |p - target| < p_tol
        target and the unbalanced force < unb_tol. Returns (max inertial number, unb)."""
        self.load_plate(target)
        start = O.iter
        p_now = self.plate_pressure()
        while True:
            # speed limiter at half the inertial-number speed (the plate accelerates between
            # two checks): keeps the sampled I near or below the target
            v = self.plate_speed()
            limit = 0.5 * self.inertial_speed(p_now)
            if abs(v) > limit:
                self.plate.state.vel = Vector3(0, 0, -math.copysign(limit, v))
            self.run(CHUNK)
            p_now = self.plate_pressure()
            unb = self.unbalanced()
            v = self.plate_speed()
            inertial = self.inertial_number(v, p_now)
            imax = max(imax, inertial)
            if abs(p_now - target) < p_tol * target and unb < unb_tol:
                return imax, unb
            self.progress(stage, f"p {p_now:.4g} Pa ({p_now / target:.4f} of {target:.4g})  "
                                 f"unbalanced {unb:.2e}  I {inertial:.1e}  v {v:.2e} m/s  "
                                 f"H {self.plate_height():.5f} m  E {self.young_now:.3g} Pa")
            self.check_steps(start, stage, target, p_now, unb)

    def relax_unloaded(self, stage, unb_tol):
        """Relax the bed under gravity only (plate at rest above it)."""
        self.drive_plate(0.0)
        start = O.iter
        while True:
            self.run(CHUNK)
            unb = self.unbalanced()
            if unb < unb_tol:
                return unb
            self.progress(stage, f"unbalanced {unb:.2e}  E {self.young_now:.3g} Pa")
            self.check_steps(start, stage, 0.0, 0.0, unb)

    def stage_inertial_number(self):
        """The plate's inertial-number target: ``soft_inertial_number`` while the modulus is
        softened (that state is re-relaxed at the real modulus before any dump),
        ``inertial_number`` at the real modulus."""
        soft = self.young_now < self.p["young_pa"] * (1.0 - 1e-9)
        self.i_target = self.p["soft_inertial_number" if soft else "inertial_number"]

    def compress(self, target):
        p = self.p
        imax = 0.0
        self.stage_inertial_number()
        if self.young_now < p["young_pa"] and p["preload_fraction"] < 1.0:
            # softened: load only to the preload, re-stiffen there, then go on at the real E
            preload = p["preload_fraction"] * target
            imax, _ = self.compress_softened(preload, dump=False)
        if self.young_now < p["young_pa"]:
            return self.compress_softened(target, dump=True)
        imax = self.approach(target, imax)
        return self.relax(target, "hold", p["pressure_tolerance"],
                          p["unbalanced_force_target"], imax)

    def compress_softened(self, target, dump):
        p = self.p
        if self.young_now < p["young_pa"]:
            # not softer than needed for a mean overlap <= SOFT_OVERLAP r under the target
            e_star = target * (3.3 / SOFT_OVERLAP) ** 1.5
            needed = min(p["young_pa"], 2.0 * (1.0 - p["poisson"] ** 2) * e_star)
            while self.young_now < needed * (1.0 - 1e-9):
                factor = min(p["stiffen_factor"], needed / self.young_now)
                self.stiffen(factor)
                self.log(f"modulus raised to {self.young_now:.4g} Pa (x{factor:.3g}) under "
                         f"gravity, for the approach to {target:.4g} Pa")
                self.relax_unloaded("stiffen", 10 * p["unbalanced_force_target"])
        imax = self.approach(target, 0.0)
        if self.young_now < p["young_pa"]:
            # softened: relax under the load, then raise the modulus step by step under it
            loose = 10 * p["unbalanced_force_target"]
            imax, _ = self.relax(target, "load", 0.05, loose, imax)
            while self.young_now < p["young_pa"]:
                factor = min(p["stiffen_factor"], p["young_pa"] / self.young_now)
                self.stiffen(factor)
                self.log(f"modulus raised to {self.young_now:.4g} Pa (x{factor:.3g}) under "
                         f"{target:.4g} Pa")
                if self.young_now < p["young_pa"]:
                    imax, _ = self.relax(target, "stiffen", 0.05, loose, imax)
        # the softened stages' plate motion is recorded apart (inertial_number_softened): the
        # dump's inertial_number covers the stages at the real modulus only
        self.soft_imax = max(self.soft_imax, imax)
        imax = 0.0
        if not dump:
            return self.relax(target, "preload", 0.05, 10 * p["unbalanced_force_target"], imax)
        return self.relax(target, "hold", p["pressure_tolerance"],
                          p["unbalanced_force_target"], imax)

    # --- output -----------------------------------------------------------------------------
    def dump(self, path, target, imax, unb):
        """Measure the current state and write it to ``path`` (a packing file)."""
        pos, contacts, walls, attrs, now = self.measure(target, imax, unb)
        self.write(path, pos, contacts, walls, attrs, now, imax, unb)

    def interaction_records(self):
        """YADE's interactions as plain records for bed_geometry.dump_contacts: (id1, id2,
        real, penetration depth, kno), the last two None when the interaction is not real."""
        return [(i.id1, i.id2, i.isReal, i.geom.penetrationDepth if i.isReal else None,
                 i.phys.kno if i.isReal else None) for i in O.interactions.all()]

    def measure(self, target, imax, unb):
        """The state to dump: positions, contact arrays (bed_geometry.dump_contacts, with the
        Hertz coefficients kno = 4/3 E* sqrt(R*) at the modulus in use: R* = r_i r_j/(r_i+r_j)
        between spheres, R* = r against a wall, with the real particle/wall E*), walls and the
        attributes (``attributes``), and the time they were measured at."""
        p = self.p
        pos = self.positions()
        height = self.plate_height()
        e_pp, e_pw = hertz_moduli(self.young_now, p["young_pa"], p["poisson"],
                                  p["wall_young_pa"], p["wall_poisson"])
        contacts = dump_contacts(self.interaction_records(), pos, self.radii, self.wall_index,
                                 height, e_pp, e_pw)
        if contacts["kno_mismatch"] > 1e-9:
            run_error(f"internal: YADE's Hertz coefficients differ from 4/3 E* sqrt(R*) by "
                      f"{contacts['kno_mismatch']:.3g} (relative)")
        rc = p["cylinder_radius_m"]
        walls = [
            dict(name="zmin", kind="plane", point=(0, 0, 0), normal=(0, 0, 1), radius=math.nan),
            dict(name="plate", kind="plane", point=(0, 0, height), normal=(0, 0, -1),
                 radius=math.nan),
            dict(name="cylinder", kind="cylinder", point=(0, 0, 0), normal=(0, 0, 1), radius=rc),
        ]
        now = time.time()
        attrs = self.attributes(target, imax, unb, contacts, height, now)
        return pos, contacts, walls, attrs, now

    def attributes(self, target, imax, unb, contacts, height, now):
        """The packing's root attributes at this state: what the bed is (phi, Z, pressure, plate
        and container), its parameters, and how the stage that made it ran (inertial numbers,
        unbalanced force, steps, times)."""
        p = self.p
        n = self.n
        radii = self.radii
        pairs = contacts["pairs"]
        plate_force = self.plate_pressure() * self.area
        volume = 4.0 / 3.0 * math.pi * float(np.sum(radii ** 3))
        speeds = [O.bodies[k].state.vel.norm() for k in range(n)]
        rc = p["cylinder_radius_m"]
        return dict(
            generator=GENERATOR,
            seed=p["seed"],
            solid_fraction=volume / (self.area * height),
            mean_coordination=2.0 * len(pairs) / n,
            pressure_pa=plate_force / self.area,
            target_pressure_pa=float(target),
            plate_force_n=plate_force,
            plate_displacement_m=self.settled_height - height,
            bed_height_m=height,
            settled_height_m=self.settled_height,
            cylinder_radius_m=rc,
            cylinder_segments=p["cylinder_segments"],
            cylinder_vertex_radius_m=prism(rc, p["cylinder_segments"])[0],
            young_pa=p["young_pa"],
            poisson=p["poisson"],
            density=p["density"],
            young_pa_used=self.young_now,
            wall_young_pa=p["wall_young_pa"],
            wall_poisson=p["wall_poisson"],
            wall_young_pa_simulated=self.wmat.young,
            restitution=p["restitution"],
            friction=p["friction"],
            wall_friction=p["wall_friction"],
            density_scaling=self.scale,
            gravity_m_s2=p["gravity_m_s2"],
            # I = gamma_dot d sqrt(rho_eff / p_ref): gamma_dot = plate speed / bed height,
            # d the mean diameter, rho_eff the (scaled) density, p_ref = max(plate pressure,
            # bed weight / plate area). Maximum over the plate motion at the real modulus in the
            # stage that made this file (0: none); the plate speed is chosen to keep it at most
            # `inertial_number`.
            inertial_number=imax,
            inertial_number_target=p["inertial_number"],
            # the same, over the plate motion at the softened modulus (preload, re-stiffening)
            # that preceded this dump (0: none), and its target
            inertial_number_softened=self.soft_imax,
            inertial_number_softened_target=p["soft_inertial_number"],
            unbalanced_force_ratio=unb,
            unbalanced_force_target=p["unbalanced_force_target"],
            max_particle_speed_m_s=max(speeds) / math.sqrt(self.scale),
            settle_young_pa=p["settle_young_pa"],
            damping=p["damping"],
            settle_damping=p["settle_damping"],
            timestep_s=O.dt,
            steps=O.iter,
            stage_steps=O.iter - self.steps_at_last_dump,
            simulated_time_s=O.time,
            wall_seconds=now - self.t_start,
            stage_wall_seconds=now - self.wall_at_last_dump,
            yade_version=str(yade.config.version),
            contacts_not_yet_detected=contacts["undetected"],
            contact_law="Hertz-Mindlin (Law2_ScGeom_MindlinPhys_Mindlin), Tsuji damping from "
                        "restitution; wall contacts Hertz with R* = r",
        )

    def write(self, path, pos, contacts, walls, attrs, now, imax, unb):
        """Write a measured state (write_packing) and log it; the next stage's counters start
        here."""
        n = self.n
        rc = self.p["cylinder_radius_m"]
        height = attrs["bed_height_m"]
        c = contacts
        write_packing(path, pos, self.radii, np.zeros(n, np.int32), c["pairs"], c["overlaps"],
                      c["forces"], c["branch"], walls, c["w_particle"], c["w_index"],
                      c["w_overlap"], c["w_force"], (-rc, -rc, 0.0), (rc, rc, height),
                      (False, False, False), attrs, contact_radius=c["contact_radius"],
                      wall_contact_radius=c["w_contact_radius"], yade_id=np.arange(n))
        self.steps_at_last_dump = O.iter
        self.wall_at_last_dump = now
        self.soft_imax = 0.0
        w_force, forces = c["w_force"], c["forces"]
        plate_sum = float(np.sum(w_force[c["w_index"] == 1])) / self.area if len(w_force) else 0.0
        self.log(f"wrote {path}: N {n}, phi {attrs['solid_fraction']:.4f}, "
                 f"Z {attrs['mean_coordination']:.3f}, contacts {len(c['pairs'])} "
                 f"(mean force {forces.mean() if len(forces) else 0:.4g} N), wall contacts "
                 f"{len(c['w_particle'])}, p {attrs['pressure_pa']:.5g} Pa "
                 f"(from dumped plate contacts "
                 f"{plate_sum:.5g}), unbalanced {unb:.2e}, I max {imax:.2e}, plate displacement "
                 f"{attrs['plate_displacement_m'] * 1e3:.4f} mm, E used {self.young_now:.4g} Pa, "
                 f"{attrs['stage_wall_seconds']:.1f} s for this stage")


def main():
    import_yade()
    p = read_params()
    out = os.path.abspath(p["output_dir"])
    os.makedirs(out, exist_ok=True)
    bed = Bed(p)
    bed.log(f"YADE {yade.config.version}, {p['n_particles']} spheres, pressures "
            f"{', '.join(f'{x:.4g}' for x in p['pressures_pa'])} Pa -> {out}")
    saved = os.path.join(out, "settled.yade.gz")
    reuse = False
    if p["reuse_settled"] and os.path.exists(saved):
        O.load(saved)
        stored = (json.loads(O.tags["tdem_bed"]).get("settle", {})
                  if "tdem_bed" in O.tags.keys() else {})
        changed = [k for k in SETTLE_KEYS if stored.get(k) != p[k]]
        if changed:
            bed.log(f"{saved} was made with other {', '.join(changed)}; settling again")
        else:
            reuse = True
    if reuse:
        bed.load_settled(saved)
    else:
        bed.build()
        bed.settle()
        O.save(saved)
        bed.dump(os.path.join(out, "settled.h5"), 0.0, 0.0, utils.unbalancedForce())
    bed.steps_at_last_dump = O.iter
    bed.wall_at_last_dump = time.time()
    for target in p["pressures_pa"]:
        imax, unb = bed.compress(target)
        bed.dump(os.path.join(out, pressure_name(target)), target, imax, unb)
    bed.log(f"done: {len(p['pressures_pa'])} packing(s) in {time.time() - bed.t_start:.1f} s")


if __name__ == "__main__":
    main()
