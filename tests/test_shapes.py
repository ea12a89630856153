"""Exact checks of shapes: pinacoid closed forms, Platonic solids, polyhedron validation."""

import math
from pathlib import Path

import numpy as np
import pytest

from granpack.shapes import (
    PINACOID_FAMILIES,
    ConvexPolyhedron,
    Pinacoid,
    ShapeError,
    ShapeTable,
    Sphere,
    platonic,
    polyhedron_of_size,
)

SIZES = [1.0, 1.0 / 3.0, 2.5]


def closed_form(L, G, E, alpha=math.radians(60)):
    """docs/method/grains.md#the-pinacoid: exact V and principal moments (unit density) of a pinacoid."""
    l = L - E / math.tan(alpha)
    V = E * G * (2 * L + l) / 6
    sxx = E * G * (4 * L**3 + 3 * L**2 * l + 2 * L * l**2 + l**3) / 240
    syy = E * G**3 * (4 * L + l) / 240
    szz = E**3 * G * (2 * L + 3 * l) / 240
    return V, np.array([syy + szz, sxx + szz, sxx + syy])


def quadrature_mass_properties(p: Pinacoid, n=400):
    """Independent midpoint quadrature over horizontal rectangle slices of the upper half (doubled)."""
    L, G, E, l = p.length, p.width, p.thickness, p.ridge
    dz = (E / 2) / n
    z = (np.arange(n) + 0.5) * dz
    a = L / 2 - (L - l) * z / E  # half-length of the slice rectangle
    b = (G / 2) * (1 - 2 * z / E)  # half-width
    area = 4 * a * b
    V = 2 * area.sum() * dz
    sxx = 2 * (2 * b * (2 * a**3 / 3)).sum() * dz
    syy = 2 * (2 * a * (2 * b**3 / 3)).sum() * dz
    szz = 2 * (area * z**2).sum() * dz
    return V, np.array([syy + szz, sxx + szz, sxx + syy])


@pytest.mark.parametrize("family", list(PINACOID_FAMILIES))
@pytest.mark.parametrize("size", SIZES)
def test_pinacoid_volume_and_inertia_closed_form(family, size):
    p = Pinacoid.family(family, size)
    L, G, E = p.length, p.width, p.thickness
    assert p.volume == pytest.approx((E * G / 2) * (L - E / (3 * math.sqrt(3))), rel=1e-12)
    V, J = closed_form(L, G, E)
    assert p.volume == pytest.approx(V, rel=1e-12)
    np.testing.assert_allclose(p.principal_moments, J, rtol=1e-11)
    # inertia ascending along x (length), y, z (thickness)
    assert p.principal_moments[0] < p.principal_moments[1] < p.principal_moments[2]


@pytest.mark.parametrize("family", list(PINACOID_FAMILIES))
def test_pinacoid_against_independent_quadrature(family):
    p = Pinacoid.family(family, 1.0)
    V, J = quadrature_mass_properties(p)
    assert p.volume == pytest.approx(V, rel=1e-5)
    np.testing.assert_allclose(p.principal_moments, J, rtol=1e-4)


@pytest.mark.parametrize("family", list(PINACOID_FAMILIES))
@pytest.mark.parametrize("size", SIZES)
def test_pinacoid_topology_and_frame(family, size):
    p = Pinacoid.family(family, size)
    assert len(p.vertices) == 8 and len(p.edges) == 14 and len(p.faces) == 8
    assert sorted(p.face_kinds()) == [3, 3, 3, 3, 4, 4, 4, 4]
    assert p.size == pytest.approx(size, rel=1e-12)
    assert p.size == pytest.approx(math.hypot(p.length, p.width), rel=1e-12)
    np.testing.assert_allclose(p.vertices.mean(axis=0), 0.0, atol=1e-12 * size)
    np.testing.assert_allclose(p.rotation, np.eye(3))  # inertia already diagonal in (L, G, E)
    assert p.is_centrally_symmetric
    # every vertex inside or on every face plane (convexity), faces planar
    d = p.vertices @ p.face_normals.T - p.face_offsets
    assert d.max() < 1e-12
    for f, n, off in zip(p.faces, p.face_normals, p.face_offsets):
        np.testing.assert_allclose(p.vertices[f] @ n, off, atol=1e-12)
    # end faces at 60 degrees to the mid-plane; 4 distinct face axes, 6 edge directions
    tri = [n for f, n in zip(p.faces, p.face_normals) if len(f) == 3]
    for n in tri:
        assert math.degrees(math.acos(abs(n[2]))) == pytest.approx(60.0, abs=1e-9)
    assert len(p.face_axes) == 4 and len(p.edge_directions) == 6


def test_pinacoid_rejects_bad_dimensions():
    with pytest.raises(ShapeError, match="aspect"):
        Pinacoid.from_size(1.0, 0.5, 1.0)
    with pytest.raises(ShapeError, match="L >= G >= E"):
        Pinacoid(1.0, 2.0, 0.5)
    with pytest.raises(ShapeError, match="ridge"):
        Pinacoid(0.5, 0.5, 0.5, alpha_deg=20.0)


@pytest.mark.parametrize("edge", [1.0, 0.3])
def test_cube_textbook(edge):
    c = platonic("cube", edge * math.sqrt(3))
    assert c.volume == pytest.approx(edge**3, rel=1e-12)
    np.testing.assert_allclose(c.principal_moments, c.mass * edge**2 / 6, rtol=1e-12)
    assert len(c.faces) == 6 and len(c.edges) == 12 and all(k == 4 for k in c.face_kinds())


def test_regular_tetrahedron_textbook():
    t = platonic("tetrahedron", 1.0)
    a = np.linalg.norm(t.vertices[0] - t.vertices[1])
    # circumradius R = a sqrt(6)/4
    assert t.circumscribed_radius == pytest.approx(a * math.sqrt(6) / 4, rel=1e-12)
    assert t.volume == pytest.approx(a**3 / (6 * math.sqrt(2)), rel=1e-12)
    np.testing.assert_allclose(t.principal_moments, t.mass * a**2 / 20, rtol=1e-12)
    assert len(t.faces) == 4 and len(t.edges) == 6


@pytest.mark.parametrize(
    "name, faces, edges, vertex_count",
    [("octahedron", 8, 12, 6), ("dodecahedron", 12, 30, 20), ("icosahedron", 20, 30, 12)],
)
def test_other_platonic_solids(name, faces, edges, vertex_count):
    s = platonic(name, 1.0)
    assert (len(s.faces), len(s.edges), len(s.vertices)) == (faces, edges, vertex_count)
    assert s.size == pytest.approx(1.0)
    m = s.principal_moments
    np.testing.assert_allclose(m, m[0], rtol=1e-10)  # isotropic inertia


def test_octahedron_volume():
    s = platonic("octahedron", 2.0)  # vertices at +-1 on the axes
    assert s.volume == pytest.approx(4 / 3, rel=1e-12)
    # J = m a^2 / 10 with a = edge length sqrt(2)
    np.testing.assert_allclose(s.principal_moments, s.mass * 2 / 10, rtol=1e-12)


def test_user_polyhedron_recentred_and_principal(rng):
    # a box with sides 1, 2, 3, shifted and rotated: principal frame recovered
    box = np.array([[x, y, z] for x in (0, 1) for y in (0, 2) for z in (0, 3)], float)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    p = ConvexPolyhedron(box @ q.T + [5.0, -1.0, 2.0])
    assert p.volume == pytest.approx(6.0, rel=1e-12)
    np.testing.assert_allclose(p.vertices.mean(axis=0), 0.0, atol=1e-12)
    m = 6.0
    expected = sorted([m * (4 + 9) / 12, m * (1 + 9) / 12, m * (1 + 4) / 12])
    np.testing.assert_allclose(p.principal_moments, expected, rtol=1e-10)
    # inertia in the body frame is diagonal: recompute it from the stored vertices
    from granpack.shapes import mass_properties

    _, c, J = mass_properties(p.vertices, p.faces)
    np.testing.assert_allclose(J, np.diag(expected), atol=1e-10)


def test_polyhedron_of_size_scales_to_circumscribed_diameter():
    p = polyhedron_of_size([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], 0.5)
    assert p.size == pytest.approx(0.5)


@pytest.mark.parametrize(
    "vertices, match",
    [
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]], "coplanar"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "at least 4"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.1, 0.1, 0.1]], "not an extreme point"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1]], "not an extreme point"),
    ],
)
def test_polyhedron_rejects_degenerate_and_nonconvex(vertices, match):
    with pytest.raises(ShapeError, match=match):
        ConvexPolyhedron(vertices)


def test_sphere_mass_properties():
    s = Sphere(0.5)
    assert s.volume == pytest.approx(math.pi * 0.125 / 6)
    np.testing.assert_allclose(s.principal_moments, s.mass * 0.25 / 10)
    assert s.size == 0.5
    with pytest.raises(ShapeError):
        Sphere(0.0)


def test_shape_table_layout():
    shapes = [Sphere(1.0), Pinacoid.family("flat", 1 / 3), platonic("cube", 1.0)]
    t = ShapeTable.from_shapes(shapes)
    assert list(t.is_sphere) == [True, False, False]
    assert list(np.diff(t.vertex_start)) == [0, 8, 8]
    assert list(np.diff(t.face_start)) == [0, 8, 6]
    assert list(np.diff(t.edge_start)) == [0, 14, 12]
    assert len(t.face_vertex_start) == 8 + 6 + 1
    # face rows of the cube use local vertex indices 0..7
    k = 2
    f0 = t.face_start[k]
    verts = t.face_vertices[t.face_vertex_start[f0] : t.face_vertex_start[f0 + 1]]
    assert verts.max() < 8
    np.testing.assert_allclose(t.vertices[t.vertex_start[k] :][verts] @ t.face_normals[f0], t.face_offsets[f0])
    np.testing.assert_allclose(t.radius, [0.5, 1 / 6, 0.5])


def _blas_kernels() -> list[str]:
    """Two OpenBLAS kernels this CPU runs that round a dot product differently where it can:
    the AVX-512 kernel beside the AVX2 one, else two AVX2-era ones."""
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return []
    if " avx512f" in flags:
        return ["SkylakeX", "Haswell"]
    return ["Haswell", "Sandybridge"] if " avx2" in flags else []


_TABLE_BYTES = """
import hashlib, numpy as np
from granpack.shapes import PINACOID_FAMILIES, Pinacoid, ShapeTable
t = ShapeTable.from_shapes([Pinacoid.family(f, s) for f in PINACOID_FAMILIES for s in (1.0, 1 / 3)])
h = hashlib.sha256()
for name, value in sorted(vars(t).items()):
    if isinstance(value, np.ndarray):
        h.update(name.encode()); h.update(value.tobytes())
print(h.hexdigest())
"""


@pytest.mark.skipif(len(_blas_kernels()) < 2, reason="needs an x86-64 Linux CPU with AVX2")
def test_shape_table_has_the_same_bits_whatever_the_blas_kernel():
    """The machine picks OpenBLAS's kernel and the kernels round the last bit differently (the
    elongated pinacoid's edge directions did): the shapes, hence every packing of a seed, must not
    depend on it."""
    import os
    import subprocess
    import sys

    digests = {
        kernel: subprocess.run([sys.executable, "-c", _TABLE_BYTES], capture_output=True, text=True, check=True,
                               env={**os.environ, "OPENBLAS_CORETYPE": kernel}).stdout.strip()
        for kernel in _blas_kernels()
    }
    assert len(set(digests.values())) == 1, digests
