"""Yade reference for the sphere settling benchmark: 1000 frictionless spheres poured into an
L x L periodic cell (default 4 d) and settled, timed in CPU seconds back to back with
``bench_settle.py --case spheres-1000`` (4 d) or ``granpack run`` of the same spheres. Run with
the Debian package ``yade``::

    yade -n -x benchmarks/yade_spheres.py [seed] [L]

Soft-contact DEM, so its choices set its cost: d = 1 m, rho = 2500 kg/m^3, g = 9.81, Young's
modulus 1e9 Pa (overlaps about 1e-3 d under the pile's weight, the rigid grains' 1e-4 d being
out of reach at a reasonable time step), Poisson 0.3, friction angle 0, linear contact law
(``Law2_ScGeom_FrictPhys_CundallStrack``), Cundall's numerical damping 0.2 (``NewtonIntegrator``),
time step half the P-wave step. The spheres start as a random loose cloud (``makeCloud``,
periodic, from 1 d above the floor up to 110 d in a 4 d cell, else to the height of a cloud at
solid fraction 0.2: makeCloud cannot place 1000 spheres in much less, a looser start than
granpack's drop deposit). Stop: Yade's
``unbalancedForce()`` (mean net force over mean contact force) below 1e-3, a looser test than
granpack's per-grain criteria, checked every 500 steps. Prints one JSON line: CPU and wall
seconds, steps, simulated time in sqrt(d/g), the mean coordination and the largest overlap.
"""

import json
import sys
import time

from yade import O, pack, utils
from yade.wrapper import (Bo1_Facet_Aabb, Bo1_Sphere_Aabb, ForceResetter, FrictMat, Ig2_Facet_Sphere_ScGeom,
                          Ig2_Sphere_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator)
from yade.minieigenHP import Matrix3

seed = int(sys.argv[1]) if len(sys.argv) > 1 else 11
L = float(sys.argv[2]) if len(sys.argv) > 2 else 4.0
N, G = 1000, 9.81
TOP = 110.0 if L == 4.0 else 1.0 + N * (3.14159 / 6.0) / (0.2 * L * L)  # 4 d: as measured; else a cloud at 0.2
O.periodic = True
O.cell.hSize = Matrix3(L, 0, 0, 0, L, 0, 0, 0, 200.0)
O.materials.append(FrictMat(young=1e9, poisson=0.3, frictionAngle=0.0, density=2500.0))
cloud = pack.SpherePack()
cloud.makeCloud((0, 0, 1.0), (L, L, TOP), rMean=0.5, rRelFuzz=0.0, num=N, periodic=True, seed=seed)
cloud.toSimulation()
for i in range(int(L)):  # the floor: 2 L^2 triangles (a body as wide as the periodic cell is not allowed)
    for j in range(int(L)):
        a, b, c, d = (i, j, 0), (i + 1, j, 0), (i + 1, j + 1, 0), (i, j + 1, 0)
        O.bodies.append([utils.facet([a, b, c], fixed=True), utils.facet([a, c, d], fixed=True)])
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    NewtonIntegrator(gravity=(0, 0, -G), damping=0.2),
]
O.dt = 0.5 * utils.PWaveTimeStep()
placed = len(cloud)
cpu0, wall0 = time.process_time(), time.perf_counter()
unit = (1.0 / G) ** 0.5  # sqrt(d/g) in s
while True:
    O.run(500, True)
    if O.time > 200 * unit or (O.iter > 5000 and utils.unbalancedForce() < 1e-3):
        break
overlap = max((i.geom.penetrationDepth for i in O.interactions if i.isReal), default=0.0)
print(json.dumps({
    "engine": "yade", "seed": seed, "spheres": placed, "cpu_seconds": time.process_time() - cpu0,
    "wall_seconds": time.perf_counter() - wall0, "steps": O.iter, "time_step_s": O.dt,
    "simulated_time": O.time / unit, "unbalanced_force": utils.unbalancedForce(),
    "mean_coordination": utils.avgNumInteractions(), "max_overlap": overlap,
}), flush=True)
