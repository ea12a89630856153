"""Geometric sequential deposition of spheres (the shells of the pluviation) in a vertical box.

Box (owned here for the deposit only): square cross-section ``[0, L] x [0, L]``, floor ``z = 0``,
open top, either lateral walls at ``x = 0, L`` and ``y = 0, L``, or periodic in x and y with
period ``L`` (then centres are returned wrapped into ``[0, L)``, as in :mod:`granpack.box`), or
a vertical cylinder of diameter ``L`` about ``(L/2, L/2)``, for the deposit the regular polygon of
64 vertical planes inscribed in it (:func:`~granpack.deposit.geometry.wall_table`).
Lengths are in the caller's unit (d in granpack). Gravity is ``-e_z``.

Two rules (docs/method/pluviation.md), both sequential: spheres are placed one by one in the
given order (the caller shuffles the populations), each where its supports ``k`` in contact hold
it under gravity,

.. math:: e_z = \\sum_k \\lambda_k n_k, \\qquad \\lambda_k \\ge 0,

with ``n_k`` the unit normal of support ``k`` (an earlier sphere, the floor or a wall) pointing
to the centre, and overlapping nothing by more than ``1e-9 d`` (d the largest diameter).

``method="drop"`` (Visscher & Bolsterli 1972): each sphere is released above the pile at a
uniformly random ``(x, y)`` and follows the quasi-static steepest descent of its height (fall,
roll on one support, roll on the circle of two) to where its supports hold it. Bulk solid
fraction of a monodisperse deposit in a periodic column: 0.581 (Visscher & Bolsterli: 0.582;
tests/test_deposit.py).

``method="lmgc"`` (LMGC90 ``depositInBox3D``): each sphere goes to the lowest position touching
three supports, the first one of the 100 most recent spheres with fewer than 8 contacts, among
the positions inside the box, free of overlap and held by their supports; where there is none
(the first spheres) it is dropped as with ``"drop"``. This gives a denser, layered deposit with
a nearly flat top.

Modules: :mod:`~granpack.deposit.sequential` (:func:`deposit` and the loop both rules share),
:mod:`~granpack.deposit.drop` and :mod:`~granpack.deposit.lmgc` (the placement of one sphere by
each rule), :mod:`~granpack.deposit.geometry` (supports, arcs, equilibrium on supports) and
:mod:`~granpack.deposit.grid` (cell grid of the deposited spheres).
"""

from granpack.deposit.sequential import deposit

__all__ = ["deposit"]
