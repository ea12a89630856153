"""Non-Smooth Contact Dynamics: the Moreau–Jean θ-scheme with a matrix-free NLGS solver.

- :mod:`~granpack.nscd.rigid`: rigid-body kinematics (free velocities, predicted configuration,
  update, world inverse inertia, energies, the alert distance a step needs).
- :mod:`~granpack.nscd.problem`: the assembled contact problem of a step (:class:`ContactProblem`).
- :mod:`~granpack.nscd.nlgs`: the NLGS solver ``solve(problem, options) -> (impulses, info)``.
- :mod:`~granpack.nscd.warmstart`: impulses carried over from the previous step.
- :mod:`~granpack.nscd.integrator`: ``step(state, params, warm) -> (contacts, StepInfo)``.
- :mod:`~granpack.nscd.step_policy`: the alert distance, the substeps and each grain's reach of
  the next step.
"""

from __future__ import annotations

from granpack.nscd.integrator import CORRECTED_OVERLAP, Prediction, StepInfo, StepParameters, advance, predict, step
from granpack.nscd.nlgs import NLGSOptions, SolverInfo, solve
from granpack.nscd.problem import ContactProblem, assemble, tangent_frame
from granpack.nscd.rigid import kinetic_energy, potential_energy, required_alert, total_energy, world_inverse_inertia

__all__ = [
    "CORRECTED_OVERLAP",
    "step",
    "predict",
    "advance",
    "Prediction",
    "StepParameters",
    "StepInfo",
    "ContactProblem",
    "assemble",
    "tangent_frame",
    "NLGSOptions",
    "SolverInfo",
    "solve",
    "kinetic_energy",
    "potential_energy",
    "total_energy",
    "world_inverse_inertia",
    "required_alert",
]
