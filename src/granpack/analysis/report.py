"""The analysis of one packing as the ``analysis.json`` document (keys are a contract: docs/reference/outputs.md#analysisjson).

Top-level keys: ``solid_fraction`` {bulk, std, profile_z, profile_phi, ...}, ``coordination``
{N, Ns, Nd, Nt, Nc, rattler_fraction, ...; contact types from the force-bearing points, the same
figures with the gap-rule and the detection types under ``gap_rule`` and ``geometric``; a
frictional packing's rule, constraint count and sliding contacts under ``frictional``}, ``order``
{Q00, Q22, director, ...},
``pair_correlation`` {r, g, ...}, ``equilibrium`` {max_net_force, max_net_torque, kinetic_energy,
wall_force_over_weight, ...}, ``interpenetration`` {max, mean, expansion_k, ...}, ``homogeneity``
{z, proportions, ...}, ``size_classes`` {sieves, passing, profile, coordination, ...; a packing of
several sizes only}, ``wall_profile`` {distance, solid_fraction, section_solid_fraction, N, Q00, ...;
a box's or a cylinder's packing only, whose bulk figures are those of its core}, ``walls``
{floor_vertical, side_vertical, side_normal, depth, vertical_stress, janssen, ...; the walls' forces
as shares of the weight, against the depth, and the fit of Janssen's law; a container's only}, ``grain_shapes`` {elongation, flatness, sphericity, convexity: one value per
grain}, ``n_particles``, ``populations`` (each with its coordination, order, shape descriptors and
shape classes), ``seed``, ``version``; extras:
``bulk`` (the region every bulk figure uses), ``status``, ``warnings``. Undefined figures are
``nan`` here and ``null`` in the file. Each quantity's key holds its ``to_dict()``.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from granpack.analysis._base import AnalysisWarning
from granpack.analysis.coordination import Coordination
from granpack.analysis.grain_shapes import GrainShapes
from granpack.analysis.balance import Equilibrium
from granpack.analysis.homogeneity import Homogeneity
from granpack.analysis.interpenetration import Interpenetration
from granpack.analysis.order import Order
from granpack.analysis.pair_correlation import PairCorrelation
from granpack.analysis.size_classes import SizeClasses
from granpack.analysis.solid_fraction import SolidFraction
from granpack.analysis.wall_forces import WallForces
from granpack.analysis.wall_profile import WallProfile
from granpack.equilibrium import EquilibriumCriteria, criteria_of
from granpack.errors import InputError
from granpack.io.gsd import read_packing, shape_spec
from granpack.io.json import write_json
from granpack.io.run_folder import ANALYSIS_FILE, CONFIG_FILE, FINAL_FILE
from granpack.packing import Packing

__all__ = ["AnalysisOptions", "analyze_packing", "analyze_run", "summary_rows"]


@dataclass(frozen=True)
class AnalysisOptions:
    """Settings of :func:`analyze_packing` (lengths in units of the largest grain size d).

    Attributes:
        n_bottom: bulk starts ``n_bottom d`` above the wall.
        n_top: bulk ends ``n_top d`` below the free surface.
        slice_thickness: solid-fraction profile slices.
        layer_thickness: homogeneity layers.
        rdf_bin_width: g(r) bin width.
        rdf_r_max: largest g(r) distance (capped at half the lateral period).
        rdf_partials: also compute the partial g_ab(r).
        force_tol: relative threshold of force-bearing contacts.
        point_tol: relative threshold of force-bearing points within a contact; the contact type
            is the rank of those points.
        gap_tol: gap tolerance of the cross-check contact types, in d.
        rank_tol: rank tolerance of the contact types, in units of the smallest grain size.
        friction: the Coulomb coefficient μ >= 0 the coordination rules assume (frictional rules
            when positive); None: the packing's own (:attr:`~granpack.packing.Packing.friction`,
            its run's ``solver.friction``).
        slide_tol: a contact of a frictional packing slides when its resultant is within this
            share of the Coulomb cone (:func:`~granpack.analysis.coordination.mobilisation`).
        criteria: equilibrium tolerances; None: those of the run (:func:`analyze_run`, from the
            run's ``[equilibrium]`` settings), else the defaults of
            :class:`~granpack.equilibrium.EquilibriumCriteria`.
        sieves: sieve sizes (d) of the size classes of a packing of several sizes; default
            :data:`~granpack.analysis.size_classes.DEFAULT_CLASSES` classes from the smallest to
            the largest grain.
        n_wall: in a box or a cylinder, the bulk figures (solid fraction, coordination, order,
            g(r)) are those of the core, ``n_wall d`` from the side walls (0: the whole section;
            ignored in a periodic cell); g(r) then reaches ``min(rdf_r_max, n_wall)``.
        wall_bin_width: shells of the solid-fraction profile against the distance from the side
            walls (``wall_profile``, a container's packing only).
        wall_grain_bin_width: shells of the profiles over grain centres (coordination, order).
        wall_force_bin_height: depth bins of the walls' forces and the vertical stress (``walls``,
            a container's packing only), in d.
    """

    n_bottom: float = 2.0
    n_top: float = 2.0
    slice_thickness: float = 0.1
    layer_thickness: float = 1.0
    rdf_bin_width: float = 0.02
    rdf_r_max: float = 4.0
    rdf_partials: bool = False
    force_tol: float = 1e-9
    point_tol: float = 1e-3
    sieves: tuple[float, ...] | None = None
    gap_tol: float = 1e-4
    rank_tol: float = 1e-3
    friction: float | None = None
    slide_tol: float = 1e-3
    criteria: EquilibriumCriteria | None = None
    n_wall: float = 2.0
    wall_bin_width: float = 0.05
    wall_grain_bin_width: float = 0.25
    wall_force_bin_height: float = 1.0


#: the order figures of a population, and of a shape class (without the isotropic baseline)
_POPULATION_ORDER = ("Q00", "Q22", "n_analysed", "isotropic_baseline")
_CLASS_ORDER = ("Q00", "Q22", "n_analysed")


def _order_of(packing: Packing, keys: tuple[str, ...], **selection) -> dict:
    """The ``keys`` of :meth:`Order.to_dict` over the bulk grains of a population or shape class
    (``selection``: the :class:`Order` arguments that select them)."""
    figures = Order(**selection).compute(packing).to_dict()
    return {k: figures[k] for k in keys}


def _populations(packing: Packing, co: Coordination, grain_shapes: GrainShapes, z_range, n_wall: float) -> list[dict]:
    """One row per population: its grains and shapes, and over its bulk grains the coordination
    (:meth:`Coordination.figures_of`), order and shape descriptors, also per shape class."""
    state = packing.state
    total = state.mass.sum()
    out = []
    for a, name in enumerate(packing.population_names):
        members = state.population == a
        kinds = np.unique(state.kind[members])
        shapes = [state.shapes.shapes[k] for k in kinds]
        # a graded population: its grains' one shape at size 1 and their range of sizes
        bases = {id(s.scale_of[0]): s.scale_of[0] for s in shapes if getattr(s, "scale_of", None) is not None}
        sizes = 2.0 * state.radius[members]
        row = {
            "name": name,
            "n": int(members.sum()),
            "volume_fraction": float(state.mass[members].sum() / total) if total > 0 else math.nan,
            "shapes": [shape_spec(s) for s in (bases.values() if bases else shapes)],
        }
        if len(kinds) > 1 and len(sizes):
            row["sizes"] = {"min": float(sizes.min()), "max": float(sizes.max()), "mean": float(sizes.mean())}
        row["coordination"] = co.figures_of(members)
        row["order"] = _order_of(packing, _POPULATION_ORDER, z_range=z_range, population=a, n_wall=n_wall)
        row["shape_descriptors"] = grain_shapes.summary(members)
        row["shape_classes"] = [
            {"shape": c["shape"], "n": int(c["grains"].sum()),
             **{k: c[k] for k in ("elongation", "flatness", "sphericity", "convexity")},
             "coordination": co.figures_of(c["grains"]),
             "order": _order_of(packing, _CLASS_ORDER, z_range=z_range, grains=c["grains"], n_wall=n_wall)}
            for c in grain_shapes.classes[a]["classes"]]
        out.append(row)
    return out


#: analyses restricted to the bulk region
_BULK_KEYS = ("coordination", "order", "pair_correlation", "homogeneity")


def _compute(packing: Packing, opt: AnalysisOptions) -> tuple[SolidFraction, tuple[float, float], dict]:
    """The solid fraction, its bulk region ``(z_bottom, z_top)`` (empty without one) that every
    bulk figure reads, and the quantities computed over that region, by their key of
    ``analysis.json``; their warnings silenced (:func:`analyze_packing` says them once, with their
    key)."""
    box = packing.box
    core = 0.0 if box.periodic else opt.n_wall  # a container's bulk figures are its core's
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sf = SolidFraction(opt.slice_thickness, opt.n_bottom, opt.n_top, n_wall=core).compute(packing)
        z_range = (sf.z_bottom, sf.z_top) if sf.has_bulk else (0.0, 0.0)
        r_max = min(opt.rdf_r_max, 0.5 * min(box.lx, box.ly))
        if core > 0:
            r_max = min(opt.rdf_r_max, core * (packing.max_size if packing.n_particles else 1.0))
        bins = max(int(round(r_max / opt.rdf_bin_width)), 1)

        def coordination(n_wall: float) -> Coordination:
            return Coordination(z_range, opt.force_tol, point_tol=opt.point_tol, gap_tol=opt.gap_tol,
                                rank_tol=opt.rank_tol, friction=opt.friction, slide_tol=opt.slide_tol,
                                n_wall=n_wall).compute(packing)

        computed = {
            "coordination": coordination(core),
            "order": Order(z_range, n_wall=core).compute(packing),
            "pair_correlation": PairCorrelation(bins, r_max, z_range, partials=opt.rdf_partials,
                                                n_wall=core).compute(packing),
            "equilibrium": Equilibrium(opt.criteria).compute(packing),
            "interpenetration": Interpenetration(opt.n_bottom).compute(packing),
            "homogeneity": Homogeneity(opt.layer_thickness, z_range).compute(packing),
        }
        if not box.periodic:  # the profiles read the backbone of the whole slab
            slab = computed["coordination"] if core == 0 else coordination(0.0)
            computed["wall_profile"] = WallProfile(z_range, opt.wall_bin_width, opt.wall_grain_bin_width,
                                                   coordination=slab).compute(packing)
            computed["walls"] = WallForces(opt.wall_force_bin_height, z_surface=sf.z_surface).compute(packing)
    return sf, z_range, computed


def analyze_packing(packing: Packing, options: AnalysisOptions | None = None) -> dict:
    """Every analysis of ``packing`` as a dict (profiles as NumPy arrays, nan for undefined figures).

    Each quantity gives its own part (its ``to_dict()``); this function computes them over one bulk
    region, gathers their warnings, and adds the parts no single quantity owns: the packing's
    identity (``version``, ``n_particles``, ``seed``, ``status``) and the ``populations`` rows.
    :func:`granpack.io.json.write_json` turns it into strict JSON (arrays to lists, nan to null).

    A packing too thin for a bulk region, without contacts, or with a single grain yields
    warnings (also listed under ``warnings``) and nan bulk figures, never an exception.
    """
    from granpack import __version__

    opt = options or AnalysisOptions()
    sf, z_range, computed = _compute(packing, opt)
    messages: list[str] = []
    if sf.has_bulk:
        messages += [f"solid_fraction: {m}" for m in sf.warnings]
    else:  # one message says why every bulk figure is nan
        messages.append(f"{sf.no_bulk_reason}: every bulk figure (solid fraction, "
                        f"{', '.join(_BULK_KEYS).replace('_', ' ')}) is nan")
    for key, obj in computed.items():
        if sf.has_bulk or key not in _BULK_KEYS + ("wall_profile",):
            messages += [f"{key}: {m}" for m in obj.warnings]
    for m in messages:
        warnings.warn(m, AnalysisWarning, stacklevel=2)

    co = computed["coordination"]
    grain_shapes = GrainShapes().compute(packing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a population's or class's nan figures: the whole packing's warnings say why
        populations = _populations(packing, co, grain_shapes, z_range, 0.0 if packing.box.periodic else opt.n_wall)
    sizes = 2.0 * packing.state.radius
    several_sizes = packing.n_particles > 0 and sizes.max() > sizes.min() * (1 + 1e-9)
    if several_sizes:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            classes = SizeClasses(opt.sieves, opt.layer_thickness, z_range, coordination=co).compute(packing)
        messages += [f"size_classes: {m}" for m in classes.warnings]
    return {
        "version": __version__,
        "n_particles": packing.n_particles,
        "populations": populations,
        "seed": packing.seed,
        "status": packing.metadata.get("status"),
        "bulk": sf.region_to_dict(),
        "solid_fraction": sf.to_dict(expansion_k=computed["interpenetration"].expansion_k),
        "coordination": co.to_dict(),
        "order": computed["order"].to_dict(),
        "pair_correlation": computed["pair_correlation"].to_dict(),
        "grain_shapes": grain_shapes.to_dict(),
        "equilibrium": computed["equilibrium"].to_dict(),
        "interpenetration": computed["interpenetration"].to_dict(),
        "homogeneity": computed["homogeneity"].to_dict(),
        **({"wall_profile": computed["wall_profile"].to_dict()} if "wall_profile" in computed else {}),
        **({"walls": computed["walls"].to_dict()} if "walls" in computed else {}),
        **({"size_classes": classes.to_dict()} if several_sizes else {}),
        "warnings": messages,
    }


def analyze_run(run_dir: str | os.PathLike, options: AnalysisOptions | None = None) -> dict:
    """Analyse ``run_dir/final.gsd`` and write ``run_dir/analysis.json`` atomically.

    The packing's equilibrium is judged by the run's own criteria (its ``config.toml``'s
    ``[equilibrium]`` table, :func:`~granpack.equilibrium.criteria_of`) unless ``options`` gives
    others, so that a run certified by looser criteria reads as it was certified.

    Raises:
        InputError: ``run_dir`` is not a folder, or ``final.gsd`` is missing or unreadable.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: not a run folder")
    options = options or AnalysisOptions()
    if options.criteria is None:
        options = replace(options, criteria=_run_criteria(run_dir))
    result = analyze_packing(read_packing(run_dir / FINAL_FILE), options)
    write_json(run_dir / ANALYSIS_FILE, result)
    return result


def _run_criteria(run_dir: Path) -> EquilibriumCriteria:
    """The equilibrium criteria of the run in ``run_dir``: its resolved ``config.toml``'s
    ``[equilibrium]`` table, or the defaults where the folder has no config (a packing written by
    other means)."""
    import tomllib

    from granpack.config import EquilibriumConfig

    path = run_dir / CONFIG_FILE
    if not path.is_file():
        return EquilibriumCriteria()
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8")).get("equilibrium", {})
        return criteria_of(EquilibriumConfig.model_validate(table))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the run's [equilibrium] settings ({exc})") from None


def _bulk_region(bulk: dict, fmt) -> str:
    """``z_bottom .. z_top``, or ``none (surface at ... d)`` when there is no bulk region."""
    if bulk.get("valid"):
        return f"{fmt(bulk['z_bottom'], '.2f')} .. {fmt(bulk['z_top'], '.2f')}"
    return f"none (surface at {fmt(bulk.get('z_surface'), '.2f')} d)"


def _wall_rows(walls: dict | None, fmt) -> list[tuple[str, str]]:
    """The weight the floor and the side walls carry, and the fit of Janssen's law (a container's)."""
    if not walls:
        return []
    rows = [("weight on the floor / the side walls",
             f"{fmt(walls['floor_vertical'])} / {fmt(walls['side_vertical'])} W; side walls' normal force "
             f"{fmt(walls['side_normal'])} W")]
    fit = walls["janssen"]
    if fit["K"] is not None and math.isfinite(fit["K"]):
        rows.append((f"Janssen fit (μ_w = {walls['wall_friction']:g})",
                     f"K = {fmt(fit['K'], '.3f')}, σ∞ = {fmt(fit['saturation_stress'], '.3g')} ρgd, "
                     f"λ = {fmt(fit['length'], '.3g')} d; K at the wall {fmt(fit['K_wall'], '.3f')}"))
    return rows


def summary_rows(result: dict) -> list[tuple[str, str]]:
    """Headline figures of an :func:`analyze_packing` result as ``(label, formatted value)`` rows."""

    def fmt(value, spec: str = ".4f") -> str:
        if value is None or (isinstance(value, float) and not math.isfinite(value)):
            return "n/a"
        return format(value, spec)

    sf, co, order = result["solid_fraction"], result["coordination"], result["order"]
    eq, ip = result["equilibrium"], result["interpenetration"]
    frictional = co.get("frictional")
    rule = f"frictional rule, μ = {frictional['mu']:g}" if frictional else "frictionless rule"
    wall = result.get("wall_profile")
    core = f"core, {result['bulk'].get('n_wall', 0):g} d from the walls" if wall else "bulk"
    rows = [
        ("grains", str(result["n_particles"])),
        ("bulk region z/d", _bulk_region(result["bulk"], fmt)),
        (f"solid fraction ({core})", f"{fmt(sf['bulk'])} ± {fmt(sf['std'])}"),
        (f"N / Nc (backbone, {rule})", f"{fmt(co['N'], '.3f')} / {fmt(co['Nc'], '.3f')}"),
        ("Ns / Nd / Nt", f"{fmt(co['Ns'], '.3f')} / {fmt(co['Nd'], '.3f')} / {fmt(co['Nt'], '.3f')}"),
        (f"rattler fraction ({rule})", fmt(co["rattler_fraction"], ".3f")),
    ]
    if frictional:
        rows += [
            ("constraints per grain (isostatic)",
             f"{fmt(frictional['constraints_per_grain'], '.3f')} ({fmt(frictional['isostatic_constraints'], 'g')}); "
             f"hyperstaticity {fmt(frictional['hyperstaticity'], '.3f')}"),
            (f"sliding contacts (|F_T| ≥ (1 - {frictional['slide_tol']:g}) μ F_n)",
             f"{fmt(frictional['sliding_fraction'], '.4f')}; mean |F_T|/(μ F_n) {fmt(frictional['mean_mobilisation'], '.3f')}"),
        ]
    for key, label in (("gap_rule", "gap rule"), ("geometric", "detection types")):
        other = co.get(key)
        if other is not None:
            rows.append((f"Ns / Nd / Nt / Nc ({label})", " / ".join(fmt(other[k], ".3f") for k in ("Ns", "Nd", "Nt", "Nc"))))
    if wall:
        rows.append((f"solid fraction (whole {wall['container']} section)", fmt(wall["section_solid_fraction"])))
    rows += _wall_rows(result.get("walls"), fmt)
    rows += [
        ("Q00 / Q22", f"{fmt(order['Q00'])} / {fmt(order['Q22'])} (axis {order['director_axis'] or '-'})"),
        (
            "isotropic baseline Q00 / Q22",
            f"{fmt(order['isotropic_baseline']['Q00'])} / {fmt(order['isotropic_baseline']['Q22'])}",
        ),
        ("max |F|/(d²P), |T|/(d³P)", f"{fmt(eq['max_net_force'], '.2e')}, {fmt(eq['max_net_torque'], '.2e')}"),
        ("max E/(d³P)", fmt(eq["kinetic_energy"], ".2e")),
        ("wall force / weight", fmt(eq["wall_force_over_weight"], ".6f")),
        ("equilibrium", "yes" if eq["passed"] else "no"),
        ("overlap max / mean (d)", f"{fmt(ip['max'], '.2e')} / {fmt(ip['mean'], '.2e')}"),
        ("expansion k", fmt(ip["expansion_k"], ".2e")),
    ]
    for name, share in result["homogeneity"]["bulk_mean"].items():
        rows.append((f"volume share {name} (bulk)", fmt(share, ".3f")))
    return rows
