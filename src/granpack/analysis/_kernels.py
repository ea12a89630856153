"""Numba kernels of the analysis: exact slice volumes and pair-distance histograms."""

from __future__ import annotations

import numpy as np

from granpack._numba import jit


@jit
def _polygon_below(poly, count, h, out):
    """Sutherland–Hodgman clip of polygon ``poly[:count]`` (3D points) to ``z <= h``; returns the new count."""
    m = 0
    for k in range(count):
        p = poly[k]
        q = poly[(k + 1) % count]
        p_in = p[2] <= h
        q_in = q[2] <= h
        if p_in:
            out[m, 0] = p[0]
            out[m, 1] = p[1]
            out[m, 2] = p[2]
            m += 1
        if p_in != q_in:
            t = (h - p[2]) / (q[2] - p[2])
            out[m, 0] = p[0] + t * (q[0] - p[0])
            out[m, 1] = p[1] + t * (q[1] - p[1])
            out[m, 2] = h
            m += 1
    return m


@jit
def _volume_below(verts, face_start, face_vertices, face_offsets, normals, h, poly, clipped):
    """Volume of a convex polyhedron below the plane ``z = h`` (divergence theorem, docs/method/analysis.md#solid-fraction).

    ``verts`` are centred on the centroid (so ``face_offsets`` hold for them), ``normals`` are the
    rotated outward face normals.

    .. math:: V_{below}(h) = \\frac13\\Big(\\sum_f \\delta_f (A_f \\cdot n_f) + h A_{cap}\\Big),
              \\quad A_{cap} = -\\sum_f (A_f)_z
    """
    total = 0.0
    cap = 0.0
    for f in range(len(face_offsets)):
        a, b = face_start[f], face_start[f + 1]
        count = b - a
        for k in range(count):
            v = face_vertices[a + k]
            poly[k, 0] = verts[v, 0]
            poly[k, 1] = verts[v, 1]
            poly[k, 2] = verts[v, 2]
        m = _polygon_below(poly, count, h, clipped)
        if m < 3:
            continue
        ax = 0.0
        ay = 0.0
        az = 0.0
        for k in range(m):
            p = clipped[k]
            q = clipped[(k + 1) % m]
            ax += p[1] * q[2] - p[2] * q[1]
            ay += p[2] * q[0] - p[0] * q[2]
            az += p[0] * q[1] - p[1] * q[0]
        ax *= 0.5
        ay *= 0.5
        az *= 0.5
        total += face_offsets[f] * (ax * normals[f, 0] + ay * normals[f, 1] + az * normals[f, 2])
        cap -= az
    return (total + h * cap) / 3.0


@jit
def _sphere_below(radius, u):
    """Volume of a ball of radius ``radius`` centred at 0 below ``z = u``: ``F(u) - F(-R)``, F = π(R²u - u³/3)."""
    if u <= -radius:
        return 0.0
    if u >= radius:
        u = radius
    r2 = radius * radius
    return np.pi * (r2 * u - u * u * u / 3.0) + np.pi * (2.0 / 3.0) * r2 * radius


@jit
def slice_volumes_kernel(
    z0,
    dz,
    nslices,
    group,
    ngroups,
    position,
    rotation,
    kind,
    is_sphere,
    radius,
    volume,
    vertex_start,
    vertices,
    face_start,
    face_normals,
    face_offsets,
    face_vertex_start,
    face_vertices,
):
    """Exact volume of every particle inside the slices ``[z0 + k dz, z0 + (k+1) dz)``, summed per group.

    Args:
        z0, dz, nslices: the uniform slicing, d.
        group: ``(N,)`` int64 group of each particle (population), ``0 <= group < ngroups``.
        position: ``(N, 3)``; rotation: ``(N, 3, 3)`` body -> world.
        kind ... face_vertices: the :class:`~granpack.shapes.ShapeTable` arrays.

    Returns:
        ``(ngroups, nslices)`` volumes, d^3. Parts of grains outside ``[z0, z0 + nslices dz)`` are
        not counted.
    """
    out = np.zeros((ngroups, nslices))
    max_face = 3
    for f in range(len(face_vertex_start) - 1):
        max_face = max(max_face, face_vertex_start[f + 1] - face_vertex_start[f])
    poly = np.empty((max_face, 3))
    clipped = np.empty((2 * max_face + 2, 3))
    verts = np.empty((0, 3))
    normals = np.empty((0, 3))
    fstart = np.zeros(1, dtype=np.int64)
    fverts = np.zeros(0, dtype=np.int64)
    offsets = np.zeros(0)
    for p in range(len(kind)):
        k = kind[p]
        zc = position[p, 2]
        g = group[p]
        if is_sphere[k]:
            r = radius[k]
            lo = zc - r
            hi = zc + r
        else:
            va, vb = vertex_start[k], vertex_start[k + 1]
            verts = np.empty((vb - va, 3))
            rot = rotation[p]
            lo = np.inf
            hi = -np.inf
            for v in range(vb - va):
                for c in range(3):
                    verts[v, c] = rot[c, 0] * vertices[va + v, 0] + rot[c, 1] * vertices[va + v, 1] + rot[c, 2] * vertices[va + v, 2]
                lo = min(lo, zc + verts[v, 2])
                hi = max(hi, zc + verts[v, 2])
            fa, fb = face_start[k], face_start[k + 1]
            normals = np.empty((fb - fa, 3))
            for f in range(fb - fa):
                for c in range(3):
                    normals[f, c] = (
                        rot[c, 0] * face_normals[fa + f, 0] + rot[c, 1] * face_normals[fa + f, 1] + rot[c, 2] * face_normals[fa + f, 2]
                    )
            fstart = face_vertex_start[fa : fb + 1] - face_vertex_start[fa]
            fverts = face_vertices[face_vertex_start[fa] : face_vertex_start[fb]]
            offsets = face_offsets[fa:fb]
        first = int(np.floor((lo - z0) / dz))
        last = int(np.floor((hi - z0) / dz))
        if last < 0 or first >= nslices:
            continue
        first = max(first, 0)
        last = min(last, nslices - 1)
        below = 0.0
        plane = z0 + first * dz - zc
        if is_sphere[k]:
            below = _sphere_below(radius[k], plane)
        elif plane > lo - zc:
            below = _volume_below(verts, fstart, fverts, offsets, normals, plane, poly, clipped)
        for s in range(first, last + 1):
            plane = z0 + (s + 1) * dz - zc
            if is_sphere[k]:
                above = _sphere_below(radius[k], plane)
            elif plane >= hi - zc:
                above = volume[k]
            else:
                above = _volume_below(verts, fstart, fverts, offsets, normals, plane, poly, clipped)
            out[g, s] += above - below
            below = above
    return out


@jit
def pair_histogram_kernel(position, is_ref, group, ngroups, lx, ly, lz, r_max, nbins):
    """Ordered-pair distance histogram between reference particles and all others.

    Args:
        position: ``(n, 3)`` centres **sorted by z** (the loop stops once ``dz > r_max``).
        is_ref: ``(n,)`` bool, reference particles.
        group: ``(n,)`` int64 group (population) of each particle.
        lx, ly: periods in x, y, or both 0 in a box or a cylinder (nothing periodic); lz: period
            in z, or 0 for a non-periodic direction.
        r_max, nbins: uniform bins ``[b r_max / nbins, (b+1) r_max / nbins)``.

    Returns:
        ``(ngroups, ngroups, nbins)`` counts ``n[a, b, k]`` of pairs (reference of group a,
        neighbour of group b) in bin k.
    """
    counts = np.zeros((ngroups, ngroups, nbins), dtype=np.int64)
    n = len(position)
    r2max = r_max * r_max
    width = r_max / nbins
    for i in range(n):
        for j in range(i + 1, n):
            dz = position[j, 2] - position[i, 2]
            if lz == 0.0 and dz > r_max:
                break
            if lz > 0.0:
                dz -= lz * np.round(dz / lz)
            dx = position[j, 0] - position[i, 0]
            dy = position[j, 1] - position[i, 1]
            if lx > 0.0:
                dx -= lx * np.round(dx / lx)
                dy -= ly * np.round(dy / ly)
            r2 = dx * dx + dy * dy + dz * dz
            if r2 >= r2max:
                continue
            b = int(np.sqrt(r2) / width)
            if b >= nbins:
                continue
            if is_ref[i]:
                counts[group[i], group[j], b] += 1
            if is_ref[j]:
                counts[group[j], group[i], b] += 1
    return counts
