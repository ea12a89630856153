"""Mixtures: grain populations given by volume share -> particle counts for N grains.

The config gives each population's share ``f_i`` of the solid volume (docs/method/grains.md#mixtures-volume-shares-to-counts). With
particle volumes ``v_i`` (d^3) and counts ``n_i`` summing to N, the achieved share is

.. math:: s_i = \\frac{n_i v_i}{\\sum_j n_j v_j},

and :func:`volume_share_counts` picks the integer counts that make ``s`` closest to ``f``: smallest
largest error ``max_i |s_i - f_i|``, ties broken by the smallest total error
``sum_i |s_i - f_i|``. A population with share 0 gets no grain; every other one gets at least
one grain when N allows it.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from granpack.config import PopulationConfig, RunConfig
from granpack.shapes import Shape, ShapeTable

__all__ = ["Mixture", "volume_share_counts"]


#: solid fraction at which a settled pile of one grain size is expected to stand (measured
#: 0.61-0.67 for the pinacoid and sphere piles)
PHI_ONE_SIZE = 0.6
#: the same for a mix of sizes (measured 0.70-0.74 for mixes of sizes 1 and 1/3)
PHI_MIXED_SIZES = 0.72

def _mean_volume(shapes, weights) -> float:
    """Mean volume of a grain of a population whose shapes have number shares ``weights``, d^3."""
    if len(shapes) == 1:
        return shapes[0].volume
    return float(sum(w * s.volume for w, s in zip(weights, shapes)))


def _errors(counts: np.ndarray, shares: np.ndarray, volumes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest and total share error of each row of ``counts`` ``(C, K)``."""
    solid = counts * volumes
    err = np.abs(solid / solid.sum(axis=1, keepdims=True) - shares)
    return err.max(axis=1), err.sum(axis=1)


def _rounded(ideal: np.ndarray, n: int, minimum: int) -> np.ndarray:
    """Integer counts near ``ideal`` (largest remainders), each >= ``minimum``, summing to ``n``."""
    counts = np.maximum(np.floor(ideal).astype(np.int64), minimum)
    order = np.argsort(-(ideal - np.floor(ideal)), kind="stable")
    k = 0
    while counts.sum() < n:
        counts[order[k % len(counts)]] += 1
        k += 1
    while counts.sum() > n:
        counts[int(np.argmax(np.where(counts > minimum, counts - ideal, -np.inf)))] -= 1
    return counts


def volume_share_counts(shares, volumes, n_particles: int) -> np.ndarray:
    """Particle counts whose volume shares are closest to ``shares``.

    Exact search: a rounding of the continuous solution :math:`n_i \\propto f_i / v_i` gives a
    largest error ``E``; any composition at least as good has every ``s_i`` in
    ``[f_i - E, f_i + E]``, which bounds each ``n_i`` to a small window, and the windows are
    searched exhaustively.

    Args:
        shares: ``(K,)`` requested volume shares ``f_i >= 0`` summing to 1.
        volumes: ``(K,)`` particle volumes ``v_i > 0``, d^3.
        n_particles: N >= 1.

    Returns:
        ``(K,)`` int64 counts summing to N; 0 where ``f_i = 0``; >= 1 elsewhere if N allows.
    """
    shares = np.asarray(shares, dtype=np.float64)
    volumes = np.asarray(volumes, dtype=np.float64)
    n = int(n_particles)
    counts = np.zeros(len(shares), dtype=np.int64)
    active = np.flatnonzero(shares > 0)
    if len(active) == 1:
        counts[active[0]] = n
        return counts
    f, v = shares[active], volumes[active]
    minimum = 1 if n >= len(active) else 0
    ideal = n * (f / v) / np.sum(f / v)
    start = _rounded(ideal, n, minimum)
    worst, total = _errors(start[None, :], f, v)
    # windows: n_i = N a_i / (a_i + sum_{j != i} a_j) with a = s / v, s within E of f
    hi_share, lo_share = np.minimum(f + worst[0], 1.0) / v, np.maximum(f - worst[0], 0.0) / v
    rest_lo, rest_hi = lo_share.sum() - lo_share, hi_share.sum() - hi_share
    with np.errstate(divide="ignore", invalid="ignore"):
        upper = np.where(hi_share + rest_lo > 0, n * hi_share / (hi_share + rest_lo), n)
        lower = np.where(lo_share + rest_hi > 0, n * lo_share / (lo_share + rest_hi), 0)
    upper = np.minimum(np.ceil(upper).astype(np.int64) + 1, n)
    lower = np.maximum(np.floor(lower).astype(np.int64) - 1, minimum)
    best, best_key = start, (worst[0], total[0])
    outer = [range(lo, hi + 1) for lo, hi in zip(lower[:-2], upper[:-2])]
    inner = np.arange(lower[-2], upper[-2] + 1)
    for head in itertools.product(*outer):
        rows = np.empty((len(inner), len(active)), dtype=np.int64)
        rows[:, :-2] = head
        rows[:, -2] = inner
        rows[:, -1] = n - rows[:, :-1].sum(axis=1)
        rows = rows[(rows[:, -1] >= lower[-1]) & (rows[:, -1] <= upper[-1])]
        if not len(rows):
            continue
        largest, total = _errors(rows, f, v)
        k = np.lexsort((total, largest))[0]
        if (largest[k], total[k]) < best_key:
            best, best_key = rows[k], (largest[k], total[k])
    counts[active] = best
    return counts


#: the random stream that orders each graded population's sizes among its grains (apart from the
#: run's stream, which draws the population order, the deposit and the orientations)
_GRADING_STREAM = 0x67726164
#: the random stream that orders the shapes of a population of several shapes among its grains
_SHAPE_STREAM = 0x73686170


def shape_counts(weights, n: int) -> np.ndarray:
    """Grains of each shape among ``n``: the largest-remainder rounding of ``n w_s`` (``weights``
    summing to 1), so equal weights give numbers that differ by at most one."""
    ideal = n * np.asarray(weights, dtype=np.float64)
    return _rounded(ideal, n, 0)


@dataclass(frozen=True)
class Mixture:
    """The populations of a run with their shapes, particle counts and, for a graded population,
    the size of each of its grains.

    A graded population's grains have sizes :meth:`granpack.grading.Grading.sizes` of its count,
    in an order drawn from the seed: grain ``m`` of population ``k`` (in particle order) has the
    size ``sizes[k][m]`` and its own kind in the shape table (:meth:`particle_kinds`). A population
    of several shapes (mesh files) gives each shape :func:`shape_counts` of its grains, in an order
    drawn from the seed: grain ``m`` has the shape ``population_shapes[k][choices[k][m]]``.

    Attributes:
        populations: the ``K`` population configs.
        shapes: ``K`` shapes at their sizes (body frame, d); shape k is population k's (its first
            one when it has several; a graded population's at size 1).
        counts: ``(K,)`` int64 particles per population, summing to N.
        sizes: per population, the ``(counts[k],)`` sizes of its grains (d), None for one size.
        population_shapes: per population, all its shapes (one, or one per mesh file).
        choices: per population, the ``(counts[k],)`` int64 shape index of each of its grains,
            None for a population of one shape.
    """

    populations: tuple[PopulationConfig, ...]
    shapes: tuple[Shape, ...]
    counts: np.ndarray
    sizes: tuple[np.ndarray | None, ...]
    population_shapes: tuple[tuple[Shape, ...], ...] = ()
    choices: tuple[np.ndarray | None, ...] = ()

    @classmethod
    def from_config(cls, config: RunConfig) -> "Mixture":
        """Shapes, counts and graded sizes of ``config.populations`` for ``config.n_particles`` grains."""
        population_shapes = tuple(p.make_shapes() for p in config.populations)
        shapes = tuple(s[0] for s in population_shapes)
        mean_volumes = [_mean_volume(s, p.shape_weights) * (p.grading_curve.mean_cube() if p.grading is not None else 1.0)
                        for p, s in zip(config.populations, population_shapes)]
        counts = volume_share_counts([p.volume_fraction for p in config.populations], mean_volumes, config.n_particles)
        counts.setflags(write=False)
        sizes = []
        for k, (p, n) in enumerate(zip(config.populations, counts)):
            if p.grading is None:
                sizes.append(None)
                continue
            order = np.random.default_rng([config.seed, k, _GRADING_STREAM]).permutation(int(n))
            graded = p.grading_curve.sizes(int(n))[order]
            graded.setflags(write=False)
            sizes.append(graded)
        choices = []
        for k, (p, n) in enumerate(zip(config.populations, counts)):
            if len(population_shapes[k]) == 1:
                choices.append(None)
                continue
            per_shape = shape_counts(p.shape_weights, int(n))
            order = np.random.default_rng([config.seed, k, _SHAPE_STREAM]).permutation(int(n))
            chosen = np.repeat(np.arange(len(per_shape), dtype=np.int64), per_shape)[order]
            chosen.setflags(write=False)
            choices.append(chosen)
        return cls(populations=tuple(config.populations), shapes=shapes, counts=counts, sizes=tuple(sizes),
                   population_shapes=population_shapes, choices=tuple(choices))

    @property
    def n_particles(self) -> int:
        """N, the total number of grains."""
        return int(self.counts.sum())

    @property
    def names(self) -> list[str]:
        """Population names, in population order."""
        return [p.name for p in self.populations]

    @property
    def is_graded(self) -> bool:
        """Whether some population has a distribution of sizes."""
        return any(s is not None for s in self.sizes)

    @property
    def particle_volumes(self) -> np.ndarray:
        """``(K,)`` mean volume of a grain of each population, d^3."""
        return self.solid_volumes / np.maximum(self.counts, 1)

    @property
    def solid_volumes(self) -> np.ndarray:
        """``(K,)`` solid volume of each population's grains, d^3."""
        out = []
        for k, (s, n, d) in enumerate(zip(self.shapes, self.counts, self.sizes)):
            choice = self.choices[k] if self.choices else None
            if choice is None:
                out.append(s.volume * (n if d is None else float(np.sum(d ** 3))))
                continue
            volumes = np.array([shape.volume for shape in self.population_shapes[k]])[choice]
            out.append(float(np.sum(volumes * (1.0 if d is None else d ** 3))))
        return np.array(out)

    @property
    def requested_shares(self) -> np.ndarray:
        """``(K,)`` volume shares asked for in the config."""
        return np.array([p.volume_fraction for p in self.populations])

    @property
    def achieved_shares(self) -> np.ndarray:
        """``(K,)`` volume shares of the grains, :math:`V_i / \\sum_j V_j`."""
        solid = self.solid_volumes
        return solid / solid.sum()

    def pile_height(self, floor_area: float, solid_fraction: float | None = None) -> float:
        """Expected height of the settled pile, d: the grains' volume over the floor's area
        (``RunConfig.floor_area``, d^2) at ``solid_fraction``; by default :data:`PHI_ONE_SIZE` for
        grains of one size and :data:`PHI_MIXED_SIZES` for a mix of sizes, whose small grains fill
        the large ones' voids."""
        if solid_fraction is None:
            solid_fraction = PHI_MIXED_SIZES if self.has_mixed_sizes else PHI_ONE_SIZE
        return float(self.solid_volumes.sum()) / (solid_fraction * floor_area)

    @property
    def has_mixed_sizes(self) -> bool:
        """Whether the grains have more than one size."""
        return self.is_graded or len({p.size for p in self.populations}) > 1

    def sieve_curve(self, k: int, points: int = 9) -> list[dict]:
        """The requested and achieved sieve curve of graded population ``k``: ``{"size" (d),
        "requested", "achieved"}`` (shares passing by volume) at the sieves of its table, or at
        ``points`` sizes spaced evenly in log D from its smallest to its largest size."""
        from granpack.grading import achieved_passing

        grading = self.populations[k].grading_curve
        at = (np.array(grading.sieves) if grading.kind == "sieves"
              else np.geomspace(grading.d_min, grading.d_max, points))
        d = self.sizes[k]
        achieved = achieved_passing(d, d ** 3, at)
        return [{"size": float(a), "requested": float(r), "achieved": float(x)}
                for a, r, x in zip(at, grading.passing_at(at), achieved)]

    def largest_deviation(self, k: int) -> float:
        """The largest gap between the requested and achieved sieve curves of graded population ``k``."""
        from granpack.grading import largest_deviation

        d = self.sizes[k]
        return largest_deviation(self.populations[k].grading_curve, d, d ** 3)

    def table(self) -> list[dict]:
        """One row per population: ``population``, ``shape``, ``size`` (d; for a graded population its
        ``curve`` and ``d_min``, ``d_max`` instead, and the ``largest_deviation`` of its sieve curve),
        ``aspect`` (pinacoids, else None), ``count``, ``requested_share``, ``achieved_share``,
        ``particle_volume`` (d^3, the mean), ``size_definition``, ``shapes`` (how many)."""
        achieved, volumes = self.achieved_shares, self.particle_volumes
        rows = []
        for k, p in enumerate(self.populations):
            row = {
                "population": p.name,
                "shape": p.shape,
                "size": p.size,
                "aspect": list(p.aspect) if p.aspect is not None else None,
                "count": int(self.counts[k]),
                "requested_share": p.volume_fraction,
                "achieved_share": float(achieved[k]),
                "particle_volume": float(volumes[k]),
                "size_definition": p.size_definition,
                "shapes": len(self.population_shapes[k]) if self.population_shapes else 1,
            }
            if p.grading is not None:
                row.update(curve=p.grading.curve, d_min=p.smallest_size, d_max=p.largest_size,
                           largest_deviation=self.largest_deviation(k) if self.counts[k] else None)
            rows.append(row)
        return rows

    def shape_rows(self) -> list[dict]:
        """One row per shape of each population, at the population's size (a graded one's at size 1):
        ``population``, ``shape`` (its name: a mesh file's stem), ``file`` (mesh only, else None),
        ``count`` (grains of this shape), ``vertices``, ``volume`` (d^3), ``aspect`` ``[L/G, G/E]``
        (:func:`granpack.shapes.sizes.aspect_ratios`), ``sizes`` (d, in every size definition),
        and for a mesh shape ``convexity``, ``hull_vertices`` and ``deviations`` of its reduction
        (``{"volume", "moments", "aspect"}``, relative, None when the hull needed none)."""
        from granpack.shapes.sizes import SIZE_DEFINITIONS, aspect_ratios, size_of

        rows = []
        for k, p in enumerate(self.populations):
            group = self.population_shapes[k] if self.population_shapes else (self.shapes[k],)
            choice = self.choices[k] if self.choices else None
            grains = p.mesh_grains() if p.shape == "mesh" else (None,) * len(group)
            for s, (shape, grain) in enumerate(zip(group, grains)):
                count = int(self.counts[k]) if choice is None else int(np.sum(choice == s))
                scale = 1.0 if grain is None else shape.size / grain.shape.size
                row = {
                    "population": p.name,
                    "shape": getattr(shape, "name", "sphere"),
                    "file": None if grain is None else str(grain.source),
                    "count": count,
                    "vertices": len(getattr(shape, "vertices", ())),
                    "volume": float(shape.volume),
                    "aspect": list(aspect_ratios(shape)),
                    "sizes": {d: (float(grain.sizes[d] * scale) if grain is not None else float(size_of(shape, d)))
                              for d in SIZE_DEFINITIONS},
                }
                if grain is not None:
                    dev = grain.deviations
                    row.update(convexity=float(grain.convexity), hull_vertices=int(grain.hull_vertex_count),
                               deviations=None if dev is None else {"volume": dev.volume, "moments": list(dev.moments),
                                                                    "aspect": list(dev.aspect)})
                rows.append(row)
        return rows

    def particle_populations(self, rng: np.random.Generator) -> np.ndarray:
        """``(N,)`` int64 population index of each particle, in a random order.

        Args:
            rng: the random generator that shuffles the list.
        """
        return rng.permutation(np.repeat(np.arange(len(self.counts), dtype=np.int64), self.counts))

    def particle_kinds(self, population: np.ndarray) -> np.ndarray:
        """``(N,)`` int64 kind of each particle in :meth:`particle_shape_table`: its population's, or
        for the ``m``-th grain of a graded population (in particle order) its own."""
        kind = np.array(population, dtype=np.int64)
        first = self._first_kinds()
        for k, choice in enumerate(self.choices):
            if choice is not None and self.sizes[k] is None:
                kind[population == k] = first[k] + choice
            elif self.sizes[k] is None:
                kind[population == k] = first[k]
        offset = int(first[-1])
        for k, d in enumerate(self.sizes):
            if d is None:
                continue
            members = np.flatnonzero(population == k)
            kind[members] = offset + np.arange(len(members))
            offset += len(d)
        return kind

    def _first_kinds(self) -> np.ndarray:
        """``(K + 1,)`` the first kind of each population's shapes in :meth:`particle_shape_table`
        (then the first graded grain's kind)."""
        per = [len(s) for s in self.population_shapes] if self.population_shapes else [1] * len(self.populations)
        return np.concatenate([[0], np.cumsum(per)]).astype(np.int64)

    def _grain_shape(self, k: int, m: int) -> Shape:
        """The shape of grain ``m`` of population ``k`` (in particle order), at the population's size."""
        choice = self.choices[k] if self.choices else None
        return self.shapes[k] if choice is None else self.population_shapes[k][int(choice[m])]

    def particle_shape_table(self) -> ShapeTable:
        """Kernel geometry: the shapes of population 0 (one kind each, a population of one shape one
        kind), then those of population 1, ..., then one kind per graded grain (in the order of
        :attr:`sizes`), its shape scaled to its size."""
        graded = [self._grain_shape(k, m).scaled(float(size)) for k, d in enumerate(self.sizes) if d is not None
                  for m, size in enumerate(d)]
        shapes = (tuple(s for group in self.population_shapes for s in group) if self.population_shapes
                  else self.shapes)
        return ShapeTable.from_shapes(shapes + tuple(graded))
