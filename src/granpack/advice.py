"""What granpack says of a run config before the run: warnings, and refusals of what cannot work.

:func:`granpack.simulation.run_packing` calls :func:`advise` before anything is
written, so the Python API warns and refuses as ``granpack check`` and ``granpack run`` do; a
campaign checks each of its runs the same way before any starts.

- Warnings (:func:`warnings_of`): settings outside the range where runs are known to go well, a
  pile too short for a bulk region, a grading that the grains follow only roughly, a frictional
  pile, whose analysis follows other rules than the frictionless study's. The run goes on.
- Refusals (:func:`refusal`, raised by :func:`advise` as :class:`~granpack.errors.InputError`): a
  grading that ``n_particles`` grains cannot represent at all, because their poured sieve curve
  strays from the requested one by more than :data:`GRADING_REFUSAL`, or because they make no pile
  to speak of (lower than :data:`LEAST_GRADED_PILE` largest grains). Such a run would spend its time
  on a handful of the largest grains or on a dust of the smallest and measure neither.
"""

from __future__ import annotations

import math

from granpack.analysis.report import AnalysisOptions
from granpack.config import RunConfig
from granpack.errors import InputError
from granpack.mixture import PHI_MIXED_SIZES, PHI_ONE_SIZE, Mixture

__all__ = ["GRADING_DEVIATION", "GRADING_REFUSAL", "LEAST_GRADED_PILE", "advise", "column_warning", "expected_height", "friction_warning",
           "grading_warnings", "refusal", "settings_warnings", "warnings_of", "USEFUL_NARROWING"]

#: largest gap between the requested and the poured sieve curves accepted without a warning
GRADING_DEVIATION = 0.02
#: largest gap between the requested and the poured sieve curves of a run that is not refused
GRADING_REFUSAL = 0.25
#: least expected height of a graded pile, in largest grains (d), of a run that is not refused
LEAST_GRADED_PILE = 1.0
#: a cell is advised down to its narrowest only from this many times the narrowest
USEFUL_NARROWING = 1.05


def settings_warnings(config: RunConfig) -> list[str]:
    """Settings that are valid but outside the range where runs are known to go well, each one
    line naming the key."""
    notes = []
    h = config.time_stepping.time_step
    smallest = min(p.smallest_size for p in config.populations)
    largest_step = 0.01 * math.sqrt(smallest)
    if h > largest_step:
        notes.append(f"time_stepping.time_step = {h:g} sqrt(d/g) is above 0.01 sqrt(d_min/g) = "
                     f"{largest_step:.3g} (d_min = {smallest:g} d, the smallest grain): the overlaps "
                     "of impacts and the error of the gaps held linear over a step grow with the step over sqrt(d_min/g)")
    if config.solver.tolerance > 1e-3:
        notes.append(f"solver.tolerance = {config.solver.tolerance:g} is above 1e-3: the contact forces are then "
                     "too inexact for the equilibrium criteria to be met")
    if config.equilibrium.max_time < 30.0:
        notes.append(f"equilibrium.max_time = {config.equilibrium.max_time:g} sqrt(d/g): piles seldom come to rest "
                     "before t = 30 (300 isometric pinacoids: about 60), so the run will likely stop at the cap")
    return notes


def friction_warning(config: RunConfig) -> str | None:
    """For a frictional run (``solver.friction`` > 0), the one line that says how its analysis
    differs: the frictional rules of :mod:`granpack.analysis.coordination` (rattlers, constraint
    count, isostatic references, sliding contacts), whose figures are not those of the frictionless
    study; None for a frictionless run."""
    mu = config.solver.friction
    if not mu > 0:
        return None
    return (f"solver.friction = {mu:g}: `granpack analyze` applies the frictional rules (a rattler below 3 "
            "force-bearing contact points; 3, 5, 6 force components per simple, double, triple contact against an "
            "isostatic 12 per grain, N = 4 for spheres; sliding contacts counted): compare its N and Nc with those, "
            "not with the frictionless N = 6 and Nc = 12")


def _grains_for_gap(config: RunConfig, deviation: float, target: float) -> int:
    """Grains that bring a sieve curve's largest gap from ``deviation`` to ``target`` (the gap
    falls about as 1/N), rounded up to a hundred."""
    return int(math.ceil(config.n_particles * deviation / target / 100.0)) * 100


def grading_warnings(config: RunConfig, mixture: Mixture) -> list[str]:
    """A warning for each graded population whose poured sieve curve strays from the requested one
    by more than :data:`GRADING_DEVIATION` (too few grains in its coarse fractions), with the grain
    count that would do."""
    out = []
    for k, population in enumerate(config.populations):
        if population.grading is None or not mixture.counts[k]:
            continue
        deviation = mixture.largest_deviation(k)
        if deviation > GRADING_DEVIATION:
            coarse = int((mixture.sizes[k] > population.grading_curve.d_max / 2).sum())
            out.append(f"{population.name}: the {mixture.counts[k]} grains follow the requested sieve curve to within "
                       f"{100 * deviation:.1f} % (largest gap; {coarse} grains above half the largest size carry the "
                       f"coarse fractions): n_particles about {_grains_for_gap(config, deviation, GRADING_DEVIATION)} "
                       f"brings it within {100 * GRADING_DEVIATION:g} %")
    return out


def _bulk_column(config: RunConfig) -> float:
    """The least pile height with a bulk region, d: ``n_bottom`` above the wall, one largest grain of
    bulk, ``n_top`` below the surface (:class:`~granpack.analysis.report.AnalysisOptions`)."""
    options = AnalysisOptions()
    return (options.n_bottom + options.n_top + 1.0) * config.largest_size


def expected_height(config: RunConfig, mixture: Mixture) -> tuple[float, float]:
    """The expected height of the settled pile, d, and the solid fraction it is estimated at:
    the grains' volume over the floor's area (the cell's, the box's or the cylinder's section)
    and that solid fraction (:meth:`granpack.mixture.Mixture.pile_height`)."""
    phi = PHI_MIXED_SIZES if mixture.has_mixed_sizes else PHI_ONE_SIZE
    return mixture.pile_height(config.floor_area, phi), phi


def column_warning(config: RunConfig, mixture: Mixture) -> str | None:
    """A warning when the settled pile is expected to be too low for a bulk region (else None),
    with what would give one: more grains, or a narrower cell where the cell can be narrowed.

    The height is :meth:`granpack.mixture.Mixture.pile_height`; the bulk region of ``granpack
    analyze`` starts ``n_bottom d`` above the wall, ends ``n_top d`` below the surface and must be
    at least ``d`` thick (``d`` the largest grain size).
    """
    options = AnalysisOptions()
    holder = {"periodic": "cell", "box": "box", "cylinder": "cylinder"}[config.container.shape]
    where = (f"{config.lateral_size:g} d cylinder" if holder == "cylinder" else
             f"{config.lateral_size:g} d x {config.lateral_size:g} d {holder}")
    height, phi = expected_height(config, mixture)
    needed = _bulk_column(config)
    if height >= needed:
        return None
    n_needed = int(-(-config.n_particles * needed // height)) + 1 if height > 0 else None
    remedies = [f"about {n_needed} grains" if n_needed else "more grains"]
    narrowest = config.narrowest_cell
    fitting = config.lateral_size * math.sqrt(height / needed)  # the same grains, a bulk region
    if fitting > narrowest:
        remedies.append(f"a {holder} of about {math.floor(100 * fitting) / 100:g} d")
    elif config.lateral_size > USEFUL_NARROWING * narrowest:
        remedies.append(f"the narrowest cell ({narrowest:.3g} d, lateral_size must exceed it) with more grains")
    else:
        remedies[0] += " (the cell is at its narrowest)"
    return (f"the settled pile will stand about {height:.2g} d high (solid fraction about {phi:g} over the "
            f"{where}), below the {needed:g} d that a bulk region "
            f"needs ({options.n_bottom * config.largest_size:g} d above the wall, {config.largest_size:g} d of bulk, "
            f"{options.n_top * config.largest_size:g} d below the surface): the bulk figures of `granpack analyze` will be nan; use {' or '.join(remedies)}")


def warnings_of(config: RunConfig, mixture: Mixture) -> list[str]:
    """Every warning of ``config``: its settings, its gradings, its pile, its friction."""
    column, friction = column_warning(config, mixture), friction_warning(config)
    return (settings_warnings(config) + grading_warnings(config, mixture) + ([column] if column else [])
            + ([friction] if friction else []))


def refusal(config: RunConfig, mixture: Mixture) -> str | None:
    """Why ``config`` cannot give a packing (one line naming the keys and the grain count it would
    need), or None. Only graded populations are judged: a few grains of one size make a small pile
    by design (a ball on a floor), a grading poured by too few grains is a mistake."""
    for k, population in enumerate(config.populations):
        if population.grading is None:
            continue
        key = f"populations[{k}].grading"
        grading = population.grading
        curve = population.grading_curve
        what = f"{grading.curve} curve from {curve.d_min:.4g} d to {curve.d_max:.4g} d"
        height, phi = expected_height(config, mixture)
        deviation = mixture.largest_deviation(k) if mixture.counts[k] else 1.0
        if deviation <= GRADING_REFUSAL and height >= LEAST_GRADED_PILE * config.largest_size:
            continue
        needs = [_grains_for_gap(config, deviation, GRADING_DEVIATION)]
        if height > 0:
            needs.append(int(math.ceil(config.n_particles * _bulk_column(config) / height)))
        problems = []
        if deviation > GRADING_REFUSAL:
            problems.append(f"their poured sieve curve strays from it by {100 * deviation:.0f} % (more than "
                            f"{100 * GRADING_REFUSAL:g} % is refused)")
        if height < LEAST_GRADED_PILE * config.largest_size:
            problems.append(f"they would stand about {height:.2g} d high (less than one largest grain)")
        return (f"{key} ({what}) cannot be represented by n_particles = {config.n_particles}: "
                f"{' and '.join(problems)}; it needs about {max(needs):.3g} grains, or a narrower range of sizes "
                f"({key}.d_min or the first sieve raised)")
    return None


def advise(config: RunConfig, mixture: Mixture | None = None) -> list[str]:
    """The warnings of ``config`` (:func:`warnings_of`); raises before any of them when it is refused.

    Raises:
        InputError: :func:`refusal` gives a reason.
    """
    mixture = Mixture.from_config(config) if mixture is None else mixture
    reason = refusal(config, mixture)
    if reason is not None:
        raise InputError(reason)
    return warnings_of(config, mixture)
