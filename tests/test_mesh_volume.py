"""The volume mesh (`granpack mesh`): exact volumes after the shrink, valid elements, periodic faces,
groups read back from every format, and the one-line errors. Needs gmsh (the mesh extra)."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace

import meshio
import numpy as np
import pytest
from packing_builders import cubic_cubes, fcc_spheres, sphere_column

from granpack.box import Box
from granpack.cli import main
from granpack.contact.contacts import ContactSet
from granpack.errors import InputError
from granpack.io.gsd import write_packing
from granpack.mesh.region import MeshOptions, plan_mesh
from granpack.mesh.volume import TOLERANCE, mesh_packing, mesh_report, tetra_volumes, write_mesh
from granpack.packing import Packing
from granpack.rotations import random_quaternions
from granpack.shapes import Pinacoid, ShapeTable
from granpack.state import ParticleState


def lattice_pinacoids(rng) -> Packing:
    """27 pinacoids of two sizes, turned at random, on a 1 d lattice in a 3 d cell (none touching)."""
    shapes = ShapeTable.from_shapes([Pinacoid.family("isometric", 0.95), Pinacoid.family("isometric", 0.6)])
    cells = np.array([(i, j, k) for i in range(3) for j in range(3) for k in range(3)], dtype=float)
    position = cells + 0.5 + rng.uniform(-0.02, 0.02, cells.shape)
    kind = (rng.random(len(cells)) < 0.4).astype(np.int64)
    state = ParticleState(box=Box.square(3.0), shapes=shapes, kind=kind, population=kind, position=position,
                          quaternion=random_quaternions(len(cells), rng))
    return Packing(state, ContactSet.empty(), 5e-3, ["big", "small"], {"seed": 1})


def packing_kind(plan):
    """``(N,)`` shape kind of each grain, from the bodies of the plan (-1: not in the box)."""
    kind = np.full(len(plan.grain_volume), -1)
    kind[plan.instances.grain] = plan.instances.kind
    return kind


def assert_exact(plan, mesh):
    """The aggregate fraction and every grain's volume within the tolerance; no inverted element."""
    report = mesh_report(plan, mesh)
    assert report["checks"] == {"aggregate_fraction": True, "grain_volumes": True, "positive_volumes": True, "mean_quality": True}
    volume = tetra_volumes(mesh.points, mesh.tetra)
    assert volume.min() > 0 and mesh.sicn.min() > 0
    meshed = volume[mesh.phase == 1].sum() / plan.volume
    assert abs(meshed / plan.solid_fraction - 1) < TOLERANCE
    assert math.isclose(volume.sum(), plan.volume, rel_tol=1e-9)  # the phases tile the box
    per_grain = np.bincount(mesh.grain[mesh.grain >= 0], weights=volume[mesh.grain >= 0], minlength=len(plan.grain_volume))
    inside = plan.grain_volume > 0
    assert np.array_equal(per_grain > 0, inside)
    whole = plan.shapes.volume[packing_kind(plan)]
    assert np.all(np.abs(per_grain[inside] - plan.grain_volume[inside]) / whole[inside] < TOLERANCE)
    return report


@pytest.fixture(scope="module")
def gmsh():
    try:
        return pytest.importorskip("gmsh", reason="the mesh extra (gmsh) is not installed")
    except OSError as exc:  # installed, but its shared libraries are missing here
        pytest.skip(f"gmsh does not load: {exc}")


def test_touching_spheres_shrunk_apart_and_periodic(gmsh):
    """An FCC crystal (every sphere touching 12): the cell's full width, periodic in x and y."""
    packing, a = fcc_spheres(1, 4)
    plan, mesh = mesh_packing(packing, MeshOptions(box=(0, 0, 2.2, a, a, 3.28), periodic=True))
    assert plan.full_width and plan.gap == pytest.approx(0.02) and plan.min_clearance == pytest.approx(0.02)
    assert np.allclose(plan.scale, 1 - 0.02 / 1.0)
    assert plan.solid_fraction == pytest.approx(plan.solid_fraction_unshrunk * 0.98**3, rel=0.02)
    report = assert_exact(plan, mesh)
    assert report["quality"]["mean_gamma"] > 0.6
    # periodic: every node of the x / y max faces has its master on the min face, one period away
    lo, hi = np.array(plan.box[:3]), np.array(plan.box[3:])
    slave, master = mesh.points[mesh.periodic[:, 0]], mesh.points[mesh.periodic[:, 1]]
    shift = slave - master
    along_x = np.all(np.abs(shift - [hi[0] - lo[0], 0, 0]) < 1e-9, axis=1)
    along_y = np.all(np.abs(shift - [0, hi[1] - lo[1], 0]) < 1e-9, axis=1)
    assert np.all(along_x | along_y) and along_x.any() and along_y.any()
    assert report["periodic_mismatch"] < 1e-9
    for name, axis in (("xmax", 0), ("ymax", 1)):
        nodes = np.unique(mesh.faces[name])
        assert np.allclose(mesh.points[nodes, axis], hi[axis])
        assert set(nodes) <= set(mesh.periodic[:, 0])  # every node of the face is matched
        twin = np.unique(mesh.faces[name.replace("max", "min")])
        assert len(twin) == len(nodes)


def test_touching_cubes_face_to_face(gmsh):
    """Cubes stacked face to face: matrix slabs one gap thick between all of them."""
    packing, edge = cubic_cubes(cells_xy=2, layers=4)
    plan, mesh = mesh_packing(packing, MeshOptions(box=(0, 0, 0.3, 2 * edge, 2 * edge, 1.33)))
    assert plan.solid_fraction_unshrunk == pytest.approx(1.0)
    s = plan.scale[0]
    centres = (np.arange(4) + 0.5) * edge
    z0, z1 = plan.box[2], plan.box[5]
    height = np.clip(centres + s * edge / 2, z0, z1) - np.clip(centres - s * edge / 2, z0, z1)
    assert plan.solid_fraction == pytest.approx(s**2 * height.sum() / (z1 - z0), rel=1e-12)  # by hand
    assert_exact(plan, mesh)


def test_itz_and_every_format(gmsh, rng, tmp_path):
    packing = lattice_pinacoids(rng)
    box = (0.0, 0.0, 0.8, 3.0, 3.0, 2.2)
    options = MeshOptions(box=box, gap=0.05, itz=0.01, grain_groups=True)
    paths, report = write_mesh(tmp_path / "m.msh", packing, options)
    assert [p.name for p in paths] == ["m.json", "m.msh"]
    assert json.loads(paths[0].read_text())["checks"] == report["checks"]
    assert all(report["checks"].values())
    assert report["elements"]["itz"] > 0 and report["volumes"]["itz"] > 0
    grains_in_box = report["grains"]
    native = meshio.read(paths[1])
    names = set(native.field_data)
    assert {"aggregate", "matrix", "itz", "xmin", "zmax"} <= names
    assert len([n for n in names if n.startswith("grain_")]) == grains_in_box

    for suffix, more in ((".inp", {}), (".xdmf", {"size_factor": 1.0, "curvature": 8})):
        if suffix == ".xdmf":
            pytest.importorskip("h5py", reason="meshio writes XDMF's heavy data with h5py (the mesh extra)")
        write_mesh(tmp_path / f"m{suffix}", packing, replace(options, **more))
        back = meshio.read(tmp_path / f"m{suffix}")
        tetra = back.get_cells_type("tetra")
        assert tetra_volumes(back.points, tetra).min() > 0
        if suffix == ".inp":
            assert len(tetra) == report["elements"]["tetra"]
            sets = {name.lower() for name in back.cell_sets}
            assert {"aggregate", "matrix", "itz"} <= sets and len([s for s in sets if s.startswith("grain_")]) == grains_in_box
            assert {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"} <= {name.lower() for name in back.point_sets}
        else:
            phase, grain = back.cell_data["phase"][0], back.cell_data["grain"][0]
            assert set(phase.tolist()) == {1, 2, 3} and np.array_equal(grain >= 0, phase == 1)
            assert len(set(grain.tolist()) - {-1}) == grains_in_box
    assert (tmp_path / "m.h5").is_file()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_bad_options_are_one_line(rng):
    packing = lattice_pinacoids(rng)
    cases = [
        (MeshOptions(box=(0, 0, 0, 9, 3, 2)), "--box 0 0 0 9 3 2: outside the packing"),
        (MeshOptions(box=(0, 0, 1, 3, 3, 1.5)), "thinner than the largest grain"),
        (MeshOptions(box=(0, 0, 1, 2, 2, 2.5), periodic=True), "--periodic needs the cell's full width"),
        (MeshOptions(box=(0, 0, 0.8, 3, 3, 2.2), itz=0.5), "--itz 0.5: thicker than the gaps allow"),
        (MeshOptions(gap=0.4), "--gap 0.4: too large"),
        (MeshOptions(size=-1.0), "--size must be a number > 0"),
        (MeshOptions(curvature=3), "--curvature must be a whole number >= 8"),
    ]
    for options, message in cases:
        with pytest.raises(InputError) as info:
            plan_mesh(packing, options)
        assert message in str(info.value) and "\n" not in str(info.value)
    low, _ = fcc_spheres(1, 1)  # one layer of cells: no bulk to cut the default box from
    with pytest.raises(InputError, match="the packing has no bulk region .* give the region with --box"):
        plan_mesh(low, MeshOptions())
    overlapping = sphere_column(side=2, layers=6, overlap=0.02)
    with pytest.raises(InputError, match="--gap 0.02: the packing's grains overlap by up to 0.02 d"):
        plan_mesh(overlapping, MeshOptions())


def run_cli(args, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    out = capsys.readouterr()
    return info.value.code, out.out, out.err.strip()


def test_mesh_command(gmsh, rng, tmp_path, capsys):
    write_packing(tmp_path / "final.gsd", lattice_pinacoids(rng))
    code, out, err = run_cli(["mesh", str(tmp_path), "--out", str(tmp_path / "out" / "m.vtu"), "--box", "0", "0", "0.8", "3", "3",
                              "2.2"], capsys)
    assert code == 0 and "tetrahedra" in out and err == ""
    assert (tmp_path / "out" / "m.vtu").is_file() and (tmp_path / "out" / "m.json").is_file()

    for args, message in [
        (["--out", str(tmp_path / "m.stl")], "error: --out"),
        (["--out", str(tmp_path / "m.vtu"), "--itz", "0.5", "--box", "0", "0", "0.8", "3", "3", "2.2"], "error: --itz 0.5"),
    ]:
        code, _, err = run_cli(["mesh", str(tmp_path), *args], capsys)
        assert code == 2 and err.startswith(message) and len(err.splitlines()) == 1
    assert "'.stl'; one of .msh, .inp, .xdmf, .vtu" in run_cli(["mesh", str(tmp_path), "--out", "m.stl"], capsys)[2]
    assert not (tmp_path / "m.vtu").exists() and [p for p in tmp_path.iterdir() if p.name.startswith(".")] == []

    code, _, err = run_cli(["mesh", str(tmp_path / "nowhere"), "--out", str(tmp_path / "m.msh")], capsys)
    assert code == 2 and "final.gsd: file not found" in err

    (tmp_path / "summary.json").write_text('{"status": "equilibrium"}')  # a run's own file is never replaced
    code, _, err = run_cli(["mesh", str(tmp_path), "--out", str(tmp_path / "summary.msh")], capsys)
    assert code == 2 and "its report would replace" in err and (tmp_path / "summary.json").read_text() == '{"status": "equilibrium"}'
    # an earlier mesh's report is replaced with its mesh
    code, *_ = run_cli(["mesh", str(tmp_path), "--out", str(tmp_path / "out" / "m.vtu"), "--box", "0", "0", "0.8", "3", "3",
                        "2.2", "--size-factor", "0.5"], capsys)
    assert code == 0


def test_cli_defaults_are_the_library_ones():
    import typer.main

    from granpack.cli import app
    from granpack.mesh.region import CURVATURE, SIZE_FACTOR

    defaults = {p.name: p.default for p in typer.main.get_command(app).commands["mesh"].params}
    assert defaults["size_factor"] == SIZE_FACTOR and defaults["curvature"] == CURVATURE


def test_missing_extra_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "gmsh", None)  # import gmsh raises ImportError
    code, _, err = run_cli(["mesh", str(tmp_path), "--out", str(tmp_path / "m.msh")], capsys)
    assert code == 2 and err == 'error: granpack mesh needs gmsh (GPL, an optional extra): pip install "granpack[mesh]"'


def test_a_gmsh_failure_is_one_line(gmsh):
    from granpack.mesh._gmsh import _failure

    gmsh.initialize()
    try:
        with pytest.raises(InputError) as info, _failure("could not mesh the box"):
            gmsh.model.occ.fragment([(3, 99)], [(3, 98)])  # no such volumes
    finally:
        gmsh.finalize()
    message = str(info.value)
    assert message.startswith("gmsh could not mesh the box (") and "--gap" in message and "\n" not in message


def test_checks_not_met_are_said(gmsh, tmp_path, capsys):
    """Coarse sphere facets (8 per turn) lose some 15 % of the volume: the mesh is written, the checks say so."""
    packing, a = fcc_spheres(1, 4)
    write_packing(tmp_path / "final.gsd", packing)
    code, out, err = run_cli(["mesh", str(tmp_path), "--out", str(tmp_path / "m.msh"), "--curvature", "8",
                              "--box", "0", "0", "2.2", str(a), str(a), "3.28"], capsys)
    assert code == 0 and "tetrahedra" in out
    assert err.startswith("checks not met: aggregate_fraction, grain_volumes (") and len(err.splitlines()) == 1
    report = json.loads((tmp_path / "m.json").read_text())
    assert report["aggregate_fraction"]["relative_error"] < -0.05 and report["checks"]["positive_volumes"]


def test_gmsh_without_its_system_libraries_is_one_line(tmp_path, capsys, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def failing(name, *args, **kwargs):
        if name == "gmsh":
            raise OSError("libGLU.so.1: cannot open shared object file: No such file or directory")
        return real_import(name, *args, **kwargs)

    monkeypatch.delitem(sys.modules, "gmsh", raising=False)
    monkeypatch.setattr(builtins, "__import__", failing)
    code, _, err = run_cli(["mesh", str(tmp_path), "--out", str(tmp_path / "m.msh")], capsys)
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith("error: granpack mesh: gmsh is installed but does not load (libGLU.so.1") and "apt install" in err
