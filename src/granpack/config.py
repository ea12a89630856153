"""Run configuration: the TOML schema of a run as validated pydantic models.

Units: lengths in d (the largest grain's circumscribed diameter), times in sqrt(d/g). The docs'
Reference > Run config page is generated from these models (docs/hooks/reference.py).

Every model forbids unknown keys and is strict about types (``n_particles = 3.0`` or
``size = "1"`` are errors; an integer is accepted where a number is expected). Every error is
reported by :func:`load_config` / :func:`load_config_dict` as one
:class:`~granpack.errors.InputError` line naming the source and the field path, e.g.::

    config.toml: populations[1].size: must be > 0 (got -1)

The settings are grouped by what they control, one table each (:data:`SETTING_TABLES`):
``[container]`` (the cell's sides: periodic, a box or a cylinder), ``[time_stepping]``, ``[solver]`` (contact law and NLGS), ``[overlap]``, ``[end_game]``,
``[threads]``, ``[equilibrium]``, ``[deposit]``, ``[output]``; each field is declared once here, with
its default, bounds, unit and meaning, and the nscd defaults, the reference page and ``granpack
check`` read them from here. A file in the flat ``[solver]`` layout of granpack 0.1.0 is read as
the grouped one (:data:`MOVED_SOLVER_KEYS`; ``granpack check`` names the new keys).

A :class:`RunConfig` is fully resolved once validated (population names derived, pinacoid aspect
filled in); :meth:`RunConfig.to_toml` writes it back as TOML that :func:`load_config` reads into an
equal object.
"""

from __future__ import annotations

import json
import math
from functools import lru_cache
import re
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal, Optional

from pydantic import (BaseModel, ConfigDict, Field, PrivateAttr, Strict, ValidationError, ValidationInfo, field_validator,
                      model_validator)

from granpack.errors import InputError
from granpack.grading import Grading
from granpack.shapes import ConvexPolyhedron, Pinacoid, Shape, ShapeError, Sphere, polyhedron_of_size
from granpack.shapes.aspect_classes import DEFAULT_CLASSES_PER_RATIO, MAX_CLASSES, MAX_CLASSES_PER_RATIO
from granpack.shapes.rock import DEFAULT_FACES, DEFAULT_ROUGHNESS, DEFAULT_SHAPES, MAX_FACES, MIN_FACES
from granpack.shapes.sizes import SIZE_DEFINITIONS

__all__ = [
    "AUTO_ALERT_FRACTION",
    "SHARE_TOLERANCE",
    "SETTING_TABLES",
    "CONTINUABLE_SETTINGS",
    "MOVED_SOLVER_KEYS",
    "PopulationConfig",
    "GradingConfig",
    "TimeSteppingConfig",
    "SolverConfig",
    "OverlapConfig",
    "EndGameConfig",
    "ThreadsConfig",
    "EquilibriumConfig",
    "DepositConfig",
    "OutputConfig",
    "ContainerConfig",
    "RunConfig",
    "load_config",
    "load_config_dict",
    "moved_keys",
    "unit_of",
]

#: automatic alert distance, as a fraction of the largest grain size (docs/method/nscd.md#alert-distance-and-substeps)
AUTO_ALERT_FRACTION = 0.02
#: the volume shares of the populations must sum to 1 within this tolerance
SHARE_TOLERANCE = 1e-6
#: most grains in a run: some 10 GB of memory for a settled pile of pinacoids
MAX_PARTICLES = 2_000_000
#: most cells of the contact grid over the cell's area (cells of the smallest grain's size):
#: some GB of grid for a pile a few grains tall
MAX_GRID_CELLS = 50_000_000

_NAME_PATTERN = re.compile(r"^[\w.+-][\w .+-]{0,63}$")

_Number = Annotated[float, Strict()]
# TOML arrays arrive as lists: accept them for tuple fields, keep the items strict.
_Pair = Annotated[tuple[_Number, _Number], Strict(False)]
_Point = Annotated[tuple[_Number, _Number, _Number], Strict(False)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


def _setting(default: Any, unit: str = "", **field: Any) -> Any:
    """A config field with its unit (``""``: a pure number or a word), which the reference page and
    ``granpack check`` print beside the value."""
    return Field(default=default, json_schema_extra={"unit": unit}, **field)


def unit_of(model: type[BaseModel], key: str) -> str:
    """The unit declared for ``model.key`` (``""`` if none)."""
    extra = model.model_fields[key].json_schema_extra
    return extra.get("unit", "") if isinstance(extra, dict) else ""


class GradingConfig(_Model):
    """A continuous size distribution by volume, given instead of one `size`.

    Method: docs/method/grains.md#gradings.
    """

    curve: Literal["fuller", "sieves", "lognormal"] = _setting(
        ..., description='"fuller": P(D) = (D^n - d_min^n) / (d_max^n - d_min^n), the Fuller / Talbot curve '
        '(D / d_max)^n without the fines below d_min; "sieves": a sieve table, interpolated linearly in log D; '
        '"lognormal": ln D normal by number.')
    d_min: Optional[_Number] = _setting(None, "d", gt=0, description="Fuller: the smallest grain size.")
    d_max: Optional[_Number] = _setting(None, "d", gt=0, description="Fuller: the largest grain size.")
    exponent: Optional[_Number] = _setting(None, gt=0, description="Fuller: the exponent n (0.5: Fuller's "
                                           "curve of densest packing; 0.3 to 0.7 in mix design).")
    sieves: Annotated[Optional[tuple[_Number, ...]], Strict(False)] = _setting(
        None, description="Sieve table: the sieve sizes, increasing, in any one unit (mm, say).")
    percent_passing: Annotated[Optional[tuple[_Number, ...]], Strict(False)] = _setting(
        None, "%", description="Sieve table: the cumulative share passing each sieve, % by volume (by mass at "
        "one density), non-decreasing from 0 to 100.")
    sieve_unit: Optional[_Number] = _setting(
        None, gt=0, description="Sieve table: the size, in the unit of `sieves`, of a grain of 1 d; unset: the "
        "first sieve that 100 % passes (the largest grains are 1 d).")
    mean: Optional[_Number] = _setting(None, "d", gt=0, description="Lognormal: the mean size by number.")
    polydispersity: Optional[_Number] = _setting(
        None, gt=0, description="Lognormal: std / mean of the size by number (before the truncation).")
    cut: Optional[_Number] = _setting(None, gt=0, description="Lognormal: the truncation, in standard deviations "
                                      "of ln D each side of its mean; unset: 3.")

    @model_validator(mode="after")
    def _check_curve(self) -> "GradingConfig":
        given = {k for k in ("d_min", "d_max", "exponent", "sieves", "percent_passing", "sieve_unit", "mean",
                             "polydispersity", "cut") if getattr(self, k) is not None}
        needed = {"fuller": {"d_min", "d_max", "exponent"}, "sieves": {"sieves", "percent_passing"},
                  "lognormal": {"mean", "polydispersity"}}[self.curve]
        allowed = needed | {"sieves": {"sieve_unit"}, "lognormal": {"cut"}}.get(self.curve, set())
        if needed - given:
            raise ValueError(f"curve '{self.curve}' needs {', '.join(sorted(needed - given))}")
        if given - allowed:
            raise ValueError(f"{', '.join(sorted(given - allowed))}: not a key of curve '{self.curve}' "
                             f"(it takes {', '.join(sorted(allowed))})")
        if self.curve == "fuller" and not self.d_min < self.d_max:
            raise ValueError(f"d_min must be below d_max (got {self.d_min:g} and {self.d_max:g})")
        if self.curve == "sieves":
            sizes, shares = self.sieves, self.percent_passing
            if len(sizes) != len(shares) or len(sizes) < 2:
                raise ValueError(f"sieves and percent_passing must be two lists of the same length, at least 2 "
                                 f"(got {len(sizes)} and {len(shares)})")
            if not all(a > 0 for a in sizes) or not all(a < b for a, b in zip(sizes, sizes[1:])):
                raise ValueError("sieves must be sizes > 0 in increasing order")
            if not all(a <= b for a, b in zip(shares, shares[1:])):
                raise ValueError("percent_passing must not decrease from one sieve to the next")
            if shares[0] != 0 or shares[-1] != 100:
                raise ValueError(f"percent_passing must go from 0 at the first sieve to 100 at the last (got "
                                 f"{shares[0]:g} ... {shares[-1]:g})")
        return self

    def make_grading(self) -> Grading:
        """The distribution, sizes in d."""
        if self.curve == "fuller":
            return Grading.fuller(self.d_min, self.d_max, self.exponent)
        if self.curve == "lognormal":
            return Grading.lognormal(self.mean, self.polydispersity, 3.0 if self.cut is None else self.cut)
        full = next(size for size, share in zip(self.sieves, self.percent_passing) if share >= 100)
        unit = self.sieve_unit if self.sieve_unit is not None else full
        return Grading.sieve_table([size / unit for size in self.sieves], [share / 100 for share in self.percent_passing])

    def label(self) -> str:
        """A short name of the curve, for derived population names."""
        g = self.make_grading()
        if self.curve == "fuller":
            return f"fuller{self.exponent:g}-{g.d_min:g}-{g.d_max:g}"
        if self.curve == "lognormal":
            return f"lognormal{self.polydispersity:g}-{self.mean:g}"
        return f"sieves-{g.d_min:.3g}-{g.d_max:.3g}"


class PopulationConfig(_Model):
    """One grain population: a shape at one size and its share of the solid volume."""

    #: the seed of the run the population belongs to (set by :class:`RunConfig`; a rock population's
    #: default :attr:`library_seed`); 1, the run's default, for a population on its own
    _run_seed: int = PrivateAttr(default=1)

    shape: Literal["sphere", "pinacoid", "polyhedron", "mesh", "rock"] = Field(
        description='Grain shape: "sphere", "pinacoid", "polyhedron" (then give vertices), "mesh" (then give '
        'files: each grain is the convex hull of a surface read from a file) or "rock" (convex rocks generated from '
        "the seed: `aspect`, `faces`, `shapes`, `roughness`)."
    )
    size: Annotated[Optional[_Number], Field(validate_default=True)] = Field(
        default=None,
        gt=0,
        description="Circumscribed diameter, d: the sphere diameter, sqrt(L^2 + G^2) for a pinacoid; required "
        "unless `grading` gives a distribution of sizes.",
    )
    size_definition: Literal["circumscribed", "sieve", "equivalent_volume"] = Field(
        default="circumscribed",
        description='What `size` and the grading\'s sizes measure: "circumscribed", the diameter of the smallest '
        'centred ball holding the grain (granpack\'s d); "sieve", the side of the smallest square aperture the grain '
        'passes through; "equivalent_volume", the diameter of the ball of the same volume.',
    )
    grading: Annotated[Optional[GradingConfig], Field(validate_default=True)] = Field(
        default=None, description="A distribution of sizes instead of `size` ([populations.grading] table)."
    )
    volume_fraction: _Number = Field(
        ge=0, le=1, description="Share of the total solid volume; the shares of all populations sum to 1."
    )
    aspect_distribution: Annotated[Optional[tuple[_Point, ...]], Strict(False), Field(validate_default=True)] = Field(
        default=None, min_length=1, max_length=MAX_CLASSES,
        description="Pinacoid only, instead of `aspect`: aspect ratios varying grain by grain, as a table of classes "
        "[[L/G, G/E, weight], ...] (weights: relative numbers of grains); one shape per row, each grain's row drawn "
        "from the seed.",
    )
    aspect_lognormal: Annotated[Optional[tuple[_Pair, ...]], Strict(False), Field(validate_default=True)] = Field(
        default=None, min_length=2, max_length=2,
        description="Pinacoid only, instead of `aspect`: aspect ratios varying grain by grain, ln(L/G) and ln(G/E) "
        "independent normals given as [[median L/G, standard deviation of ln(L/G)], [median G/E, standard deviation "
        "of ln(G/E)]], each truncated to ratios >= 1 and cut into `aspect_classes` classes of equal probability.",
    )
    aspect_classes: Annotated[Optional[int], Field(validate_default=True)] = Field(
        default=None, ge=1, le=MAX_CLASSES_PER_RATIO,
        description="With `aspect_lognormal`: classes per ratio (a ratio of spread 0 has one), so up to "
        "aspect_classes^2 shapes; default 4.",
    )
    aspect: Annotated[Optional[_Pair], Field(validate_default=True)] = Field(
        default=None,
        description="Pinacoid and rock: [L/G, G/E] (elongation, flatness), each >= 1; default [1, 1] (isometric) "
        "unless `aspect_distribution` or `aspect_lognormal` is given.",
    )
    vertices: Annotated[Optional[tuple[_Point, ...]], Strict(False), Field(validate_default=True)] = Field(
        default=None,
        description="Polyhedron only (required there): [[x, y, z], ...] of a convex body, any scale "
        "(it is scaled to `size`).",
    )
    max_vertices: Annotated[Optional[int], Field(validate_default=True)] = Field(
        default=None, ge=4, le=1000,
        description="Mesh only: the most vertices a grain keeps; a hull with more is reduced to this many, its "
        "volume kept exactly, its principal moments and aspect ratios within 5 %; default 24.",
    )
    min_convexity: Annotated[Optional[_Number], Field(validate_default=True)] = Field(
        default=None, gt=0, le=1,
        description="Mesh only: the least convexity (volume the file's surface encloses / volume of its convex "
        "hull, which the grain is) accepted; default 0.85.",
    )
    files: Annotated[Optional[tuple[str, ...]], Strict(False), Field(validate_default=True)] = Field(
        default=None, min_length=1,
        description="Mesh only (required there): mesh files (STL, OBJ, PLY or OFF), one grain shape each, as paths "
        "or glob patterns relative to the config file; the resolved config lists the files found.",
    )
    weights: Annotated[Optional[tuple[_Number, ...]], Strict(False), Field(validate_default=True)] = Field(
        default=None,
        description="Mesh only: the relative number of grains of each file's shape, one weight per file in the "
        "order of `files` (each pattern's matches by name); default: equal numbers.",
    )
    faces: Annotated[Optional[int], Field(validate_default=True)] = Field(
        default=None, ge=MIN_FACES, le=MAX_FACES,
        description="Rock only: the faces of each rock (it has 2 faces - 4 vertices); default 14 (24 vertices).",
    )
    shapes: Annotated[Optional[int], Field(validate_default=True)] = Field(
        default=None, ge=1, le=100,
        description="Rock only: how many distinct rocks the population's grains are drawn from, in equal numbers; "
        "default 10.",
    )
    roughness: Annotated[Optional[_Number], Field(validate_default=True)] = Field(
        default=None, ge=0, le=2,
        description="Rock only: the random step of the faces' normals from an even spread, in mean spacings "
        "between normals (0: near-regular rocks; 1: faces of very unequal sizes); default 0.5.",
    )
    seed: Optional[int] = Field(
        default=None, ge=0,
        description="Rock only: the seed the rocks are generated from; unset: the run's seed (so another run seed "
        "packs other rocks).",
    )
    name: Annotated[Optional[str], Field(validate_default=True)] = Field(
        default=None,
        description='Label in tables and outputs; default derived from shape, size and aspect, e.g. "pinacoid-1-1x1".',
    )

    @field_validator("aspect")
    @classmethod
    def _check_aspect(cls, aspect: tuple[float, float] | None, info: ValidationInfo) -> tuple[float, float] | None:
        shape = info.data.get("shape")
        if shape not in ("pinacoid", "rock"):
            if aspect is not None and shape is not None:
                raise ValueError(f"only allowed for shapes 'pinacoid' and 'rock' (this population is a {shape})")
            return aspect
        varying = [k for k in ("aspect_distribution", "aspect_lognormal") if info.data.get(k) is not None]
        if varying:
            if aspect is not None:
                raise ValueError(f"give either aspect (one shape) or {varying[0]} (ratios varying grain by grain), not both")
            return None
        if aspect is None:
            return (1.0, 1.0)
        if not (aspect[0] >= 1.0 and aspect[1] >= 1.0):
            raise ValueError(f"[L/G, G/E] must both be >= 1 (got [{aspect[0]:g}, {aspect[1]:g}])")
        try:
            Pinacoid.from_size(1.0, *aspect)
        except ShapeError as exc:
            raise ValueError(str(exc)) from None
        return aspect

    @field_validator("aspect_distribution", "aspect_lognormal", "aspect_classes")
    @classmethod
    def _check_aspect_classes(cls, value, info: ValidationInfo):
        shape = info.data.get("shape")
        if shape != "pinacoid":
            if value is not None and shape is not None:
                raise ValueError(f"only allowed for shape 'pinacoid' (this population is a {shape})")
            return value
        if info.field_name == "aspect_distribution" and value is not None:
            for row in value:
                if not (row[0] >= 1.0 and row[1] >= 1.0 and row[2] >= 0):
                    raise ValueError(f"each row is [L/G, G/E, weight] with L/G >= 1, G/E >= 1 and weight >= 0 (got "
                                     f"[{row[0]:g}, {row[1]:g}, {row[2]:g}])")
            if not sum(row[2] for row in value) > 0:
                raise ValueError("the weights (third column) must have a positive sum")
        if info.field_name == "aspect_lognormal" and value is not None:
            if info.data.get("aspect_distribution") is not None:
                raise ValueError("give either aspect_distribution (a table) or aspect_lognormal, not both")
            if not all(m >= 1.0 and s >= 0 for m, s in value):
                raise ValueError(f"[[median L/G, sd of ln(L/G)], [median G/E, sd of ln(G/E)]] need medians >= 1 and "
                                 f"sds >= 0 (got {[list(v) for v in value]})")
        if info.field_name == "aspect_classes":
            if info.data.get("aspect_lognormal") is None:
                if value is not None:
                    raise ValueError("only allowed with aspect_lognormal")
                return value
            return DEFAULT_CLASSES_PER_RATIO if value is None else value
        return value

    @field_validator("vertices")
    @classmethod
    def _check_vertices(cls, vertices: tuple | None, info: ValidationInfo) -> tuple | None:
        shape = info.data.get("shape")
        if shape != "polyhedron":
            if vertices is not None and shape is not None:
                raise ValueError(f"only allowed for shape 'polyhedron' (this population is a {shape})")
            return vertices
        if vertices is None:
            raise ValueError("required for shape 'polyhedron': a list of [x, y, z] vertices of a convex body")
        try:
            ConvexPolyhedron(vertices)
        except ShapeError as exc:
            raise ValueError(str(exc)) from None
        return vertices

    @field_validator("max_vertices", "min_convexity")
    @classmethod
    def _check_mesh_setting(cls, value, info: ValidationInfo):
        shape = info.data.get("shape")
        if shape != "mesh":
            if value is not None and shape is not None:
                raise ValueError(f"only allowed for shape 'mesh' (this population is a {shape})")
            return value
        if value is not None:
            return value
        from granpack.shapes.from_mesh import MIN_CONVEXITY
        from granpack.shapes.reduction import DEFAULT_MAX_VERTICES

        return DEFAULT_MAX_VERTICES if info.field_name == "max_vertices" else MIN_CONVEXITY

    @field_validator("files")
    @classmethod
    def _check_files(cls, files: tuple[str, ...] | None, info: ValidationInfo) -> tuple[str, ...] | None:
        shape = info.data.get("shape")
        if shape != "mesh":
            if files is not None and shape is not None:
                raise ValueError(f"only allowed for shape 'mesh' (this population is a {shape})")
            return files
        if files is None:
            raise ValueError("required for shape 'mesh': a list of mesh files or glob patterns (STL, OBJ, PLY, OFF)")
        if info.data.get("max_vertices") is None or info.data.get("min_convexity") is None:
            return files  # another field is invalid and is reported instead
        from granpack.shapes.mesh_files import MeshFileError, expand_files
        from granpack.shapes.from_mesh import population_grains

        base = (info.context or {}).get("base_dir") or Path.cwd()
        try:
            paths = expand_files(files, Path(base))
            population_grains(paths, info.data["max_vertices"], info.data["min_convexity"])
        except MeshFileError as exc:
            raise ValueError(str(exc)) from None
        return tuple(str(p) for p in paths)

    @field_validator("weights")
    @classmethod
    def _check_weights(cls, weights: tuple[float, ...] | None, info: ValidationInfo) -> tuple[float, ...] | None:
        shape, files = info.data.get("shape"), info.data.get("files")
        if shape != "mesh":
            if weights is not None and shape is not None:
                raise ValueError(f"only allowed for shape 'mesh' (this population is a {shape})")
            return weights
        if weights is None or files is None:
            return weights
        if len(weights) != len(files):
            raise ValueError(f"one weight per file: {len(weights)} weights for the {len(files)} files "
                             f"{', '.join(Path(f).name for f in files[:4])}{', ...' if len(files) > 4 else ''}")
        if not all(w >= 0 for w in weights) or not sum(weights) > 0:
            raise ValueError("weights must be >= 0 with a positive sum")
        return weights

    @field_validator("faces", "shapes", "roughness", "seed")
    @classmethod
    def _check_rock_setting(cls, value, info: ValidationInfo):
        shape = info.data.get("shape")
        if shape != "rock":
            if value is not None and shape is not None:
                raise ValueError(f"only allowed for shape 'rock' (this population is a {shape})")
            return value
        if value is not None or info.field_name == "seed":
            return value
        return {"faces": DEFAULT_FACES, "shapes": DEFAULT_SHAPES, "roughness": DEFAULT_ROUGHNESS}[info.field_name]

    @field_validator("name")
    @classmethod
    def _derive_name(cls, name: str | None, info: ValidationInfo) -> str | None:
        if name is not None:
            if not _NAME_PATTERN.match(name):
                raise ValueError(
                    f"must be 1 to 64 letters, digits, spaces, '_', '.', '+' or '-', not starting with a space (got {name!r})"
                )
            return name
        shape, size, grading = info.data.get("shape"), info.data.get("size"), info.data.get("grading")
        if shape is None or (size is None and grading is None):
            return None  # another field is invalid and is reported instead
        derived = f"{shape}-{size:g}" if size is not None else f"{shape}-{grading.label()}"
        aspect = info.data.get("aspect")
        if shape in ("pinacoid", "rock") and aspect is not None:
            derived += f"-{aspect[0]:g}x{aspect[1]:g}"
        elif shape == "pinacoid":
            derived += "-aspects"
        return derived

    @model_validator(mode="after")
    def _check_size(self) -> "PopulationConfig":
        if self.size is None and self.grading is None:
            raise ValueError("size: required key is missing (or give a [populations.grading] table)")
        if self.size is not None and self.grading is not None:
            raise ValueError("give either size (one size) or a grading table (a distribution of sizes), not both")
        return self

    @property
    def grading_curve(self) -> Grading | None:
        """The distribution of sizes (d), None for a population of one size."""
        return self.grading.make_grading() if self.grading is not None else None

    @property
    def largest_size(self) -> float:
        """The largest circumscribed diameter of the population's grains, d (its `size` or largest
        graded size when `size_definition` is "circumscribed")."""
        largest = self.size if self.grading is None else self.grading_curve.d_max
        if self.size_definition == "circumscribed":
            return largest
        return largest * max(s.size for s in self.make_shapes()) / (1.0 if self.grading is not None else self.size)

    @property
    def smallest_size(self) -> float:
        """The smallest circumscribed diameter of the population's grains, d."""
        smallest = self.size if self.grading is None else self.grading_curve.d_min
        if self.size_definition == "circumscribed":
            return smallest
        return smallest * min(s.size for s in self.make_shapes()) / (1.0 if self.grading is not None else self.size)

    @property
    def shape_weights(self) -> tuple[float, ...]:
        """The number share of each of :meth:`make_shapes`' shapes among the population's grains (sum 1)."""
        if self.aspect_classes_of is not None:
            return tuple(w for _, w in self.aspect_classes_of)
        n = {"mesh": len(self.files or ()), "rock": self.shapes}.get(self.shape, 1)
        weights = self.weights if self.weights is not None else (1.0,) * n
        total = math.fsum(weights)
        return tuple(w / total for w in weights)

    @property
    def aspect_classes_of(self) -> list[tuple[tuple[float, float], float]] | None:
        """The classes ``((L/G, G/E), weight)`` of a pinacoid population whose aspect ratios vary
        (:mod:`granpack.shapes.aspect_classes`), None for one aspect."""
        from granpack.shapes.aspect_classes import lognormal_classes, table_classes

        if self.aspect_distribution is not None:
            return table_classes(self.aspect_distribution)
        if self.aspect_lognormal is not None:
            return lognormal_classes(*self.aspect_lognormal, self.aspect_classes)
        return None

    @property
    def library_seed(self) -> int:
        """The seed of a rock population's rocks: its `seed`, or the run's."""
        return self.seed if self.seed is not None else self._run_seed

    def with_run_seed(self, seed: int) -> "PopulationConfig":
        """This population in a run of seed ``seed`` (the seed its rocks default to)."""
        out = self.model_copy()
        out._run_seed = int(seed)
        return out

    def mesh_grains(self) -> tuple:
        """The :class:`~granpack.shapes.from_mesh.MeshGrain` of each file, in the file's unit (mesh only)."""
        from granpack.shapes.from_mesh import population_grains

        if self.shape != "mesh":
            raise ValueError(f"a {self.shape} population has no mesh files")
        return population_grains([Path(f) for f in self.files], self.max_vertices, self.min_convexity)

    def make_shapes(self) -> tuple[Shape, ...]:
        """The population's grain shapes (one, or one per file for a mesh population), each at this
        population's size in its `size_definition`, or at size 1 for a graded one (body frame, d)."""
        stamps = ()
        if self.shape == "mesh":
            stamps = tuple((st.st_size, st.st_mtime_ns) for st in (Path(f).stat() for f in self.files))
        return _population_shapes(self, stamps, self.library_seed)

    def make_shape(self) -> Shape:
        """The grain shape at this population's size, or at size 1 for a graded one (body frame,
        lengths in d; each graded grain is this shape scaled by its size).

        Returns:
            ``Sphere(size)``, ``Pinacoid.from_size(size, *aspect)`` or
            ``polyhedron_of_size(vertices, size)``; the first shape of a population of several.
        """
        if self.shape in ("mesh", "rock") or self.aspect_classes_of is not None or self.size_definition != "circumscribed":
            return self.make_shapes()[0]
        size = self.size if self.grading is None else 1.0
        if self.shape == "sphere":
            return Sphere(size)
        if self.shape == "pinacoid":
            return Pinacoid.from_size(size, *self.aspect, name=self.name)
        return polyhedron_of_size(self.vertices, size, name=self.name)


@lru_cache(maxsize=256)
def _population_shapes(population: PopulationConfig, stamps: tuple, seed: int) -> tuple[Shape, ...]:
    """:meth:`PopulationConfig.make_shapes` (cached: a sieve size takes a search; ``stamps``, the
    mesh files' sizes and modification times, make a changed file a new key; ``seed``, a rock
    population's :attr:`~PopulationConfig.library_seed`)."""
    from granpack.shapes.rock import rock_library
    from granpack.shapes.sizes import size_of

    size = population.size if population.grading is None else 1.0
    if population.shape == "mesh":
        bases = [(g.shape, g.sizes[population.size_definition]) for g in population.mesh_grains()]
    elif population.shape == "rock" or population.aspect_classes_of is not None:
        if population.shape == "rock":
            generated = rock_library(seed, population.shapes, population.aspect, population.faces,
                                     population.roughness, name=population.name)
        else:
            generated = [Pinacoid.from_size(1.0, *aspect, name=f"{population.name}-{aspect[0]:.3g}x{aspect[1]:.3g}")
                         for aspect, _ in population.aspect_classes_of]
        bases = [(s, size_of(s, population.size_definition)) for s in generated]
    elif population.size_definition == "circumscribed":
        return (population.make_shape(),)
    else:
        base = population.model_copy(update={"size": 1.0, "grading": None,
                                             "size_definition": "circumscribed"}).make_shape()
        bases = [(base, size_of(base, population.size_definition))]
    shapes = []
    for base, base_size in bases:
        shape = base.scaled(size / base_size)
        shape.scale_of = None  # the population's own shape: its graded grains are scaled from it
        shapes.append(shape)
    return tuple(shapes)


class TimeSteppingConfig(_Model):
    """The Moreau-Jean time stepping: step, scheme, and how far ahead contacts are looked for.

    Method: docs/method/nscd.md.
    """

    time_step: _Number = _setting(5e-3, "sqrt(d/g)", gt=0, description="Time step h. Rule of thumb: at most "
                                  "0.01 sqrt(d_min/g), d_min the smallest grain (0.01 for one size); the overlaps of "
                                  "impacts and the error of the linearised gaps grow with it.")
    theta: _Number = _setting(0.5, ge=0.5, le=1, description="Theta of the scheme, in [0.5, 1]: 0.5 conserves "
                              "the energy of free motion, 1 is the most dissipative.")
    rotation_update: Literal["theta", "from-start"] = _setting(
        "theta", description="'theta': the end orientation is the predicted one turned by theta h omega_end, the "
        "scheme the gaps are linearised in; 'from-start': the start orientation turned by h omega_end, as LMGC90's "
        "RBDY3 'new rotation scheme', off the linearised gaps by (1 - theta) h (omega_end - omega_start) at "
        "impacts: a compatibility setting, to measure what that update does to a packing, not for use.")
    alert_distance: Optional[_Number] = _setting(
        None, "d", gt=0, description=f"Gap below which a pair is a contact candidate; unset: automatic, "
        f"{AUTO_ALERT_FRACTION:g} x the largest grain size (raised step by step while grains move fast).")
    max_rotation: _Number = _setting(
        0.05, "rad", gt=0, description="Largest rotation in one step of a polyhedron of circumscribed radius "
        "R = 0.5 d (a grain of radius R may turn by max_rotation sqrt(0.5 d / R)): a step in which some grain in "
        "reach of another grain or the wall would turn further is split into substeps. A turn by phi moves a "
        "grain's surface off its linearised path by up to R phi^2 / 2 (6e-4 d at 0.05 rad).")


class SolverConfig(_Model):
    """The contact law and its solver, the nonlinear Gauss-Seidel (NLGS).

    Method: docs/method/nscd.md.
    """

    friction: _Number = _setting(0.0, ge=0, description="Coulomb friction coefficient mu (0: frictionless).")
    restitution: _Number = _setting(0.0, ge=0, le=1, description="Normal restitution coefficient e_N, in [0, 1].")
    tolerance: _Number = _setting(1e-4, gt=0, description="NLGS convergence tolerance (LMGC90's 'Quad' norm) "
                                  "near rest. Rule of thumb: at most 1e-3, or the equilibrium criteria are "
                                  "not met; 1e-5 for a pile that keeps missing the force criterion near rest "
                                  "while its grains hardly move and the overlaps' sum grows (timeline.csv's "
                                  "overlap_sum: a tall graded column of scans sank into its overlaps with 1e-4; "
                                  "docs, design notes). May be changed for a run that goes on "
                                  "(granpack run --resume).")
    settling_tolerance: _Number = _setting(
        1e-3, gt=0, description="NLGS tolerance while the pile is far from rest (kinetic criterion above "
        "`tolerance_below`); the run then switches to `tolerance` for good.")
    tolerance_below: _Number = _setting(
        1e-5, "d^3 P", gt=0, description="Kinetic criterion (largest kinetic energy per grain) below which the "
        "NLGS is solved to `tolerance` (for good); the equilibrium window only counts checks made with it.")
    max_iterations: int = _setting(2000, ge=1, le=10_000_000, description="Most NLGS sweeps per time step.")
    check_every: int = _setting(10, ge=1, le=10_000_000, description="NLGS sweeps between two convergence checks.")
    acceleration: Literal["nncg", "none"] = _setting(
        "nncg", description="'nncg': the momentum of nonsmooth nonlinear conjugate gradients on each symmetric "
        "pair of sweeps (with or without friction; Gauss-Seidel alone carries a load down a pile one layer per sweep); "
        "'none': plain NLGS.")


class OverlapConfig(_Model):
    """How overlaps are kept small: pushed back by the velocity law, projected away after a step.

    Method: docs/method/position-correction.md.
    """

    recovery_slop: _Number = _setting(
        5e-4, "d", ge=0, description="Overlap allowed: a deeper one is pushed back by the velocity law (a "
        "separating velocity of recovery_rate x the excess per step, at most recovery_speed). A pile at rest "
        "keeps its overlaps below it.")
    recovery_rate: _Number = _setting(
        0.2, ge=0, description="Fraction of an overlap's excess over recovery_slop pushed back per step; 0: "
        "none (the plain velocity-level law, which never pushes an overlap back, as LMGC90's).")
    recovery_speed: _Number = _setting(0.05, "sqrt(g d)", ge=0,
                                       description="Largest separating speed of the overlap recovery.")
    recovery_near_rest: bool = _setting(
        True, description="Whether that recovery still pushes once the pile is near rest (kinetic criterion "
        "below solver.tolerance_below): true, every run's rule so far; false stops it there, the projection "
        "(projection_slop) left as the backstop, the overlaps then growing towards it; the piles measured rest no "
        "sooner with false, and bidisperse pinacoids much later.")
    rest_recovery_slop: _Number = _setting(
        5e-5, "d", ge=0, description="With `rest_recovery_speed` > 0: when the pile first meets the criteria "
        "with a deeper overlap, the overlaps deeper than this are pushed back too, at most at "
        "`rest_recovery_speed`, and the equilibrium window starts again; it then bounds the overlaps of the "
        "packing written, hence its k.")
    rest_recovery_speed: _Number = _setting(
        0.0, "sqrt(g d)", ge=0, description="Largest speed of that slow recovery at rest; 0: none, the run "
        "ends at the first pass of the window with its overlaps up to recovery_slop. Rule of thumb: 2e-4 "
        "brings the expansion coefficient k down about three times, for tens of sqrt(d/g) more to rest.")
    slop_scale: Literal["largest", "pair"] = _setting(
        "largest", description='What the slops above and below are in: "largest", d for every pair (the '
        'kept runs\' rule); "pair", each pair\'s slops times its smaller grain\'s circumscribed size over the '
        'largest grain\'s, so that small grains overlap no deeper relative to their size than large ones '
        '(a wide grading: the projection and recovery act on the small grains at their own scale).')
    projection_slop: _Number = _setting(
        2e-3, "d", ge=0, description="Overlap above which positions are also projected after a step (to 0.1 "
        "of it): a backstop for the overlaps the recovery has not yet pushed back; 0: none.")
    pour_projection_slop: _Number = _setting(
        2e-3, "d", ge=0, description="The same while grains move fast (alert distance raised above "
        "alert_distance); the smaller of the two applies then.")
    pour_projection_interval: int = _setting(
        5, "steps", ge=1, description="While grains move fast, positions are projected every this many steps "
        "only (1: every step): the overlaps of a pour come from its impacts, so a projection at every step "
        "costs much and removes little.")


class EndGameConfig(_Model):
    """How a collapsed pile is brought to rest.

    Method: docs/method/equilibrium.md.
    """

    mode: Literal["damping", "none"] = _setting(
        "damping", description="'damping': every grain's velocity is scaled by exp(-damping_rate h) after "
        "each step once the kinetic criterion is below `damping_below` (not on the steps whose equilibrium is "
        "checked, so the criteria judge undamped dynamics); 'none': undamped NSCD throughout.")
    damping_rate: _Number = _setting(1.0, "1/sqrt(d/g)", gt=0, description="Rate of the viscous damping.")
    damping_below: _Number = _setting(
        1e-3, "d^3 P", gt=0, description="Kinetic criterion (largest kinetic energy per grain) below which the "
        "end game starts, for good; it starts too at the first check whose net forces meet their criterion "
        "(grains moving freely, as a grain spinning in place or sliding on a frictionless floor).")
    shake_speed: _Number = _setting(
        0.0, "sqrt(g d)", ge=0, description="Speed of a shake: each time the pile comes near rest but fails the "
        "criteria (kinetic criterion below `shake_below`, at most once per `shake_interval`), every grain's "
        "velocity gets this speed more in a random direction, so that a grain held by a contact that carries "
        "almost no force leaves it at once; 0: no shake.")
    shake_below: _Number = _setting(1e-7, "d^3 P", gt=0,
                                    description="Kinetic criterion below which the pile is shaken.")
    shake_interval: _Number = _setting(5.0, "sqrt(d/g)", gt=0, description="Least simulated time between two shakes.")


class ThreadsConfig(_Model):
    """How the NLGS uses threads (their number is Numba's: NUMBA_NUM_THREADS).

    Method: docs/method/nscd.md.
    """

    parallel_points: int = _setting(
        2000, "points", ge=0, description="Contact problems of at least this many points are swept by two "
        "threads: the lower and the upper part of the pile at once, then the points across them. The order of "
        "the sweeps, and so the run, is the same whatever the number of threads; 0: never split. Each sweep "
        "ends on a barrier, so two runs sharing two cores should each have NUMBA_NUM_THREADS=1.")


class ContainerConfig(_Model):
    """What holds the grains beside the floor z = 0 (the cell's sides, :mod:`granpack.box`).

    Method: docs/method/contact-detection.md#containers.
    """

    shape: Literal["periodic", "box", "cylinder"] = _setting(
        "periodic", description='"periodic": x and y periodic with period `lateral_size` (a bulk sample); '
        '"box": four rigid vertical walls, `lateral_size` the inside side; "cylinder": a rigid vertical '
        "cylinder, `lateral_size` its inside diameter. The deposit pours into the container, and the settling "
        "holds the grains with its walls from the start.")
    wall_friction: Optional[_Number] = _setting(
        None, ge=0, description="Coulomb friction coefficient of the grains against the floor and the "
        "container's walls; unset: `solver.friction`.")


#: the tables of a run config that hold settings, in the order a resolved config writes them
SETTING_TABLES = ("container", "time_stepping", "solver", "overlap", "end_game", "threads", "equilibrium", "deposit",
                  "output")

#: the settings a run may go on under with other values (``granpack run --resume``, from its
#: checkpoint or from the final state of a run that ended not at rest): how long it may run and how
#: finely its later steps are solved change nothing it has already done, so the run stays one run
CONTINUABLE_SETTINGS = ("equilibrium.max_time", "solver.tolerance")

#: keys of the flat ``[solver]`` table of granpack 0.1.0 and where they now live, ``(table, key)``
MOVED_SOLVER_KEYS = {
    "time_step": ("time_stepping", "time_step"),
    "theta": ("time_stepping", "theta"),
    "alert_distance": ("time_stepping", "alert_distance"),
    "max_rotation": ("time_stepping", "max_rotation"),
    "recovery_slop": ("overlap", "recovery_slop"),
    "recovery_rate": ("overlap", "recovery_rate"),
    "recovery_speed": ("overlap", "recovery_speed"),
    "rest_recovery_slop": ("overlap", "rest_recovery_slop"),
    "rest_recovery_speed": ("overlap", "rest_recovery_speed"),
    "overlap_slop": ("overlap", "projection_slop"),
    "pour_overlap_slop": ("overlap", "pour_projection_slop"),
    "pour_correction_interval": ("overlap", "pour_projection_interval"),
    "end_game": ("end_game", "mode"),
    "damping_rate": ("end_game", "damping_rate"),
    "damping_below": ("end_game", "damping_below"),
    "shake_speed": ("end_game", "shake_speed"),
    "shake_below": ("end_game", "shake_below"),
    "shake_interval": ("end_game", "shake_interval"),
    "parallel_points": ("threads", "parallel_points"),
}


class EquilibriumConfig(_Model):
    """When a packing counts as at rest and how long to wait for it.

    Criteria and the stress scale P: docs/method/equilibrium.md.
    """

    max_time: _Number = _setting(
        300.0, "sqrt(d/g)", gt=0, description="Simulated time after which the run stops unsettled. Rule of "
        "thumb: piles of some thousand grains rest at t = 50 to 250, wider and flatter ones later. Raised, "
        "granpack run --resume takes a run that ended not at rest further.")
    force_tolerance: _Number = _setting(1e-4, "d_p^2 P", gt=0, description="Bound on every grain's net force |F_p|.")
    torque_tolerance: _Number = _setting(1e-4, "d_p^3 P", gt=0, description="Bound on every grain's net torque |T_p|.")
    kinetic_tolerance: _Number = _setting(1e-8, "d^3 P", gt=0, description="Bound on the kinetic energy per grain.")
    wall_tolerance: _Number = _setting(
        1e-4, gt=0, description="Bound on |weight - wall force| / weight (the global vertical balance).")
    window: int = _setting(5, "checks", ge=1, le=10_000_000, description="Consecutive checks that must all pass.")
    check_interval: _Number = _setting(0.25, "sqrt(d/g)", gt=0, description="Simulated time between two checks.")


class DepositConfig(_Model):
    """Geometric pluviation of the grains' circumscribed spheres.

    Method: docs/method/pluviation.md.
    """

    method: Literal["drop", "lmgc"] = _setting(
        "drop", description='"drop": random drop and roll; "lmgc": lowest three-support position, as '
        "LMGC90's depositInBox3D.")
    lateral: Literal["walls", "periodic"] = _setting(
        "walls", description='Lateral boundaries during the deposit: "walls" or "periodic".')


class OutputConfig(_Model):
    """What a run writes besides its final packing."""

    checkpoint_interval: _Number = _setting(5.0, "sqrt(d/g)", gt=0, description="Simulated time between checkpoints.")
    snapshot_interval: _Number = _setting(
        0.0, "sqrt(d/g)", ge=0, description="Simulated time between trajectory snapshots; 0: none.")


class RunConfig(_Model):
    """One packing: the grains, the cell, and the solver, equilibrium, deposit and output settings.

    ``lateral_size`` is declared after ``populations``, ``time_stepping`` and ``container`` because
    its check uses them.
    """

    seed: int = Field(default=1, ge=0, description="Seed of the random generator (deposit, orientations).")
    n_particles: int = Field(default=3000, ge=1, le=MAX_PARTICLES, description="Number of grains N.")
    populations: Annotated[tuple[PopulationConfig, ...], Strict(False)] = Field(
        min_length=1, description="The grain populations ([[populations]] tables)."
    )
    time_stepping: TimeSteppingConfig = Field(default_factory=TimeSteppingConfig, description="[time_stepping] table.")
    solver: SolverConfig = Field(default_factory=SolverConfig, description="[solver] table.")
    overlap: OverlapConfig = Field(default_factory=OverlapConfig, description="[overlap] table.")
    end_game: EndGameConfig = Field(default_factory=EndGameConfig, description="[end_game] table.")
    threads: ThreadsConfig = Field(default_factory=ThreadsConfig, description="[threads] table.")
    container: ContainerConfig = Field(default_factory=ContainerConfig, description="[container] table.")
    lateral_size: Annotated[_Number, Field(validate_default=True)] = Field(
        default=8.0, gt=0, description="Side of the square periodic cell, or the container's inside side "
        "(box) or diameter (cylinder), d."
    )
    equilibrium: EquilibriumConfig = Field(default_factory=EquilibriumConfig, description="[equilibrium] table.")
    deposit: DepositConfig = Field(default_factory=DepositConfig, description="[deposit] table.")
    output: OutputConfig = Field(default_factory=OutputConfig, description="[output] table.")

    @field_validator("populations")
    @classmethod
    def _check_shares(cls, populations: tuple[PopulationConfig, ...], info: ValidationInfo) -> tuple[PopulationConfig, ...]:
        total = math.fsum(p.volume_fraction for p in populations)
        if abs(total - 1.0) > SHARE_TOLERANCE:
            shares = ", ".join(f"{p.volume_fraction:g}" for p in populations)
            raise ValueError(f"volume_fraction values must sum to 1 (got {shares}: sum {total:.9g})")
        seen: dict[str, int] = {}
        for k, p in enumerate(populations):
            if p.name in seen:
                raise ValueError(
                    f"populations[{seen[p.name]}] and populations[{k}] have the same name {p.name!r}; give them distinct names"
                )
            seen[p.name] = k
        return tuple(p.with_run_seed(info.data.get("seed", 1)) if p.shape == "rock" and p.seed is None else p
                     for p in populations)

    @field_validator("lateral_size")
    @classmethod
    def _check_lateral(cls, lateral_size: float, info: ValidationInfo) -> float:
        populations, stepping = info.data.get("populations"), info.data.get("time_stepping")
        container = info.data.get("container")
        if populations is None or stepping is None or container is None:
            return lateral_size  # reported elsewhere
        largest = max(p.largest_size for p in populations)
        alert = _alert_distance(stepping, largest)
        minimum = _narrowest_cell(largest, alert)
        if not lateral_size > minimum:
            what = {"periodic": "so that a pair interacts through at most one periodic image",
                    "box": "so that the box holds two grains side by side (its inside side)",
                    "cylinder": "so that the cylinder holds two of the largest grains side by side (its inside "
                                "diameter)"}[container.shape]
            raise ValueError(
                f"must exceed 2 x (largest grain size {largest:g} + alert distance {alert:g}) = {minimum:g} d {what} "
                f"(got {lateral_size:g})"
            )
        smallest = min(p.smallest_size for p in populations)
        cells = (lateral_size / (smallest + alert)) ** 2
        if cells > MAX_GRID_CELLS:
            largest_side = (smallest + alert) * math.sqrt(MAX_GRID_CELLS)
            raise ValueError(
                f"must be at most {largest_side:.6g} d: a {lateral_size:g} d cell holds {cells:.3g} contact-grid cells "
                f"of the smallest grain's size {smallest:g} d, more than the {MAX_GRID_CELLS:.3g} granpack allocates"
            )
        return lateral_size

    @model_validator(mode="after")
    def _check_deposit_sides(self) -> "RunConfig":
        if self.container.shape != "periodic" and self.deposit.lateral == "periodic":
            raise ValueError(f'deposit.lateral: must be "walls" in a {self.container.shape} (container.shape '
                             f'{self.container.shape!r}: the deposit pours into the container; got "periodic")')
        return self

    @model_validator(mode="after")
    def _check_times(self) -> "RunConfig":
        h, end = self.time_stepping.time_step, self.equilibrium.max_time
        if not h < end:
            raise ValueError(f"time_stepping.time_step: must be below equilibrium.max_time = {end:g} sqrt(d/g) (got {h:g})")
        if self.equilibrium.check_interval < h:
            raise ValueError(f"equilibrium.check_interval: must be at least time_stepping.time_step = {h:g} sqrt(d/g) "
                             f"(got {self.equilibrium.check_interval:g})")
        return self

    @property
    def largest_size(self) -> float:
        """Largest circumscribed diameter over the populations, d."""
        return max(p.largest_size for p in self.populations)

    @property
    def resolved_alert_distance(self) -> float:
        """The alert distance in use, d: ``time_stepping.alert_distance``, or automatic if unset."""
        return _alert_distance(self.time_stepping, self.largest_size)

    @property
    def floor_area(self) -> float:
        """The area the pile stands on, d^2: ``lateral_size^2`` in the periodic cell and the box,
        ``pi lateral_size^2 / 4`` in the cylinder."""
        if self.container.shape == "cylinder":
            return math.pi * self.lateral_size ** 2 / 4.0
        return self.lateral_size ** 2

    @property
    def narrowest_cell(self) -> float:
        """The bound ``lateral_size`` must exceed, d: 2 (largest grain size + alert distance)."""
        return _narrowest_cell(self.largest_size, self.resolved_alert_distance)

    def with_seed(self, seed: int) -> "RunConfig":
        """This config with another seed.

        Raises:
            InputError: ``seed`` is not an integer >= 0.
        """
        return _validate({**self.model_dump(), "seed": seed}, None)

    def to_toml(self) -> str:
        """The fully resolved config as TOML (every default written, each key with its description).

        Keys left unset on purpose (``time_stepping.alert_distance`` when automatic) are written as a
        comment. :func:`load_config_dict` of the parsed text gives an object equal to ``self``.
        """
        lines = [
            "# granpack run config, fully resolved (every default filled in).",
            "# Lengths in d (largest grain's circumscribed diameter), times in sqrt(d/g).",
            "",
        ]
        lines += _toml_keys(self, ("seed", "n_particles", "lateral_size"))
        for population in self.populations:
            lines += ["", "[[populations]]"]
            keys = [k for k in PopulationConfig.model_fields if getattr(population, k) is not None and k != "grading"]
            lines += _toml_keys(population, ["name"] + [k for k in keys if k != "name"])
            if population.grading is not None:
                grading = population.grading
                lines += ["", "[populations.grading]"]
                lines += _toml_keys(grading, [k for k in GradingConfig.model_fields if getattr(grading, k) is not None])
        for table in SETTING_TABLES:
            model = getattr(self, table)
            lines += ["", f"[{table}]"] + _toml_keys(model, type(model).model_fields)
        return "\n".join(lines) + "\n"


def _narrowest_cell(largest_size: float, alert: float) -> float:
    """The bound a periodic cell's side must exceed, d: ``2 (largest_size + alert)``, so that a pair
    of grains interacts through at most one periodic image."""
    return 2.0 * (largest_size + alert)


def _alert_distance(stepping: TimeSteppingConfig, largest_size: float) -> float:
    """``time_stepping.alert_distance`` or, if unset, ``AUTO_ALERT_FRACTION * largest_size`` (d)."""
    if stepping.alert_distance is not None:
        return stepping.alert_distance
    return AUTO_ALERT_FRACTION * largest_size


def _toml_value(value: Any) -> str:
    """One TOML value: bool, int, finite float, str, or a (nested) array of them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # names are restricted to characters JSON and TOML escape alike
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} as TOML")


def _toml_keys(model: BaseModel, keys) -> list[str]:
    """``# description`` + ``key = value`` lines; a ``None`` value becomes a commented-out key."""
    fields = type(model).model_fields
    lines = []
    for key in keys:
        value = getattr(model, key)
        unit = unit_of(type(model), key)
        lines.append(f"# {fields[key].description}" + (f" [{unit}]" if unit else ""))
        lines.append(f"# {key} = (unset)" if value is None else f"{key} = {_toml_value(value)}")
    return lines


def _field_path(loc: tuple) -> str:
    """``("populations", 1, "size")`` -> ``"populations[1].size"``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


def _shown(value: Any) -> str:
    """A short rendering of a bad input value for an error message."""
    if isinstance(value, str):
        text = repr(value)
    elif isinstance(value, (list, tuple, dict, bool)) or value is None:
        text = json.dumps(value, default=str)
    else:
        text = str(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _allowed_keys(loc: tuple) -> list[str]:
    """Keys allowed in the table that holds the unknown key at ``loc``."""
    model: type[BaseModel] = RunConfig
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        annotation = model.model_fields[part].annotation
        model = {"populations": PopulationConfig, "grading": GradingConfig}.get(part, annotation)
    return list(model.model_fields)


def _describe(error: dict) -> tuple[tuple, str]:
    """(field location, one-line message) for one pydantic error."""
    loc, kind, ctx, value = tuple(error["loc"]), error["type"], error.get("ctx", {}), error.get("input")
    got = f" (got {_shown(value)})"
    if kind == "extra_forbidden":
        return loc, f"unknown key (allowed: {', '.join(_allowed_keys(loc))})"
    if kind == "missing":
        if loc and isinstance(loc[-1], int):  # a too short [x, y, z] or [L/G, G/E]
            return loc[:-1], f"too few numbers (got {_shown(value)})"
        return loc, "required key is missing"
    messages = {
        "greater_than": lambda: f"must be > {ctx.get('gt'):g}{got}",
        "greater_than_equal": lambda: f"must be >= {ctx.get('ge'):g}{got}",
        "less_than": lambda: f"must be < {ctx.get('lt'):g}{got}",
        "less_than_equal": lambda: f"must be <= {ctx.get('le'):g}{got}",
        "literal_error": lambda: f"must be {ctx.get('expected')}{got}",
        "float_type": lambda: f"must be a number{got}",
        "finite_number": lambda: f"must be a finite number{got}",
        "int_type": lambda: f"must be an integer{got}",
        "int_from_float": lambda: f"must be an integer{got}",
        "string_type": lambda: f"must be a string{got}",
        "tuple_type": lambda: f"must be an array{got}",
        "model_type": lambda: f"must be a table{got}",
        "dict_type": lambda: f"must be a table{got}",
        "too_short": lambda: f"needs at least {ctx.get('min_length')} item(s){got}",
        "too_long": lambda: f"takes at most {ctx.get('max_length')} item(s){got}",
        "value_error": lambda: str(error["msg"]).removeprefix("Value error, "),
    }
    return loc, messages.get(kind, lambda: f"{error['msg']}{got}")()


def moved_keys(data: dict) -> list[str]:
    """The keys of ``data`` (a parsed config) written in the flat ``[solver]`` table of granpack
    0.1.0, each as ``"solver.OLD -> TABLE.KEY"`` (:data:`MOVED_SOLVER_KEYS`); empty for today's layout."""
    solver = data.get("solver") if isinstance(data, dict) else None
    if not isinstance(solver, dict):
        return []
    return [f"solver.{old} -> {'.'.join(MOVED_SOLVER_KEYS[old])}" for old in solver if old in MOVED_SOLVER_KEYS]


def _regrouped(data: dict, prefix: str) -> dict:
    """``data`` with the keys of the flat ``[solver]`` table of granpack 0.1.0 moved to their tables
    (:data:`MOVED_SOLVER_KEYS`), so that its config files and kept runs keep working."""
    solver = data.get("solver")
    if not isinstance(solver, dict) or not any(old in MOVED_SOLVER_KEYS for old in solver):
        return data
    data, solver = dict(data), dict(solver)
    for old in [k for k in solver if k in MOVED_SOLVER_KEYS]:
        table, key = MOVED_SOLVER_KEYS[old]
        target = data.get(table, {})
        if not isinstance(target, dict):
            continue  # reported by the validation: "must be a table"
        if key in target:
            raise InputError(f"{prefix}solver.{old}: the same setting as {table}.{key}, which is also given; keep only "
                             f"{table}.{key}")
        data[table] = {**target, key: solver.pop(old)}
    data["solver"] = solver
    return data


def _validate(data: Any, source: str | None, base_dir: Path | None = None) -> RunConfig:
    prefix = f"{source}: " if source else ""
    if not isinstance(data, dict):
        raise InputError(f"{prefix}must be a table of config keys (got {type(data).__name__})")
    try:
        return RunConfig.model_validate(_regrouped(data, prefix), context={"base_dir": base_dir})
    except ValidationError as exc:
        loc, message = _describe(exc.errors(include_url=False)[0])
        where = f"{_field_path(loc)}: " if loc else ""
        raise InputError(" ".join(f"{prefix}{where}{message}".split())) from None


def load_config_dict(data: dict, source: str = "<dict>", base_dir: Path | None = None) -> RunConfig:
    """Validate a config given as a dict (parsed TOML).

    Args:
        data: the config keys, as :func:`tomllib.loads` returns them.
        source: what the data came from, first in error messages (a file name, a campaign entry).
        base_dir: the folder that relative mesh `files` are read from; default the current one.

    Raises:
        InputError: one line ``SOURCE: FIELD.PATH: what is wrong``.
    """
    return _validate(data, source, base_dir)


def load_config(path: str | Path) -> RunConfig:
    """Read and validate a run config file (TOML).

    Args:
        path: the TOML file.

    Raises:
        InputError: missing or unreadable file, not TOML, unknown key or bad value; one line naming
            the file and the field path.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a config file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a TOML file (not UTF-8 text)") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(" ".join(f"{path}: not valid TOML: {exc}".split())) from None
    return _validate(data, str(path), path.parent)
