"""Explicit Runge–Kutta tableaus as data: what drives the one compiled step (``step.rk_step``).

A ``Tableau`` holds a method's stage coefficients a, weights b, stage times c and error
weights, as diffrax holds its ``ButcherTableau``: the step is written once, and DOP853 and
DOPRI5 are two values of it. The integrator's stage matrix K has ``END + 1`` rows; rows
0 … s−1 are a method's s stages and row ``END`` is the derivative at the new point (the
first same as last: the next step's row 0). The error weights run over all those rows
(zero where a method has no stage), with two of them for a method whose norm mixes two
estimators (DOP853's 5th- and 3rd-order ones, as Hairer's code and SciPy do):

    err = |h|·e₅² / sqrt((e₅² + 0.01·e₃²)·n)   (with e₃ ≡ 0: |h|·sqrt(e₅²/n), DOPRI5's norm).

Worked example (both tableaus integrate polynomials to their order, from the same data):

    >>> import numpy as np
    >>> [bool(abs(float(t.b @ t.c[: t.stages] ** (t.order - 1)) * t.order - 1) < 1e-12)
    ...  for t in (DOP853, DOPRI5)]
    [True, True]
    >>> DOP853.stages, DOPRI5.stages, DOPRI5.compiled().error_rows.tolist()
    (12, 6, [0, 2, 3, 4, 5, 12])
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sim_core.integrate import dop853, dopri5

END = 12
"""The row of the stage matrix holding the derivative at the step's end."""


class Stages(NamedTuple):
    """A tableau as the compiled step reads it (every tableau the same types: one compilation)."""

    a: NDArray[np.float64]
    """(END + 1, END): row s, the coefficients of stage s on the earlier stages."""
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    """(END + 1,): stage times as fractions of the step; c[END] = 1, the end point."""
    e_high: NDArray[np.float64]
    """(END + 1,): the main error estimator over the stage rows."""
    e_low: NDArray[np.float64]
    """(END + 1,): the second estimator mixed into the norm (zeros: none)."""
    error_rows: NDArray[np.int64]
    """The rows either estimator weighs (rows a method leaves stale are never read)."""
    stages: int
    order: int


@dataclass(frozen=True)
class Tableau:
    """An explicit embedded Runge–Kutta method (see the module's docstring)."""

    name: str
    a: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    e_high: NDArray[np.float64]
    e_low: NDArray[np.float64]
    order: int

    @property
    def stages(self) -> int:
        return int(self.b.size)

    def __post_init__(self) -> None:
        s = self.stages
        if self.a.shape[0] < s or self.a.shape[1] < s - 1:
            raise ValueError(f"{self.name}: a is {self.a.shape}, needs {s} rows of {s - 1} stages")
        if self.c.size < s:
            raise ValueError(f"{self.name}: c has {self.c.size} times for {s} stages")
        if s > END or self.e_high.size != END + 1 or self.e_low.size != END + 1:
            raise ValueError(
                f"{self.name}: at most {END} stages, error weights over {END + 1} rows"
            )
        if abs(float(self.b.sum()) - 1.0) > 1e-12:
            raise ValueError(f"{self.name}: the weights b sum to {float(self.b.sum())!r}, not 1")

    def compiled(self) -> Stages:
        a = np.zeros((END + 1, END))
        a[: self.a.shape[0], : self.a.shape[1]] = self.a[:, :END]
        c = np.zeros(END + 1)
        c[: self.c.size] = self.c
        c[END] = 1.0  # the end point
        rows = np.flatnonzero((self.e_high != 0.0) | (self.e_low != 0.0)).astype(np.int64)
        return Stages(
            a,
            np.ascontiguousarray(self.b, dtype=np.float64),
            c,
            np.ascontiguousarray(self.e_high, dtype=np.float64),
            np.ascontiguousarray(self.e_low, dtype=np.float64),
            rows,
            self.stages,
            self.order,
        )


def _dopri5_errors() -> NDArray[np.float64]:
    """DOPRI5's error weights on the stage rows: stages 0..5, and its 7th (FSAL) on row END."""
    e = np.zeros(END + 1)
    e[:6] = dopri5.E[:6]
    e[END] = dopri5.E[6]
    return e


DOP853 = Tableau(
    "DOP853",
    dop853.A[: dop853.N_STAGES, : dop853.N_STAGES],
    dop853.B[: dop853.N_STAGES],
    dop853.C[: dop853.N_STAGES],
    dop853.E5,
    dop853.E3,
    8,
)
"""Dormand–Prince 8(5,3): twelve stages, the 5th- and 3rd-order error estimators."""

DOPRI5 = Tableau(
    "DOPRI5", dopri5.A[:6, :6], dopri5.B[:6], dopri5.C[:6], _dopri5_errors(), np.zeros(END + 1), 5
)
"""Dormand–Prince 5(4): six stages (the seventh is the end point), one error estimator."""
