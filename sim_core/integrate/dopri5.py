"""The Dormand–Prince 5(4) tableau (DOPRI5, RK45): the integrator's short step.

Coefficients from Dormand & Prince, "A family of embedded Runge–Kutta formulae",
J. Comp. Appl. Math. 6 (1980), as SciPy lists them (scipy/integrate/_ivp/rk.py,
``RK45``, BSD-3-Clause, Copyright (c) 2001-2002 Enthought, Inc. and 2003-2024
SciPy Developers). Seven stages, the seventh at the new point (first same as
last): six new right-hand sides per step against DOP853's twelve.

railtwin takes this step where the constraint's breakpoints (kinks, curvature
jumps) cut a contact step far below what DOP853's controller allows
(``sim_core.integrate.loop``): there h·ω is about 0.01 and a 5th-order step's error,
~(h·ω)⁶ of the motion, is far below any tolerance the passage asks for, so its
half-price stages are all that is needed. Its embedded 4th-order solution gives
its own error estimate, and the dense output (a septic Hermite polynomial from
both ends) does not depend on which pair produced the end state.

Worked example: the weights integrate a polynomial of degree 4 exactly (order 5),

    >>> [round(float(B @ C[:6] ** k) * (k + 1), 12) for k in range(5)]
    [1.0, 1.0, 1.0, 1.0, 1.0]
    >>> abs(float(E.sum())) < 1e-15
    True
"""

import numpy as np

N_STAGES = 6
"""Stages evaluated inside a step (the seventh is the end point, reused as the next first)."""

C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
"""Stage times as fractions of the step (the last: the new point)."""

A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1 / 5, 0.0, 0.0, 0.0, 0.0, 0.0],
        [3 / 40, 9 / 40, 0.0, 0.0, 0.0, 0.0],
        [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0, 0.0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0, 0.0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0.0],
        [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    ]
)
"""Stage coefficients; row 6 (the new point) is the 5th-order solution's weights."""

B = A[6].copy()
"""The 5th-order weights (stages 0..5; the seventh stage has weight 0)."""

E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
"""The error estimator: the 5th-order minus the embedded 4th-order weights, over all 7 stages."""
