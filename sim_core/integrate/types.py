"""What the compiled integrator is handed and what it hands back: typed named tuples and codes.

Two named tuples replace the long argument lists and the float vector that once
carried integer codes:

- ``Table``: the arrays of a ``ConstraintTable`` (nodes, values, one-sided
  slopes, contact points, stiffness scale) and its period;
- ``Params``: the passage's constants, the float ones as floats and the codes
  (contact law, foundation, dent tracking) as an int and bools.

Numba compiles a named tuple to a struct passed by value, so the compiled
functions read ``par.mass`` or ``tab.x`` at no cost. Build them with
``table_of`` and ``Params(...)`` (every field converted to its declared type,
so that one compiled signature serves every call).

One numbering of events (``Event``) serves the transition list, the event
functions and the root finder.

Worked example:

    >>> import numpy as np
    >>> from sim_core.constraint import flat_constraint
    >>> tab = table_of(flat_constraint())
    >>> tab.period > 0, tab.x.dtype == np.float64
    (True, True)
    >>> Event(0).name, [e.label for e in Event]
    ('LOSS', ['loss', 'contact', 'yield', 'unyield'])
"""

from __future__ import annotations

import functools
from enum import IntEnum
from typing import Literal, NamedTuple, cast, get_type_hints

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import ConstraintTable

kernel = numba.njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # _nrt: not in the stubs
"""The decorator of the integrator's compiled functions that allocate nothing.

Without the runtime's reference counting (``_nrt=False``): a compiled function
takes ownership of every array argument by an atomic increment on entry and a
decrement on exit, and a ``Table`` or ``Work`` carries six or seven arrays, so a
call cost ~30 atomic operations (a third of a passage's time, measured with
``perf``). A kernel borrows its arrays instead; it must not create or return one.

One compiled signature per kernel: numba types a constant argument (``EV_LOSS``,
``True``, ``200``) as its literal value and compiles the callee once more for each
value, as if it were a new function (``find_root`` was compiled six times, once per
event code). Call sites pass codes and flags as ``as_int(EV_LOSS)`` and
``as_bool(True)``, which are plain int64 and bool to the compiler (``python -m
benchmarks.compile_times`` lists each kernel's signatures).
"""


@numba.njit(cache=True, inline="always")
def as_int(x: int) -> int:
    """``x`` as a plain int64 to the compiler, not its literal value (see ``kernel``)."""
    return int(x)


@numba.njit(cache=True, inline="always")
def as_bool(x: bool) -> bool:
    """``x`` as a plain bool to the compiler, not its literal value (see ``kernel``)."""
    return bool(x)


TransitionKind = Literal["loss", "contact", "yield", "unyield"]
"""The name of a transition code (``Event.label``); ``schemas.result.TransitionKind`` is the
same set in the contract (``tests/test_transition_kinds.py``)."""


class Event(IntEnum):
    """A change of mode located by the integrator: the transition codes of ``PassageOutput``.

    Each has an event function g, signed so that the event is g going from <= 0 to > 0
    (``sim_core.integrate.events.event_value``).
    """

    LOSS = 0
    """δ falls through 0 (g = -δ)."""
    CONTACT = 1
    """δ rises through 0 (g = δ)."""
    YIELD = 2
    """δ rises through δ_Y + hysteresis (g = δ - δ_Y - hyst)."""
    UNYIELD = 3
    """δ falls through δ_Y - hysteresis (g = δ_Y - hyst - δ)."""

    @property
    def label(self) -> TransitionKind:
        return cast(TransitionKind, self.name.lower())


# The same codes as plain ints for the compiled code (an int compares and stores
# without the enum type in the way); NO_EVENT marks "none in this step".
EV_LOSS = int(Event.LOSS)
EV_CONTACT = int(Event.CONTACT)
EV_YIELD = int(Event.YIELD)
EV_UNYIELD = int(Event.UNYIELD)
NO_EVENT = -1

# Other functions the root finder locates zeros of (continuing the event codes).
F_RATE = 4
"""dδ/dt: its sign changes are extrema of δ."""
F_FORCE_RATE = 5
"""q = 1.5·σ·dδ/dt + V·σ'·δ, the sign of dF/dt with a stiffness scale σ(x)."""

# Modes: the branch of the right-hand side in force during a step.
FLIGHT = 0
ELASTIC = 1
PLASTIC = 2
MODE_NAMES = ("flight", "elastic", "plastic")

# Status codes.
OK = 0
STEP_TOO_SMALL = 1
TOO_MANY_STEPS = 2

# Why the loop returned: done (its status says how), or a buffer is full.
LOOP_DONE = 0
LOOP_NEED_TRANSITIONS = 1
LOOP_NEED_DENTS = 2

# Sample columns.
S_T = 0
S_X = 1
S_YC = 2
S_VC = 3
S_YM = 4
S_VM = 5
S_YCK = 6
S_DELTA = 7
S_FORCE = 8
S_CONTACT = 9
N_COLS = 10

# Extrema vector (taken from the continuous solution).
X_PEAK_DELTA = 0
X_MIN_DELTA = 1
X_T_FLIGHT = 2
X_PEAK_FORCE = 3
X_MIN_FORCE = 4
N_EXTREMA = 5


class Table(NamedTuple):
    """The constraint table as the compiled code reads it (see ``ConstraintTable``)."""

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    slope_left: NDArray[np.float64]
    slope_right: NDArray[np.float64]
    contact_x: NDArray[np.float64]
    scale: NDArray[np.float64]
    """Empty, or C(x)/C per node (linear between nodes)."""
    period: float


def table_of(table: ConstraintTable) -> Table:
    """The compiled view of ``table`` (contiguous float64 arrays, float period)."""

    def arr(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.ascontiguousarray(a, dtype=np.float64)

    return Table(
        arr(table.x),
        arr(table.y),
        arr(table.slope_left),
        arr(table.slope_right),
        arr(table.contact_x),
        arr(table.stiffness_scale),
        float(table.period),
    )


class Params(NamedTuple):
    """The constants of one passage (SI units)."""

    # contact law (MODEL.md §3)
    law: int
    """``contact_laws.HERTZ``, ``JOHNSON`` or ``HERTZ_PLASTIC``."""
    c: float
    f_y: float
    d_y: float
    theta: float
    hyst: float
    """Width of the elastic/plastic switch's hysteresis (m)."""
    # bodies (MODEL.md §4)
    mass: float
    load: float
    speed: float
    compliant: bool
    f_mass: float
    """Foundation mass (1 when rigid, unused)."""
    f_stiff: float
    f_damp: float
    # accuracy and resolution
    rtol: float
    atol_y: float
    atol_v: float
    hmax_contact: float
    """Longest step in contact (s)."""
    c2max: float
    """max |y_C^k''| of the table (1/m)."""
    # dent records (MODEL.md §5)
    track_dents: bool
    dent_dx: float

    @classmethod
    def build(cls, **kw: float | int | bool) -> Params:
        """Every field converted to its declared type (one compiled signature for all calls)."""
        out: dict[str, float | int | bool] = {}
        for name, kind in _param_kinds().items():
            out[name] = kind(kw.pop(name))
        if kw:
            raise TypeError(f"unknown parameters {sorted(kw)}")
        return cls(**out)  # type: ignore[arg-type]


@functools.cache
def _param_kinds() -> dict[str, type]:
    """Each ``Params`` field's declared type (the annotations are strings until resolved)."""
    hints = get_type_hints(Params)
    return {name: hints[name] for name in Params._fields}


class Work(NamedTuple):
    """The integrator's scratch arrays, allocated once per passage."""

    K: NDArray[np.float64]
    """[13, 4] stage derivatives (v_C, a_C, v_M, a_M) of the current step."""
    dstage: NDArray[np.float64]
    """[13] δ at each stage (NaN in flight)."""
    tmp: NDArray[np.float64]
    """[4] the state at a stage."""
    ynew: NDArray[np.float64]
    """[4] the state at the step's end."""
    coef: NDArray[np.float64]
    """[2, 8] the step's dense output (``sim_core.integrate.dense``)."""
    stack_s: NDArray[np.float64]
    """[128] the flight scan's bisection stack: fractions ..."""
    stack_g: NDArray[np.float64]
    """[128] ... and δ there."""


class LoopState(NamedTuple):
    """Where the integrator's loop stands: what it hands back when it stops to be given room.

    The loop allocates nothing (it is compiled without reference counting); when a
    buffer (transitions, dents) is full it returns this, is handed a larger buffer and
    resumes from it. Every field is a scalar, so it is passed by value.
    """

    t: float
    h: float
    """The next step's size: DOP853's proposal, capped on the approach of a loss."""
    h_control: float
    """DOP853's proposal itself (a step cut below it may take the short pair)."""
    h_short: float
    """The longest step the short pair (DOPRI5) is trusted with, from its last error."""
    mode: int
    kp: int
    """The next kink's index."""
    jp: int
    """The next curvature jump's index."""
    si: int
    """The next sample's index."""
    hint: int
    sample_hint: int
    """The samples' own look-up hint: they advance monotonically, where the step's
    look-ups end ahead of them (a shared hint made the first sample of a step bisect)."""
    j0c: float
    """The jerks at t (wheel, foundation)."""
    j0m: float
    steps: int
    rejected: int
    rhs_evaluations: int
    n_tr: int
    """Rows of the transition buffer used."""
    n_dent: int
    """Rows of the dent buffer used."""
    status: int


class Result(NamedTuple):
    """What ``integrator.integrate`` returns."""

    status: int
    """``OK``, ``STEP_TOO_SMALL`` or ``TOO_MANY_STEPS``."""
    t_end: float
    """The time reached (``t1`` unless it failed)."""
    mode_end: int
    """The mode there."""
    samples: NDArray[np.float64]
    """[n, N_COLS] at the requested times."""
    transitions: NDArray[np.float64]
    """[m, 2] rows (t, ``Event`` code)."""
    extrema: NDArray[np.float64]
    """[N_EXTREMA] indexed by X_*: peak δ, least δ in contact, time out of contact,
    peak force, least force in contact (on the loading branch)."""
    dents: NDArray[np.float64]
    """[k, 3] rows (t, x_D, δ) taken while plastic."""
    steps: int
    rejected: int
    rhs_evaluations: int
    y_end: NDArray[np.float64]
    """The final state (y_C, v_C, y_M, v_M)."""
