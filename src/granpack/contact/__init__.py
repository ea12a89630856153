"""Contact detection: broad phase (cell grid, Verlet list), narrow phase (manifolds per shape pair).

The public entry points are :func:`detect` and :class:`Detector` (see :mod:`granpack.contact.detect`);
the output layout and its conventions are owned by :mod:`granpack.contact.contacts`.
"""

from granpack.contact.contacts import DOUBLE, SIMPLE, TRIPLE, WALL, ContactSet, contact_types
from granpack.contact.detect import Detector, detect

__all__ = ["ContactSet", "Detector", "detect", "contact_types", "SIMPLE", "DOUBLE", "TRIPLE", "WALL"]
