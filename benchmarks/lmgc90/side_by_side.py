"""LMGC90 beside granpack: the same grains poured and settled by both engines, both piles
analysed by granpack.

LMGC90 comes from the ``compas-lmgc90`` wheel (the LMGC90 core, statically linked into its
nanobind module ``compas_lmgc90._lmgc90``). The wheel's own step (``compute_one_step``) fixes its
settings in Fortran: NLGS with the 'QM/16' norm, tolerance 1.666e-4, relaxation 0.1, and the 'STO'
polyhedron detection. Its module exports every LMGC90 routine, so this script keeps the wheel's
set-up calls (bodies, materials, contact law, see table) and makes the step itself through
``ctypes``, as LMGC90's own Python API (ChiPy) does: the study's settings, theta 0.5, frictionless
``IQS_CLB``, the 'Quad' norm at 1.666e-4 with relaxation 1 (51 sweeps between checks, at most
501 checks), Cundall's common-plane detection (``PRPRx_UseCpCundallDetection(200)``), a cell
periodic in x and y (``RBDY3`` and ``PRPRx`` periodic data) over a fixed polyhedral floor.

Units: LMGC90 runs in SI with the wheel's gravity 9.81 m/s^2 and d = 1 m, density 1 kg/m^3, so
its time step is 5e-3 sqrt(d/g) = 5e-3 / sqrt(9.81) s; times are reported in sqrt(d/g), and the
contact forces the wheel returns (``rloc``, in N) become granpack's impulses over the step,
rloc h / (rho g d^3) with h = 5e-3.

Subcommands (``python benchmarks/lmgc90/side_by_side.py CMD ...``, in granpack's venv; the wheel
is imported from ``LMGC90_SITE``, default ``/work/lmgc90-venv/lib/python3.11/site-packages``,
where ``pip install --no-deps compas-lmgc90 numpy`` put it):

- ``export CONFIG OUT``: granpack's initial state of CONFIG (its deposit, before gravity acts),
  written to ``OUT/initial.npz``;
- ``lmgc OUT [--max-time T] [--steps N] [--resume]``: LMGC90 from ``OUT/initial.npz``; a line of
  ``OUT/lmgc.log`` and a row of ``OUT/lmgc_timeline.csv`` every check (0.25 sqrt(d/g)), the latest
  state as a granpack run folder ``OUT/lmgc/final.gsd`` (analyse it with ``granpack analyze``);
  stops when granpack's criteria, or else the study's, have held for five checks in a row, or at
  ``--max-time``. Every check also writes ``OUT/lmgc_state.npz`` (positions, orientations and
  LMGC90's own velocities at the end of the step, with the counters), from which ``--resume``
  goes on: the bodies are set up again where they were, with their velocities; only the
  reactions that warm-start the first step's NLGS are lost;
- ``pairs OUT``: how LMGC90's interactions group by pair in the latest state a run saved
  (``OUT/lmgc_interactions.npz``, LMGC90's interactions as they are, written with
  ``final.gsd``): one JSON object, for every pair of bodies the points found with each body as
  candidate against the type granpack gives the merged manifold, and the contacts per grain
  counted per manifold, per pair and per (candidate, antagonist) call;
- ``report OUT GRANPACK_RUN``: analyses both piles (``analysis.json`` in each folder) and prints
  one JSON object: solid fraction, k, contact types (over the bulk, and over the whole column for
  piles too thin for a bulk), CPU time to rest, per step.

The floor is 3 x 3 fixed box tiles (see ``Lmgc``), not one slab, and the common-plane search is
freed from the wheel's face-to-face flag (``_clear_f2f``): the two things without which LMGC90
let grains through the floor. Diagnostic switches (environment), each of which reproduces one of
the failures in benchmarks/lmgc90/README.md: ``LMGC_WHEEL_DETECTION=1`` (keep the wheel's 'STO'
face-to-face set-up), ``LMGC_FLOOR_TILES=1`` (one slab), ``LMGC_OLD_CCPM=1`` (LMGC90's older
common-plane search), ``LMGC_NODAL=0``, ``LMGC_NORM`` / ``LMGC_RELAX`` (the wheel's 'QM/16' and
0.1), ``LMGC_NO_PERIODIC=1``, ``LMGC_DEBUG=1`` (LMGC90's own log and OUTBOX files).
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

G = 9.81  # the wheel's gravity, m/s^2 (d = 1 m)
SQRT_G = math.sqrt(G)
H = 5e-3  # the study's time step, sqrt(d/g)
THETA = 0.5
ALERT = 0.02  # d, granpack's automatic alert distance for this mixture (0.02 d_max)
NLGS_NORM, NLGS_TOL, NLGS_RELAX, NLGS_SWEEPS, NLGS_CHECKS = "Quad ", 1.666e-4, 1.0, 50, 500
CUNDALL_ITERATIONS = 200
CHECK_EVERY = 50  # steps: 0.25 sqrt(d/g)
WINDOW = 5  # checks in a row
STUDY_CRITERIA = dict(force=1e-3, torque=1e-3, kinetic_energy=1e-7, wall=5e-3)
I_PRPRX = 18  # LMGC90's interaction id of PRPRx in this wheel (read from lmgc90_get_nb_inters)
MAX_NB_INT = 19
FLOOR_TILES = 3  # per side: tiles 0.75 d wide in the 2.25 d cell
FLOOR_DEPTH = 0.5  # d


# ---------------------------------------------------------------- export (granpack's deposit)
def export(config_path: str, out: Path) -> dict:
    from granpack.config import load_config
    from granpack.simulation import initial_state

    config = load_config(config_path)
    state, mixture = initial_state(config)
    out.mkdir(parents=True, exist_ok=True)
    kinds = {}
    for k, shape in enumerate(state.shapes.shapes):
        faces = [np.asarray(f) for f in shape.faces]
        tri = np.array([(f[0], f[i], f[i + 1]) for f in faces for i in range(1, len(f) - 1)], dtype=np.int64)
        kinds[f"vertices_{k}"] = np.asarray(shape.vertices, dtype=np.float64)
        kinds[f"triangles_{k}"] = tri
    np.savez(out / "initial.npz", position=state.position, quaternion=state.quaternion, kind=state.kind,
             population=state.population, lateral_size=config.lateral_size, n_kinds=len(state.shapes.shapes),
             population_names=np.array(mixture.names), config=config.to_toml(), seed=config.seed, **kinds)
    return {"grains": int(state.n), "lateral_size": config.lateral_size, "file": str(out / "initial.npz")}


def granpack_state(init, position, quaternion, velocity=None, omega=None, time_=0.0):
    """A granpack ParticleState of the exported grains at the given pose."""
    from granpack.box import Box
    from granpack.mixture import Mixture
    from granpack.config import load_config_dict
    import tomllib

    config = load_config_dict(tomllib.loads(str(init["config"])))
    shapes = Mixture.from_config(config).particle_shape_table()
    box = Box.square(float(init["lateral_size"]))
    from granpack.state import ParticleState

    return ParticleState(box=box, shapes=shapes, kind=init["kind"], population=init["population"],
                         position=box.wrap(position), quaternion=quaternion, velocity=velocity, omega=omega,
                         time=time_), config


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices -> (N, 4) unit quaternions (w, x, y, z), w >= 0."""
    q = np.empty((len(r), 4))
    for n, m in enumerate(r):
        t = np.trace(m)
        if t > 0:
            s = 2.0 * math.sqrt(t + 1.0)
            q[n] = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
        else:
            i = int(np.argmax(np.diag(m)))
            j, k = (i + 1) % 3, (i + 2) % 3
            s = 2.0 * math.sqrt(max(1.0 + m[i, i] - m[j, j] - m[k, k], 1e-300))
            v = np.empty(4)
            v[0] = (m[k, j] - m[j, k]) / s
            v[1 + i] = 0.25 * s
            v[1 + j] = (m[j, i] + m[i, j]) / s
            v[1 + k] = (m[k, i] + m[i, k]) / s
            q[n] = v
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# ---------------------------------------------------------------- LMGC90 through the wheel
class Inter(ctypes.Structure):
    _fields_ = [("cdan", ctypes.c_char * 5), ("icdan", ctypes.c_int), ("cdbdy", ctypes.c_char * 5),
                ("icdbdy", ctypes.c_int), ("anbdy", ctypes.c_char * 5), ("ianbdy", ctypes.c_int),
                ("cdtac", ctypes.c_char * 5), ("icdtac", ctypes.c_int), ("antac", ctypes.c_char * 5),
                ("iantac", ctypes.c_int), ("icdsci", ctypes.c_int), ("iansci", ctypes.c_int),
                ("behav", ctypes.c_char * 5), ("status", ctypes.c_char * 5), ("coor", ctypes.c_double * 3),
                ("uc", ctypes.c_double * 9), ("rloc", ctypes.c_double * 3), ("vloc", ctypes.c_double * 3),
                ("gap", ctypes.c_double), ("nb_int", ctypes.c_int), ("internals", ctypes.c_double * MAX_NB_INT)]


class Body(ctypes.Structure):
    _fields_ = [("coor", ctypes.c_double * 3), ("frame", ctypes.c_double * 9)]


def F(so, name: str):
    """The exported Fortran module routine ``__<module>_MOD_<name>`` (a plain getattr: a class
    body would mangle the double underscore)."""
    return getattr(so, "__" + name)


def _clear_f2f(so) -> None:
    """Undo the wheel's ``set_f2f_tol_PRPRx`` (its 'STO' set-up): PRPRx's private flag
    ``with_f2f`` makes the common-plane detection keep, after its first call, only the pairs face
    to face at that call (blocks of masonry), so that grains falling onto others are never
    detected; no routine clears it, so the byte is found from the one instruction of
    ``set_f2f_tol_PRPRx`` that sets it (``movl $1, with_f2f(%rip)``) and cleared."""
    fn = F(so, "prprx_MOD_set_f2f_tol_prprx")
    addr = ctypes.cast(fn, ctypes.c_void_p).value
    code = ctypes.string_at(addr, 10)
    if code[:2] != b"\xc7\x05" or code[6:10] != b"\x01\x00\x00\x00":
        raise RuntimeError("set_f2f_tol_PRPRx is not the expected 'movl $1, with_f2f(%rip)': another wheel build")
    flag = addr + 10 + int.from_bytes(code[2:6], "little", signed=True)
    if ctypes.c_int.from_address(flag).value != 1:
        raise RuntimeError("with_f2f is not set: another wheel build")
    ctypes.c_int.from_address(flag).value = 0


def _lmgc_module():
    try:
        from compas_lmgc90 import _lmgc90
    except ImportError:
        sys.path.append(os.environ.get("LMGC90_SITE", "/work/lmgc90-venv/lib/python3.11/site-packages"))
        from compas_lmgc90 import _lmgc90
    return _lmgc90


class Lmgc:
    """One LMGC90 simulation of the exported grains over a fixed floor, periodic in x and y."""

    def __init__(self, init):
        m = _lmgc_module()
        self.so = so = ctypes.CDLL(m.__file__)
        self.n = n = len(init["kind"])
        self.L = L = float(init["lateral_size"])
        self.dt = H / SQRT_G
        self.solver = s = m.LMGC90Solver()
        s.initialize(self.dt, THETA, bool(os.environ.get("LMGC_DEBUG")))
        s.add_one_tact_behav("iqsc0", "IQS_CLB", [0.0])  # frictionless
        s.set_materials([1.0])  # sets gravity (0, 0, -9.81)
        s.set_see_tables(ALERT)
        k = int(os.environ.get("LMGC_FLOOR_TILES", FLOOR_TILES))
        self.n_floor = k * k
        s.set_nb_bodies(n + self.n_floor)
        from granpack.rotations import quat_to_matrix

        self.r0 = quat_to_matrix(init["quaternion"])
        for p in range(n):
            kind = int(init["kind"][p])
            v = init[f"vertices_{kind}"] @ self.r0[p].T
            tri = init[f"triangles_{kind}"] + 1
            s.set_one_polyr("s0001", [float(c) for c in init["position"][p]], tri.ravel().tolist(),
                            v.ravel().tolist(), 0, 0)
        # the floor: k x k fixed tiles (boxes L/k wide, FLOOR_DEPTH deep) whose top faces make the
        # plane z = 0 over the cell; with their periodic images they tile the plane. Tiles about
        # a grain wide, not one slab: a slab is a 'big POLYR' (one larger than 4 times the mean
        # radius), which LMGC90 keeps out of the periodic search and meets with its nodal
        # detection, which took the slab's side faces for the nearest ones and let grains through;
        # a slab made small enough not to be big meets, through its periodic images, grains it
        # does not touch, and the common-plane search returned contacts with a zero frame there
        # (NaN reactions). The big-POLYR threshold is raised all the same.
        w = L / k
        quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
        tri = np.array([(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]) + 1
        local = np.array([[x, y, z] for z in (-FLOOR_DEPTH / 2, FLOOR_DEPTH / 2) for y in (-w / 2, w / 2)
                          for x in (-w / 2, w / 2)])
        for a in range(k):
            for b in range(k):
                centre = [(a + 0.5) * w, (b + 0.5) * w, -FLOOR_DEPTH / 2]
                s.set_one_polyr("s0001", centre, tri.ravel().tolist(), local.ravel().tolist(), 6, 0)
                body = n + a * k + b + 1
                for dof in range(1, 7):
                    s.set_drvdof(body, dof, [0.0] * 6, True, False)
        # periodic in x and y (ChiPy: RBDY3_/PRPRx_SetX/YPeriodicCondition)
        per, true = ctypes.c_double(L), ctypes.c_int(1)
        if os.environ.get("LMGC_NO_PERIODIC"):
            per = None
        if per is not None:
            F(so, "rbdy3_MOD_set_xperiodic_data_rbdy3")(ctypes.byref(per))
            F(so, "rbdy3_MOD_set_yperiodic_data_rbdy3")(ctypes.byref(per))
            F(so, "prprx_MOD_set_xperiodic_data_prprx")(ctypes.byref(per), ctypes.byref(true))
            F(so, "prprx_MOD_set_yperiodic_data_prprx")(ctypes.byref(per), ctypes.byref(true))
        # Cundall's common plane (ChiPy: PRPRx_UseCpCundallDetection(200, 0, 0, 0))
        if not os.environ.get("LMGC_WHEEL_DETECTION"):
            _clear_f2f(so)
            F(so, "prprx_MOD_set_cundall_iteration_prprx")(ctypes.byref(ctypes.c_int(CUNDALL_ITERATIONS)))
            z = ctypes.c_double(0.0)
            F(so, "prprx_MOD_set_clipper_parameters")(ctypes.byref(z), ctypes.byref(z), ctypes.byref(z))
            if os.environ.get("LMGC_OLD_CCPM"):
                F(so, "prprx_MOD_use_old_ccpm_prprx")()
            if os.environ.get("LMGC_NODAL", "1") == "1":
                F(so, "prprx_MOD_with_nodal_contact_prprx")()
        F(so, "polyr_MOD_set_threshold_big_polyr")(ctypes.byref(ctypes.c_double(1e9)))
        s.close_before_computing()
        if ctypes.c_int.in_dll(so, "__polyr_MOD_nb_big_polyr").value != 0:
            raise RuntimeError("LMGC90 made the floor a big POLYR")
        for name in ("prprx_MOD_check_prprx", "prprx_MOD_run_prprx", "inter_meca_handler_3d_MOD_get_nb_inters"):
            F(so, name).restype = ctypes.c_int
        self.box_done = False
        self.step_count = 0
        self.sweeps = 0
        self.last_sweeps = 0
        self.frame0 = self.frames()[1]

    def step(self) -> int:
        """One Moreau-Jean step (the sequence of the wheel's compute_one_step, with the study's
        detection and NLGS); returns the NLGS sweeps it took."""
        so, ref = self.so, ctypes.byref
        F(so, "overall_MOD_clean_writing_flags")()
        F(so, "overall_MOD_time_increment")()
        F(so, "rbdy3_MOD_increment_rbdy3")()
        F(so, "rbdy3_MOD_comp_fext_rbdy3")()
        F(so, "rbdy3_MOD_comp_fint_rbdy3")()
        F(so, "rbdy3_MOD_comp_free_vlocy_rbdy3")()
        F(so, "overall_MOD_init_entitylist")()
        F(so, "overall_MOD_set_run_contactor")(ref(ctypes.c_int(1)))
        if F(so, "prprx_MOD_check_prprx")():
            if not self.box_done:
                F(so, "prprx_MOD_compute_box_prprx")()
                self.box_done = True
            F(so, "prprx_MOD_coor_prediction_prprx")()
            if F(so, "prprx_MOD_run_prprx")():
                F(so, "prprx_MOD_creation_tab_visu_prprx")()
            F(so, "prprx_MOD_wcp_compute_contact_prprx")(None)
        i_prprx = ctypes.c_int(I_PRPRX)
        F(so, "inter_meca_handler_3d_MOD_recup_rloc")(ref(i_prprx))
        tol, relax = ctypes.c_double(NLGS_TOL), ctypes.c_double(float(os.environ.get("LMGC_RELAX", NLGS_RELAX)))
        norm = os.environ.get("LMGC_NORM", NLGS_NORM)
        F(so, "nlgs_3d_MOD_set_nlgs_parameter")(ctypes.c_char_p(norm.encode()), ref(tol), ref(relax),
                                            ctypes.c_size_t(5))
        F(so, "nlgs_3d_MOD_prep_nlgs")(ref(ctypes.c_int(1)))
        iconv = ctypes.c_int(0)
        sweeps = 0
        one, two, three = ctypes.c_int(1), ctypes.c_int(2), ctypes.c_int(3)
        nb_inters = F(so, "inter_meca_handler_3d_MOD_get_nb_inters")(ref(i_prprx))
        for _ in range(NLGS_CHECKS if nb_inters > 0 else 0):
            for _ in range(NLGS_SWEEPS):
                F(so, "nlgs_3d_MOD_solve_nlgs")(ref(one))
            F(so, "nlgs_3d_MOD_prep_check_nlgs")(ref(iconv))
            F(so, "nlgs_3d_MOD_solve_nlgs")(ref(two))
            sweeps += NLGS_SWEEPS + 1
            F(so, "nlgs_3d_MOD_comp_check_nlgs")(ref(iconv))
            if iconv.value == 0:
                break
        F(so, "nlgs_3d_MOD_rnodhrloc_nlgs")(None, None)
        F(so, "nlgs_3d_MOD_solve_nlgs")(ref(three))
        F(so, "nlgs_3d_MOD_nullify_entitylist_nlgs")()
        F(so, "nlgs_3d_MOD_update_tact_behav_nlgs")()
        F(so, "inter_meca_handler_3d_MOD_stock_rloc")(ref(i_prprx))
        F(so, "rbdy3_MOD_comp_dof_rbdy3")()
        F(so, "overall_MOD_updt_time_begin")()
        F(so, "rbdy3_MOD_update_dof_rbdy3")()
        self.step_count += 1
        self.sweeps += sweeps
        self.last_sweeps = sweeps
        return sweeps

    def frames(self):
        bodies = (Body * (self.n + self.n_floor))()
        self.so.lmgc90_get_all_bodies(bodies, self.n + self.n_floor)
        coor = np.array([b.coor[:] for b in bodies])
        frame = np.array([b.frame[:] for b in bodies]).reshape(-1, 3, 3)
        return coor[: self.n], frame[: self.n]

    def rotations(self, frame):
        """Body -> world rotations now: the turn since the start (the wheel's own mesh update,
        F_now^T F_0) applied to granpack's initial orientation."""
        return np.einsum("nji,njk,nkl->nil", frame, self.frame0, self.r0)

    def interactions(self):
        nb = F(self.so, "inter_meca_handler_3d_MOD_get_nb_inters")(ctypes.byref(ctypes.c_int(I_PRPRX)))
        if nb <= 0:
            return []
        arr = (Inter * nb)()
        self.so.lmgc90_get_all_inters(arr, nb)
        return arr


def raw_interactions(sim: "Lmgc") -> dict:
    """LMGC90's PRPRx interactions as arrays, one row per interaction: candidate and antagonist
    bodies (0-based; the floor tiles after the grains), the point, its gap, the local frame (t, n,
    s), the reaction (a force in N on the candidate, in that frame) and LMGC90's ``type_ctc``,
    the number of points its detection found for that (candidate, antagonist) call."""
    inters = sim.interactions()
    get_type = F(sim.so, "prprx_MOD_get_type_prprx")
    get_type.restype = ctypes.c_int
    return {"cd": np.array([it.icdbdy - 1 for it in inters], np.int64),
            "an": np.array([it.ianbdy - 1 for it in inters], np.int64),
            "point": np.array([it.coor[:] for it in inters]).reshape(-1, 3),
            "gap": np.array([it.gap for it in inters], np.float64),
            "frame": np.array([it.uc[:] for it in inters]).reshape(-1, 9),
            "rloc": np.array([it.rloc[:] for it in inters]).reshape(-1, 3),
            "type_ctc": np.array([get_type(ctypes.byref(ctypes.c_int(it.icdan))) for it in inters], np.int64)}


def _pair_key(cd: int, an: int, n: int, merge_floor: bool = True) -> tuple[int, int, bool]:
    """granpack's pair of an interaction: the grain of lower index (or the grain, for the floor)
    as i, j = -1 for the floor (or the tile's body, merge_floor False); and whether LMGC90's
    candidate is that i."""
    i, j, flipped = cd, an, False
    if i >= n or (j < n and j < i):
        i, j, flipped = j, i, True
    return i, (j if j < n or not merge_floor else -1), not flipped


def contact_set(raw: dict, n: int, position: np.ndarray, L: float, merge_floor: bool = True):
    """granpack's ContactSet from LMGC90's interactions (``raw_interactions``): the points of a
    pair make one manifold, the grain of lower index (or the grain, for the floor) as i, its
    normal the mean of theirs (from j towards i), impulses in granpack's unit; a grain's points
    on the floor tiles make one manifold with the floor (j = -1), or one per tile (j the tile's
    body) if not merge_floor. LMGC90 finds a pair's points in one detection call, one body as
    candidate (the lower index, but for pairs across the periodic boundary), so the merge is a
    change of sign for some pairs, not a union of two sides (``pairs`` measures it)."""
    from granpack.contact import ContactSet
    from granpack.contact.contacts import contact_types

    rows = {}
    for cd, an, point, gap, uc, r in zip(raw["cd"], raw["an"], raw["point"], raw["gap"], raw["frame"], raw["rloc"]):
        if cd >= n and an >= n:  # two floor tiles
            continue
        t, nrm, s = uc[0:3], uc[3:6], uc[6:9]
        imp = (r[0] * t + r[1] * nrm + r[2] * s) * (H / G)  # impulse over h, rho g d^3 sqrt(d/g)
        i, j, as_cd = _pair_key(int(cd), int(an), n, merge_floor)
        sign = 1.0 if as_cd else -1.0
        rows.setdefault((i, j), []).append((point, float(gap), sign * nrm, sign * imp))
    keys = sorted(rows)
    body_i = np.array([k[0] for k in keys], dtype=np.int64)
    body_j = np.array([k[1] for k in keys], dtype=np.int64)
    shift = np.zeros((len(keys), 3))
    normal = np.zeros((len(keys), 3))
    start = [0]
    pts, gaps, imps = [], [], []
    for m, key in enumerate(keys):
        rs = rows[key]
        nsum = sum(r[2] for r in rs)
        normal[m] = nsum / np.linalg.norm(nsum)
        if 0 <= key[1] < n:
            d = position[key[0], :2] - position[key[1], :2]
            shift[m, :2] = L * np.round(d / L)
        for point, gap, _, imp in rs:
            pts.append(point)
            gaps.append(gap)
            imps.append(imp)
        start.append(len(pts))
    cs = ContactSet(body_i=body_i, body_j=body_j, shift=shift, normal=normal,
                    ctype=np.ones(len(keys), np.int64), point_start=np.array(start, np.int64),
                    point=np.array(pts).reshape(-1, 3), gap=np.array(gaps), impulse=np.array(imps).reshape(-1, 3))
    if len(keys):
        cs.ctype = np.maximum(contact_types(cs, 1e-3 / 3.0), 1)
    return cs


def _velocities(x0, r0, x1, r1, L, dt_gp):
    """Mean velocities over the last step: translation from the centres (unwrapped), rotation
    from R1 R0^T, body frame."""
    dx = x1 - x0
    dx[:, :2] -= L * np.round(dx[:, :2] / L)
    v = dx / dt_gp
    d = np.einsum("nij,nkj->nik", r1, r0)
    angle = np.arccos(np.clip((np.trace(d, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))
    axis = np.stack([d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], axis=1)
    sn = np.sin(angle)
    with np.errstate(invalid="ignore", divide="ignore"):
        w_world = np.where(sn[:, None] > 1e-12, axis * (angle / (2.0 * sn))[:, None], 0.5 * axis) / dt_gp
    omega = np.einsum("nji,nj->ni", r1, w_world)
    return v, omega


def body_velocities(sim: "Lmgc", name: str = "Vbeg_") -> np.ndarray:
    """LMGC90's velocity vector ``name`` of every grain, (n, 6): translation in the world frame
    (m/s), rotation in the body's inertia frame (rad/s), as ``RBDY3`` holds them."""
    get = F(sim.so, "rbdy3_MOD_get_vector_rbdy3")
    out, six = (ctypes.c_double * 6)(), ctypes.c_int(6)
    rows = []
    for b in range(sim.n):
        get(ctypes.c_char_p(name.encode()), ctypes.byref(ctypes.c_int(b + 1)), out, ctypes.byref(six),
            ctypes.c_size_t(5))
        rows.append(out[:])
    return np.array(rows)


def put_body_velocities(sim: "Lmgc", velocity: np.ndarray) -> None:
    """Set every grain's velocity at the beginning of the next step (``Vbeg_`` and ``V____``) to
    ``velocity``, (n, 6), in ``body_velocities``' convention."""
    put, six = F(sim.so, "rbdy3_MOD_put_vector_rbdy3"), ctypes.c_int(6)
    for b in range(sim.n):
        row = (ctypes.c_double * 6)(*velocity[b])
        for name in ("Vbeg_", "V____"):
            put(ctypes.c_char_p(name.encode()), ctypes.byref(ctypes.c_int(b + 1)), row, ctypes.byref(six),
                ctypes.c_size_t(5))


def _resume_state(out: Path, init: dict) -> tuple[dict, dict]:
    """The set-up of a run resumed from ``OUT/lmgc_state.npz``: ``init`` with the saved positions
    and orientations, and the saved counters and velocities (rotation in world axes)."""
    saved = dict(np.load(out / "lmgc_state.npz", allow_pickle=False))
    resumed = dict(init)
    resumed["position"] = saved["position"]
    resumed["quaternion"] = saved["quaternion"]
    frame = saved["frame"]  # rows: the inertia axes in world coordinates
    velocity = saved["velocity"].copy()
    velocity[:, 3:] = np.einsum("nji,nj->ni", frame, velocity[:, 3:])
    counters = json.loads(str(saved["counters"]))
    counters["world_velocity"] = velocity
    return resumed, counters


def _save_state(out: Path, sim: "Lmgc", position, rotation, frame, counters: dict) -> None:
    """``OUT/lmgc_state.npz``, written beside and then moved over the last (never half-written)."""
    tmp = out / "lmgc_state.tmp.npz"
    np.savez(tmp, position=position, quaternion=matrix_to_quat(rotation), frame=frame,
             velocity=body_velocities(sim), counters=json.dumps(counters))
    os.replace(tmp, out / "lmgc_state.npz")


def run_lmgc(out: Path, max_time: float, steps: int | None, resume: bool = False) -> dict:
    from granpack.equilibrium import EquilibriumCriteria, check_equilibrium
    from granpack.io.gsd import write_packing
    from granpack.packing import Packing

    init = dict(np.load(out / "initial.npz"))
    log = open(out / "lmgc.log", "a", buffering=1)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    counters = {"step": 0, "cpu_s": 0.0, "wall_s": 0.0, "sweeps": 0, "setup_cpu_s": 0.0,
                "in_row": {"granpack": 0, "study": 0}, "rest": {"granpack": None, "study": None}}
    if resume:
        start, counters = _resume_state(out, init)
        sim = Lmgc(start)
        # back from world axes into the new set-up's inertia frames
        velocity = counters.pop("world_velocity")
        velocity[:, 3:] = np.einsum("nij,nj->ni", sim.frame0, velocity[:, 3:])
        put_body_velocities(sim, velocity)
        sim.step_count, sim.sweeps = counters["step"], counters["sweeps"]
        init_for_state = start
    else:
        sim = Lmgc(init)
        init_for_state = init
    setup_cpu = time.process_time() - cpu0
    # CPU and wall time carry on from the saved run
    cpu0 -= counters["cpu_s"]
    wall0 -= counters["wall_s"]
    if not resume:
        counters["setup_cpu_s"] = setup_cpu
    n, L = sim.n, sim.L
    log.write(f"# LMGC90 (compas-lmgc90 wheel) {n} grains, L = {L} d, h = {H} sqrt(d/g), theta {THETA}, "
              f"NLGS {NLGS_NORM.strip()} {NLGS_TOL} relax {NLGS_RELAX}, Cundall common plane, alert {ALERT} d; "
              f"set-up {setup_cpu:.1f} CPU s" + (f"; resumed at t = {sim.step_count * H:.2f}" if resume else "") + "\n")
    crit_gp, crit_study = EquilibriumCriteria(), EquilibriumCriteria(**STUDY_CRITERIA)
    cols = ["step", "time", "cpu_s", "wall_s", "sweeps_mean", "sweeps_last", "contacts", "max_overlap",
            "max_net_force", "max_net_torque", "kinetic_energy", "wall_force_over_weight", "gp_ok", "study_ok"]
    if resume:
        _truncate_timeline(out / "lmgc_timeline.csv", sim.step_count)
    timeline = open(out / "lmgc_timeline.csv", "a" if resume else "w", newline="")
    writer = csv.writer(timeline)
    if not resume:
        writer.writerow(cols)
    in_row, rest = counters["in_row"], counters["rest"]
    max_steps = steps if steps is not None else int(round(max_time / H))
    status = "not at rest"
    sweeps_since = 0
    packing = None
    while sim.step_count < max_steps:
        check = (sim.step_count + 1) % CHECK_EVERY == 0 or sim.step_count + 1 == max_steps
        if check:
            x0, f0 = sim.frames()
        sweeps_since += sim.step()
        if not check:
            continue
        x1, f1 = sim.frames()
        r0, r1 = sim.rotations(f0), sim.rotations(f1)
        v, omega = _velocities(x0, r0, x1, r1, L, H)
        t = sim.step_count * H
        state, config = granpack_state(init_for_state, x1, matrix_to_quat(r1), v, omega, t)
        raw = raw_interactions(sim)
        cs = contact_set(raw, n, x1, L)
        rep_gp = check_equilibrium(state, cs, H, criteria=crit_gp)
        rep_st = check_equilibrium(state, cs, H, criteria=crit_study)
        for key, rep in (("granpack", rep_gp), ("study", rep_st)):
            in_row[key] = in_row[key] + 1 if rep.passed else 0
            if in_row[key] == WINDOW and rest[key] is None:
                rest[key] = {"time": t, "step": sim.step_count, "cpu_s": time.process_time() - cpu0}
        cpu = time.process_time() - cpu0
        overlap = float(-cs.gap.min()) if cs.n_points else 0.0
        row = [sim.step_count, t, round(cpu, 2), round(time.perf_counter() - wall0, 2),
               round(sweeps_since / CHECK_EVERY, 1), sim.last_sweeps, cs.n_manifolds, overlap,
               rep_gp.max_net_force, rep_gp.max_net_torque, rep_gp.kinetic_energy, rep_gp.wall_force_over_weight,
               int(rep_gp.passed), int(rep_st.passed)]
        writer.writerow(row)
        timeline.flush()
        sweeps_since = 0
        counters.update(step=sim.step_count, cpu_s=cpu, wall_s=time.perf_counter() - wall0, sweeps=sim.sweeps)
        _save_state(out, sim, x1, r1, f1, counters)
        log.write(f"t={t:.2f} step={sim.step_count} cpu={cpu:.0f}s cpu/step={cpu / sim.step_count:.3f}s "
                  f"sweeps/step={row[4]} contacts={cs.n_manifolds} overlap={overlap:.2e} "
                  f"F={rep_gp.max_net_force:.2e} T={rep_gp.max_net_torque:.2e} E={rep_gp.kinetic_energy:.2e} "
                  f"wall={rep_gp.wall_force_over_weight:.4f} "
                  f"ok(granpack/study)={int(rep_gp.passed)}/{int(rep_st.passed)}\n")
        if sim.step_count % (20 * CHECK_EVERY) == 0 or rest["study"] is not None or sim.step_count >= max_steps:
            status = "equilibrium" if rest["granpack"] is not None else (
                "equilibrium (study criteria)" if rest["study"] is not None else "not at rest")
            names = [str(s) for s in init["population_names"]]
            packing = Packing(state=state, contacts=cs, time_step=H, population_names=names,
                              metadata={"seed": int(init["seed"]), "engine": "LMGC90 (compas-lmgc90 0.1.11)",
                                        "config": str(init["config"]), "status": status, "step": sim.step_count,
                                        "time": t, "cpu_s": cpu, "rest": rest, "nlgs_sweeps": sim.sweeps})
            (out / "lmgc").mkdir(exist_ok=True)
            write_packing(out / "lmgc" / "final.gsd", packing)
            np.savez(out / "lmgc_interactions.npz", position=x1, n=n, lateral_size=L, time=t, **raw)
            (out / "lmgc_summary.json").write_text(json.dumps(
                {"status": status, "steps": sim.step_count, "time": t, "cpu_s": cpu,
                 "setup_cpu_s": counters["setup_cpu_s"],
                 "cpu_per_step_s": cpu / sim.step_count, "nlgs_sweeps_per_step": sim.sweeps / sim.step_count,
                 "rest": rest, "final": dict(zip(cols, row))}, indent=1))
        if rest["granpack"] is not None or (rest["study"] is not None and steps is None):
            break  # at rest by granpack's criteria, or by the study's (five checks in a row)
    log.write(f"# end: {status} at t = {sim.step_count * H:.2f}, {time.process_time() - cpu0:.0f} CPU s\n")
    return json.loads((out / "lmgc_summary.json").read_text())


def _truncate_timeline(path: Path, step: int) -> None:
    """Drop the rows of ``path`` after ``step`` (written after the state a run resumes from)."""
    lines = path.read_text().splitlines(keepends=True)
    kept = [lines[0]] + [ln for ln in lines[1:] if int(ln.split(",", 1)[0]) <= step]
    path.write_text("".join(kept))


# ---------------------------------------------------------------- interactions by pair
def _class(points: int) -> str:
    """A contact type by its number of points, as a study counting points would: 1 simple, 2
    double, 3 or 4 triple (face to face)."""
    return {1: "simple", 2: "double"}.get(points, "triple")


def _counting(sides: list[tuple[int, int]], gp_types: list[int], n: int) -> dict:
    """Contacts per grain (2 x count / grains) of the grain pairs counted three ways: granpack's
    merged manifold (its type from the rank of the points), LMGC90's interactions per pair of
    bodies, and per (candidate, antagonist) ordered pair (LMGC90's own ``type_ctc``)."""
    ways = {"granpack manifold": [{1: "simple", 2: "double", 3: "triple"}[t] for t in gp_types],
            "interactions per pair": [_class(a + b) for a, b in sides],
            "interactions per ordered pair": [_class(k) for a, b in sides for k in (a, b) if k]}
    return {way: {c: round(2 * kinds.count(c) / n, 3) for c in ("simple", "double", "triple")}
            | {"N": round(2 * len(kinds) / n, 3)} for way, kinds in ways.items()}


def pair_table(raw: dict, n: int, position: np.ndarray, L: float) -> dict:
    """How LMGC90's PRPRx interactions group by pair of bodies: for each pair (granpack's merged
    manifold; a grain and a floor tile, not the whole floor), the points found with the
    lower-index grain (or the grain) as candidate (a) and with the other body as candidate (b),
    against the type granpack gives the merged manifold; over all the points within the alert
    distance, and over those bearing a force (rn > 0)."""
    from granpack.contact.contacts import contact_types

    cs = contact_set(raw, n, position, L, merge_floor=False)
    rows = {}
    for k, (cd, an) in enumerate(zip(raw["cd"], raw["an"])):
        if cd < n or an < n:
            i, j, as_cd = _pair_key(int(cd), int(an), n, merge_floor=False)
            rows.setdefault((i, j), []).append((k, as_cd))
    keys = sorted(rows)
    order = np.array([k for key in keys for k, _ in rows[key]], np.int64)  # cs's point order
    force = raw["rloc"][:, 1] > 0.0
    calls = {}  # points per (candidate, antagonist) call, against LMGC90's type_ctc
    for cd, an in zip(raw["cd"], raw["an"]):
        calls[(cd, an)] = calls.get((cd, an), 0) + 1
    type_ok = sum(int(t == calls[(cd, an)]) for cd, an, t in zip(raw["cd"], raw["an"], raw["type_ctc"]))
    out = {"interactions": int(len(raw["gap"])), "interactions_bearing_force": int(force.sum()),
           "type_ctc_equals_points_of_its_call": f"{type_ok} of {len(raw['gap'])}"}
    for label, mask in (("all", np.ones(len(force), bool)), ("bearing_force", force)):
        gp = contact_types(cs, 1e-3 / 3.0, mask=mask[order])
        table, sides, gp_grain = {}, [], []
        pairs = {"grain": 0, "floor": 0, "both_sides": 0}
        for m, key in enumerate(keys):
            a = sum(1 for k, as_cd in rows[key] if as_cd and mask[k])
            b = sum(1 for k, as_cd in rows[key] if not as_cd and mask[k])
            if a + b == 0:
                continue
            kind = "floor" if key[1] >= n else "grain"
            pairs[kind] += 1
            pairs["both_sides"] += int(a > 0 and b > 0)
            cell = table.setdefault(f"{kind} {a}+{b}", {"simple": 0, "double": 0, "triple": 0})
            cell[{1: "simple", 2: "double", 3: "triple"}[int(gp[m])]] += 1
            if kind == "grain":
                sides.append((a, b))
                gp_grain.append(int(gp[m]))
        out[label] = {"pairs": pairs, "points_a+b_vs_granpack_type": dict(sorted(table.items())),
                      "per_grain": _counting(sides, gp_grain, n)}
    return out


def pairs(out: Path) -> dict:
    """``pair_table`` of the latest LMGC90 state a run saved (``OUT/lmgc_interactions.npz``)."""
    d = dict(np.load(out / "lmgc_interactions.npz"))
    raw = {k: d[k] for k in ("cd", "an", "point", "gap", "frame", "rloc", "type_ctc")}
    return {"time": float(d["time"]), "grains": int(d["n"])} | pair_table(
        raw, int(d["n"]), d["position"], float(d["lateral_size"]))


# ---------------------------------------------------------------- the report
def _figures(run_dir: Path, analysis: dict, summary: dict) -> dict:
    """The figures compared: granpack's analysis of one pile."""
    sf, co = analysis.get("solid_fraction", {}), analysis.get("coordination", {})
    ip, eq = analysis.get("interpenetration", {}), analysis.get("equilibrium", {})
    return {"run": str(run_dir), "status": summary.get("status"), "time": summary.get("time"),
            "bulk": analysis.get("bulk"),
            "phi_bulk": sf.get("bulk"), "phi_bulk_std": sf.get("std"), "phi_plateau": sf.get("plateau"),
            "phi_corrected_for_overlap": sf.get("corrected_for_overlap"),
            "k": ip.get("expansion_k"), "k_detail": ip.get("k"), "overlap_max": ip.get("max"),
            "overlap_mean": ip.get("mean"), "fraction_overlapping": ip.get("fraction_overlapping"),
            "fraction_deep": ip.get("fraction_deep"),
            "N": co.get("N"), "Ns": co.get("Ns"), "Nd": co.get("Nd"), "Nt": co.get("Nt"), "Nc": co.get("Nc"),
            "rattler_fraction": co.get("rattler_fraction"), "types_by_gap": co.get("gap_rule"),
            "equilibrium": {k: eq.get(k) for k in ("max_net_force", "max_net_torque", "kinetic_energy",
                                                    "wall_force_over_weight", "passed")}}


def _study_rest(timeline: Path) -> dict | None:
    """When a granpack run first met the study's criteria five checks in a row (its timeline's
    kinetic criterion, largest net force and torque, wall force over weight)."""
    if not timeline.is_file():
        return None
    c = STUDY_CRITERIA
    in_row = 0
    with open(timeline, newline="") as f:
        for row in csv.DictReader(f):
            ok = (float(row["max_net_force"]) <= c["force"] and float(row["max_net_torque"]) <= c["torque"]
                  and float(row["kinetic_criterion"]) <= c["kinetic_energy"]
                  and abs(1.0 - float(row["wall_force_over_weight"])) <= c["wall"])
            in_row = in_row + 1 if ok else 0
            if in_row == WINDOW:
                return {"time": float(row["time"]), "step": int(row["step"]), "cpu_s": float(row["cpu_seconds"])}
    return None


def column_types(run_dir: Path) -> dict:
    """Contact types of the whole column of ``run_dir/final.gsd`` (every grain analysed, the floor
    a boundary), by granpack's rules: the figures two piles too thin for a bulk region can be
    compared by. ``{"all": {N, Ns, Nd, Nt, Nc, rattler_fraction}, population name: {...}}``."""
    from granpack.analysis.coordination import Coordination
    from granpack.io.gsd import read_packing

    packing = read_packing(run_dir / "final.gsd")
    co = Coordination(z_range=(-math.inf, math.inf)).compute(packing)
    result = {"all": co.figures | {"rattler_fraction": co.rattler_fraction}}
    for index, name in enumerate(packing.population_names):
        result[name] = co.figures_of(packing.state.population == index)
    return result


def report(out: Path, gp_run: Path) -> dict:
    from granpack.analysis.report import analyze_run

    result = {}
    lm_summary = json.loads((out / "lmgc_summary.json").read_text())
    lm = analyze_run(out / "lmgc")
    result["lmgc90"] = _figures(out / "lmgc", lm, lm_summary) | {"column_types": column_types(out / "lmgc")} | {
        "cpu_s": lm_summary["cpu_s"], "steps": lm_summary["steps"], "cpu_per_step_s": lm_summary["cpu_per_step_s"],
        "nlgs_sweeps_per_step": lm_summary["nlgs_sweeps_per_step"], "rest": lm_summary["rest"]}
    if (gp_run / "summary.json").is_file():
        gp_summary = json.loads((gp_run / "summary.json").read_text())
        gp = analyze_run(gp_run)
        steps = gp_summary.get("steps") or 0
        result["granpack"] = _figures(gp_run, gp, gp_summary) | {"column_types": column_types(gp_run)} | {
            "time": gp_summary.get("simulated_time"), "steps": steps, "cpu_s": gp_summary.get("cpu_time"),
            "cpu_per_step_s": gp_summary["cpu_time"] / steps if steps else None,
            "nlgs": gp_summary.get("nlgs"), "rest_study_criteria": _study_rest(gp_run / "timeline.csv")}
    return result


def _strict(x):
    """Strict JSON: nan and infinities as null, NumPy scalars as numbers."""
    if isinstance(x, dict):
        return {str(k): _strict(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_strict(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("export")
    e.add_argument("config")
    e.add_argument("out", type=Path)
    r = sub.add_parser("lmgc")
    r.add_argument("out", type=Path)
    r.add_argument("--max-time", type=float, default=300.0)
    r.add_argument("--steps", type=int, default=None)
    r.add_argument("--resume", action="store_true", help="go on from OUT/lmgc_state.npz")
    q = sub.add_parser("pairs")
    q.add_argument("out", type=Path)
    p = sub.add_parser("report")
    p.add_argument("out", type=Path)
    p.add_argument("granpack_run", type=Path)
    a = ap.parse_args(argv)
    if a.cmd == "export":
        res = export(a.config, a.out)
    elif a.cmd == "lmgc":
        res = run_lmgc(a.out, a.max_time, a.steps, a.resume)
    elif a.cmd == "pairs":
        res = pairs(a.out)
    else:
        res = report(a.out, a.granpack_run)
    print(json.dumps(_strict(res), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
