"""Shape descriptors of every grain, and the shape classes of each population.

Per grain, from its shape (scale-free, so a graded grain has its population shape's figures;
method: docs/method/analysis.md#grain-shapes):

- **elongation** L/G and **flatness** G/E, from the extents along the principal axes of inertia
  (:func:`granpack.shapes.sizes.aspect_ratios`);
- **sphericity** (Wadell) :math:`\\psi = \\pi^{1/3}(6V)^{2/3}/A` (:func:`granpack.shapes.sizes.sphericity`);
- **convexity** of the surface a grain from a file is the hull of (volume it encloses / hull
  volume; ``nan`` for a grain given as a convex body: a sphere, pinacoid, polyhedron or rock).

A **shape class** is one shape of a population (one per mesh file, generated rock, or aspect
class; one for a population of one shape); a graded grain belongs to the class of the shape it is
scaled from. :attr:`GrainShapes.classes` lists each population's classes with their grains.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, NotComputedError, result
from granpack.packing import Packing
from granpack.shapes.sizes import aspect_ratios, sphericity

__all__ = ["GrainShapes", "DESCRIPTORS"]

#: the per-grain descriptors, in the order of :attr:`GrainShapes.per_grain`
DESCRIPTORS = ("elongation", "flatness", "sphericity", "convexity")


def _descriptors(shape) -> tuple[float, float, float, float]:
    """``(L/G, G/E, sphericity, source convexity or nan)`` of one shape."""
    elongation, flatness = aspect_ratios(shape)
    convexity = getattr(shape, "source_convexity", None)
    return elongation, flatness, sphericity(shape), math.nan if convexity is None else float(convexity)


class GrainShapes(Compute):
    """Elongation, flatness, sphericity and source convexity of every grain, and its shape class."""

    def compute(self, packing: Packing) -> "GrainShapes":
        """Describe the grains of ``packing`` (one evaluation per shape class, then per grain by lookup)."""
        self._start()
        state = packing.state
        shapes = state.shapes.shapes
        base_of_kind = [s.scale_of[0] if getattr(s, "scale_of", None) is not None else s for s in shapes]
        bases: dict[int, int] = {}
        for base in base_of_kind:
            bases.setdefault(id(base), len(bases))
        class_of_kind = np.array([bases[id(b)] for b in base_of_kind], dtype=np.int64)
        unique = {bases[id(b)]: b for b in base_of_kind}
        table = np.array([_descriptors(unique[c]) for c in range(len(unique))]).reshape(-1, len(DESCRIPTORS))
        self._shape_class = class_of_kind[state.kind]
        self._per_grain = table[self._shape_class]
        self._classes = []
        for a, name in enumerate(packing.population_names):
            members = state.population == a
            rows = []
            for c in np.unique(self._shape_class[members]):
                grains = members & (self._shape_class == c)
                rows.append({"shape": getattr(unique[int(c)], "name", "sphere"), "grains": grains,
                             **dict(zip(DESCRIPTORS, (float(v) for v in table[c])))})
            self._classes.append({"population": name, "classes": rows})
        return self._done()

    @result
    def per_grain(self) -> dict[str, np.ndarray]:
        """``{descriptor: (N,) values}`` for each of :data:`DESCRIPTORS`."""
        return {k: self._per_grain[:, i].copy() for i, k in enumerate(DESCRIPTORS)}

    @result
    def shape_class(self) -> np.ndarray:
        """``(N,)`` int64 index of each grain's shape (its base shape for a graded grain), over the packing."""
        return self._shape_class.copy()

    @result
    def classes(self) -> list[dict]:
        """Per population ``{"population", "classes"}``, each class ``{"shape" (its name), "grains"
        ((N,) bool), elongation, flatness, sphericity, convexity}``."""
        return [{"population": p["population"], "classes": [dict(c) for c in p["classes"]]} for p in self._classes]

    def summary(self, grains: np.ndarray) -> dict[str, dict[str, float]]:
        """``{descriptor: {"mean", "std", "min", "max"}}`` over the grains flagged in ``grains`` (nan when none)."""
        if not self._computed:
            raise NotComputedError("GrainShapes.summary is available after compute()")
        values = self._per_grain[grains]
        out = {}
        for i, k in enumerate(DESCRIPTORS):
            v = values[:, i]
            out[k] = ({"mean": float(v.mean()), "std": float(v.std()), "min": float(v.min()), "max": float(v.max())}
                      if len(v) else dict.fromkeys(("mean", "std", "min", "max"), math.nan))
        return out

    def to_dict(self) -> dict:
        """The ``grain_shapes`` part of ``analysis.json``: :attr:`per_grain`."""
        return self.per_grain
