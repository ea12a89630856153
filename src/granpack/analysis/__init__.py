"""Analysis of a static packing: one module per quantity, each a compute object.

``Quantity(options).compute(packing)`` returns the object; results are read-only properties that
raise :class:`NotComputedError` before ``compute``; ``to_dict()`` is the quantity's part of
``analysis.json``, which :func:`analyze_packing` / :func:`analyze_run` assemble. The quantities
with a figure (solid fraction, g(r), homogeneity, size classes, wall profile, walls' forces) draw it with ``.plot(ax)`` through
a pyplot-free function of their module, the one that ``granpack figures`` calls with the part read
from the file (:mod:`granpack.figures`): one implementation of each figure.
"""

from __future__ import annotations

from granpack.analysis._base import AnalysisWarning, NotComputedError
from granpack.analysis.coordination import Coordination
from granpack.analysis.balance import Equilibrium
from granpack.analysis.fit import ExponentialFit
from granpack.analysis.grain_shapes import GrainShapes
from granpack.analysis.homogeneity import Homogeneity
from granpack.analysis.interpenetration import Interpenetration
from granpack.analysis.order import Order
from granpack.analysis.pair_correlation import PairCorrelation
from granpack.analysis.report import AnalysisOptions, analyze_packing, analyze_run
from granpack.analysis.solid_fraction import SolidFraction
from granpack.analysis.wall_forces import WallForces
from granpack.analysis.wall_profile import WallProfile

__all__ = [
    "AnalysisOptions",
    "AnalysisWarning",
    "Coordination",
    "Equilibrium",
    "ExponentialFit",
    "GrainShapes",
    "Homogeneity",
    "Interpenetration",
    "NotComputedError",
    "Order",
    "PairCorrelation",
    "SolidFraction",
    "WallForces",
    "WallProfile",
    "analyze_packing",
    "analyze_run",
]
