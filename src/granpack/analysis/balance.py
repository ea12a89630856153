"""The balance of a packing: its equilibrium figures (the criteria: :mod:`granpack.equilibrium`).

Reports the worst normalised net force :math:`|F_p|/(d_p^2 P_p)`, net torque
:math:`|T_p|/(d_p^3 P_p)`, kinetic energy :math:`E_p/(d_p^3 \\bar P)` and the wall force over the
weight, as defined in :mod:`granpack.equilibrium` (docs/method/equilibrium.md), over all grains.
"""

from __future__ import annotations

from granpack.analysis._base import Compute, result
from granpack.equilibrium import EquilibriumCriteria, EquilibriumFields, EquilibriumReport, equilibrium_fields, report_from_fields
from granpack.packing import Packing

__all__ = ["Equilibrium"]


class Equilibrium(Compute):
    """Mechanical equilibrium of a packing.

    Args:
        criteria: tolerances (defaults of :class:`~granpack.equilibrium.EquilibriumCriteria`).
    """

    def __init__(self, criteria: EquilibriumCriteria | None = None):
        self.criteria = criteria or EquilibriumCriteria()

    def compute(self, packing: Packing) -> "Equilibrium":
        """Evaluate the criteria on ``packing``."""
        self._start()
        self._fields = equilibrium_fields(
            packing.state, packing.contacts, packing.time_step, gravity=packing.gravity, criteria=self.criteria
        )
        self._report = report_from_fields(self._fields, self.criteria)
        if packing.contacts.n_manifolds == 0:
            self._warn("no contact: the packing cannot be in equilibrium (normalised figures are inf)")
        return self._done()

    @result
    def report(self) -> EquilibriumReport:
        """The verdicts and worst values."""
        return self._report

    @result
    def fields(self) -> EquilibriumFields:
        """Per-grain forces, torques, energies, pressures and ratios."""
        return self._fields

    @result
    def figures(self) -> dict:
        """``{max_net_force, max_net_torque, kinetic_energy, wall_force_over_weight}`` plus the verdicts."""
        return self._report.as_dict()

    @result
    def passed(self) -> bool:
        """True when all criteria hold."""
        return self._report.passed

    def to_dict(self) -> dict:
        """The ``equilibrium`` part of ``analysis.json``:
        :attr:`~granpack.analysis.balance.Equilibrium.figures`."""
        return self.figures
