"""The exact rigid constraint y_C^k(x_C) of MODEL.md §2, one module per method.

The public API (everything a caller needs) is re-exported here:

- :func:`tabulate_constraint`: the table of any wheel on any rail (it picks the method);
- :func:`evaluate_exact`: the general ψ-search at isolated points (no table);
- :func:`flat_constraint`, :func:`profile_constraint`: the trivial tables;
- :func:`curvature_stiffness_scale`: the curvature-dependent Hertz factor per node;
- :func:`amplitude_spectrum`: harmonic amplitudes of a table;
- :func:`warm_up_constraint`: compile every path before the first wheel;
- :class:`ConstraintTable`: the table and (in :mod:`sim_core.constraint.table`) its
  compiled look-up.

Worked example: a round wheel on a flat rail never leaves y = 0:

    >>> import numpy as np
    >>> from sim_core.rail import RailProfile
    >>> from sim_core.wheel import WheelOutline
    >>> t = tabulate_constraint(WheelOutline.round(0.46), RailProfile.flat(), 0.0, 1.0)
    >>> float(t.evaluate(np.array([0.3]))[0])
    0.0
"""

from sim_core.constraint.flat_rail import flat_constraint
from sim_core.constraint.general import evaluate_exact
from sim_core.constraint.profile import profile_constraint
from sim_core.constraint.spectrum import amplitude_spectrum
from sim_core.constraint.stiffness import curvature_stiffness_scale
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.tabulate import tabulate_constraint
from sim_core.constraint.warm_up import warm_up_constraint

__all__ = [
    "ConstraintTable",
    "amplitude_spectrum",
    "curvature_stiffness_scale",
    "evaluate_exact",
    "flat_constraint",
    "profile_constraint",
    "tabulate_constraint",
    "warm_up_constraint",
]
