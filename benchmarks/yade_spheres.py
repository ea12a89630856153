"""Yade reference for the sphere settling benchmark: 1000 frictionless spheres poured into an
L x L periodic cell over a floor and settled, timed in CPU seconds back to back with
``granpack run`` of the same spheres (``examples/spheres-1000.toml``: 8 d cell, seed 7) or
``bench_settle.py --case spheres-1000`` (4 d). Run with the Debian package ``yade``::

    yade -n -x benchmarks/yade_spheres.py [seed] [L] [setup] [cap]

Soft-contact DEM, so its choices set its cost and where it stops; d = 1 m, rho = 2500 kg/m^3,
g = 9.81 m/s^2, no friction. Two set-ups (``setup``):

- ``viscoelastic`` (the default, the one to compare with granpack): a linear spring-dashpot
  contact (``ViscElMat`` with ``Law2_ScGeom_ViscElPhys_Basic``) of contact time tc = 0.0055 s and
  normal restitution en = 0.01, so that a collision dissipates nearly all its energy, as
  granpack's e = 0 does; no numerical damping; time step tc / 20; the spheres start on a jittered
  lattice (spacing L / floor(L / 1.1) in x and y and 1.1 d in z, each centre moved by up to
  a third of the gap between neighbours, from the seed); stop: the total kinetic energy below
  1e-8 N m g d (N spheres of mass m), checked every 100 steps, or the cap (200 sqrt(d/g) unless
  given). The largest overlap at rest, about 1e-3 d, is set by tc (the stiffness is
  m (pi^2 + ln^2 en) / tc^2 per contact). On the floor of facets the pile can drift as a whole,
  a motion the contacts' damping, acting on relative normal velocities, hardly damps, and the
  total kinetic energy counts it: the script also reports the kinetic energy less that of the
  spheres' mean velocity, and when (simulated time, CPU s) it first fell below the stop, checked
  every 1000 steps;
- ``cundall``: the set-up of the first measurements, kept to repeat them: Young's modulus 1e9 Pa,
  Poisson 0.3, a linear contact law (``Law2_ScGeom_FrictPhys_CundallStrack``), Cundall's numerical
  damping 0.2, time step half the P-wave step, a random loose cloud (``makeCloud``, periodic, from
  1 d above the floor up to 110 d in a 4 d cell, else to the height of a cloud at solid fraction
  0.2), stop: Yade's ``unbalancedForce()`` (mean net force over mean contact force) below 1e-3,
  checked every 500 steps, or 200 sqrt(d/g). Its stop is not one of rest: the ratio of a pile
  whose grains still move can pass it, and a pile may not reach it by the cap (the 8 d cell did
  not, with one thread).

Prints one JSON line: the set-up, CPU and wall seconds, steps, simulated time in sqrt(d/g), the
total kinetic energy and the kinetic energy less the drift in N m g d (with when the latter first
passed the stop), the unbalanced force, the mean coordination and the largest overlap in d.
"""

import json
import math
import random
import sys
import time

from yade import O, pack, utils
from yade.minieigenHP import Matrix3
from yade.wrapper import (Bo1_Facet_Aabb, Bo1_Sphere_Aabb, ForceResetter, FrictMat, Ig2_Facet_Sphere_ScGeom,
                          Ig2_Sphere_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                          Ip2_FrictMat_FrictMat_FrictPhys, Ip2_ViscElMat_ViscElMat_ViscElPhys,
                          Law2_ScGeom_FrictPhys_CundallStrack, Law2_ScGeom_ViscElPhys_Basic, NewtonIntegrator,
                          ViscElMat)

seed = int(sys.argv[1]) if len(sys.argv) > 1 else 11
L = float(sys.argv[2]) if len(sys.argv) > 2 else 4.0
SETUP = sys.argv[3] if len(sys.argv) > 3 else "viscoelastic"
CAP = float(sys.argv[4]) if len(sys.argv) > 4 else 200.0  # sqrt(d/g)
if SETUP not in ("viscoelastic", "cundall"):
    raise SystemExit(f"setup must be viscoelastic or cundall, got {SETUP!r}")
N, G, RHO = 1000, 9.81, 2500.0
TC, EN = 0.0055, 0.01
MASS = RHO * math.pi / 6.0  # one sphere of d = 1 m, kg
REST = 1e-8 * N * MASS * G * 1.0  # total kinetic energy at rest, J
O.periodic = True
O.cell.hSize = Matrix3(L, 0, 0, 0, L, 0, 0, 0, 200.0)


def lattice(rng: random.Random) -> int:
    """1000 spheres on a jittered lattice above the floor; returns the number placed."""
    n_side = int(L // 1.1)
    step = L / n_side
    dz = 1.1
    jitter_xy, jitter_z = (step - 1.0) / 3.0, (dz - 1.0) / 3.0
    placed = 0
    layer = 0
    while placed < N:
        for i in range(n_side):
            for j in range(n_side):
                if placed == N:
                    break
                centre = ((i + 0.5) * step + rng.uniform(-jitter_xy, jitter_xy),
                          (j + 0.5) * step + rng.uniform(-jitter_xy, jitter_xy),
                          1.0 + layer * dz + rng.uniform(-jitter_z, jitter_z))
                O.bodies.append(utils.sphere(centre, 0.5))
                placed += 1
        layer += 1
    return placed


if SETUP == "viscoelastic":
    O.materials.append(ViscElMat(tc=TC, en=EN, et=EN, frictionAngle=0.0, density=RHO))
    placed = lattice(random.Random(seed))
    physics, law, damping = Ip2_ViscElMat_ViscElMat_ViscElPhys(), Law2_ScGeom_ViscElPhys_Basic(), 0.0
else:
    O.materials.append(FrictMat(young=1e9, poisson=0.3, frictionAngle=0.0, density=RHO))
    top = 110.0 if L == 4.0 else 1.0 + N * (3.14159 / 6.0) / (0.2 * L * L)  # 4 d: as measured; else a cloud at 0.2
    cloud = pack.SpherePack()
    cloud.makeCloud((0, 0, 1.0), (L, L, top), rMean=0.5, rRelFuzz=0.0, num=N, periodic=True, seed=seed)
    cloud.toSimulation()
    placed = len(cloud)
    physics, law, damping = Ip2_FrictMat_FrictMat_FrictPhys(), Law2_ScGeom_FrictPhys_CundallStrack(), 0.2
for i in range(int(L)):  # the floor: 2 L^2 triangles (a body as wide as the periodic cell is not allowed)
    for j in range(int(L)):
        a, b, c, d = (i, j, 0), (i + 1, j, 0), (i + 1, j + 1, 0), (i, j + 1, 0)
        O.bodies.append([utils.facet([a, b, c], fixed=True), utils.facet([a, c, d], fixed=True)])
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom()], [physics], [law]),
    NewtonIntegrator(gravity=(0, 0, -G), damping=damping),
]
O.dt = TC / 20.0 if SETUP == "viscoelastic" else 0.5 * utils.PWaveTimeStep()
unit = (1.0 / G) ** 0.5  # sqrt(d/g) in s
cpu0, wall0 = time.process_time(), time.perf_counter()
spheres = [b for b in O.bodies if b.shape.__class__.__name__ == "Sphere"]


def internal_energy() -> float:
    """Kinetic energy of the spheres relative to their mean velocity, J: the total less the drift
    of the pile as a whole (the spheres have equal masses and, frictionless, no spin)."""
    vels = [b.state.vel for b in spheres]
    mean = [sum(v[k] for v in vels) / len(vels) for k in range(3)]
    return 0.5 * MASS * sum((v[0] - mean[0]) ** 2 + (v[1] - mean[1]) ** 2 + (v[2] - mean[2]) ** 2 for v in vels)


internal_at = None  # (simulated time, CPU s) when the energy less the drift first passes the stop
if SETUP == "viscoelastic":
    while True:
        O.run(100, True)
        if O.time <= 1.0:  # the spheres start at rest: the test begins once they fall
            continue
        if internal_at is None and O.iter % 1000 == 0 and internal_energy() < REST:
            internal_at = (O.time / unit, time.process_time() - cpu0)
        if O.time > CAP * unit or utils.kineticEnergy() < REST:
            break
else:
    while True:
        O.run(500, True)
        if O.time > CAP * unit or (O.iter > 5000 and utils.unbalancedForce() < 1e-3):
            break
cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
overlap = max((i.geom.penetrationDepth for i in O.interactions if i.isReal), default=0.0)
print(json.dumps({
    "engine": "yade", "setup": SETUP, "seed": seed, "cell": L, "spheres": placed, "cpu_seconds": cpu,
    "wall_seconds": wall, "steps": O.iter, "time_step_s": O.dt, "simulated_time": O.time / unit,
    "kinetic_energy_N_mgd": utils.kineticEnergy() / (N * MASS * G),
    "kinetic_energy_less_drift_N_mgd": internal_energy() / (N * MASS * G),
    "less_drift_below_stop_at": None if internal_at is None else {"simulated_time": internal_at[0], "cpu_seconds": internal_at[1]},
    "unbalanced_force": utils.unbalancedForce(),
    "mean_coordination": utils.avgNumInteractions(), "max_overlap": overlap,
}), flush=True)
