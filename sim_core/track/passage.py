"""One wheel passage over a rail on discrete supports or a slab (MODEL.md §8), with its crib channels.

    m·ÿ_C = −P + F(δ),   δ = −y_C + y_C^k(x_C) + w(x_C, t)

with w the rail's deflection under the wheel centre, from the modal track
(``sim_core.track.modal``) advanced by the exact-mode stepper
(``sim_core.track.stepper``). Starts from the static equilibrium of wheel and
track with the wheel at x_C(t0), velocities zero (or the given initial
offsets of the wheel).

Worked example (a wheel standing on a slab track is pressed δ0 = (P/C)^(2/3)
into the rail, and the rail under it sinks by P/k_track):

    >>> import numpy as np
    >>> from sim_core.materials import Material, derive
    >>> from sim_core.contact_laws import ContactLaw, ContactModel
    >>> from sim_core.constraint import flat_constraint
    >>> from sim_core.passage import PassageSpec
    >>> from sim_core.track.spec import Crib, Support, TrackSpec
    >>> d = derive(Material(2.14e11, 0.3), radius=0.46, load=85000.0, mass=700.0)
    >>> track = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.3, pad=Support(6e7, 1.5e4))
    >>> spec = PassageSpec(mass=700.0, load=85000.0, speed=1.0, duration=0.01, sample_rate=1e3,
    ...                    contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient),
    ...                    foundation=track, cribs=(Crib("c1", -0.2, 0.2),))
    >>> out = simulate_on_track(flat_constraint(), spec, track)
    >>> round(float(out.delta[-1]) * 1e6, 1), round(float(out.channels["c1"][-1]) / 85000.0, 3)
    (86.1, 1.0)
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from sim_core.contact_laws import ContactLaw
from sim_core.integrate.types import table_of
from sim_core.track import stepper as st
from sim_core.track.lanes import aligned_zeros, padded_parts, padded_size
from sim_core.track.modal import ModalTrack, reduce_track
from sim_core.track.spec import TrackError, TrackSpec, check_cribs

if TYPE_CHECKING:
    from sim_core.constraint.table import ConstraintTable
    from sim_core.passage import PassageOutput, PassageSpec

STEP = 2.0e-5
"""Longest step, s: the contact force is linear in time over a step (convergence: docs/MODEL.md §8)."""

FEATURE_STEPS = 2.0
"""A step advances the wheel by at most this many of the constraint table's ``resolution``."""

KINK_FRACTION = 0.05
"""The step stops on a kink of the constraint whose slope jump Δs moves the constraint, over
a longest step, by more than this fraction of the static indentation: V·|Δs|·τ > f·δ0.

A rough rail's table has thousands of kinks where the wheel's contact passes from one
sample's crest to the next (|Δs| < 1e-3 on the site rail); a flat's corners jump by
~l/R. Stopping costs two sets of step coefficients (an exponential per mode)."""

MAX_TRANSITIONS = 100_000


def simulate_on_track(
    table: ConstraintTable,
    spec: PassageSpec,
    track: TrackSpec,
    *,
    model: ModalTrack | None = None,
    step: float = STEP,
    track_dents: bool | None = None,
    dent_spacing: float = 1e-4,
    max_steps: int = 50_000_000,
) -> PassageOutput:
    """Simulate one passage of ``spec`` over ``table`` on ``track``; ``spec.cribs`` get channels.

    Raises ``IntegrationError`` past ``max_steps`` steps or ``MAX_TRANSITIONS`` transitions.
    """
    from sim_core.passage import (
        TRANSITION_KINDS,
        InitialState,
        IntegrationError,
        PassageOutput,
        Transition,
        static_indentation,
    )

    v = spec.speed
    t0 = spec.t0
    t1 = t0 + spec.duration
    x0, x1 = v * t0, v * t1
    cribs = tuple(spec.cribs)
    if cribs:
        lo = min([x0, *(c.x_a for c in cribs)])
        hi = max([x1, *(c.x_b for c in cribs)])
        check_cribs(cribs, track, lo, hi)
    if table.stiffness_scale.size:
        raise TrackError(
            "curvature_stiffness",
            "the curvature-dependent Hertz coefficient is not modelled on a discrete or slab "
            "track: leave it false",
        )
    mt = model or reduce_track(track, x0, x1, cribs)
    law = spec.contact.law
    if track_dents is None:
        track_dents = law == ContactLaw.HERTZ_PLASTIC
    init = spec.initial or InitialState()
    if init.y_m != 0.0 or init.v_m != 0.0:
        raise ValueError("initial y_m/v_m: the rail starts in static equilibrium on a track")
    h_max = min(step, FEATURE_STEPS * table.resolution / v)
    if track_dents:
        h_max = min(h_max, dent_spacing / v)

    # static equilibrium of wheel and track at x0
    f0 = spec.load
    r0 = mt.rows_at(x0)
    zeta = np.ascontiguousarray(-r0 * f0 / mt.lam)
    w0 = float(np.sum((r0 * zeta).real)) - mt.residual_compliance(x0) * f0
    d0 = static_indentation(spec.contact, spec.load)
    ck0 = float(table.evaluate(np.array([x0]))[0])
    y0 = ck0 + w0 - d0 + init.y_c

    n_samples = math.floor(spec.duration * spec.sample_rate * (1 + 1e-12)) + 1
    sample_t = np.minimum(t0 + np.arange(n_samples) / spec.sample_rate, t1)
    kinks, jump = table.kink_jumps_between(x0 - 1e-12, x1 + table.resolution)
    kinks = kinks[jump * v * h_max > KINK_FRACTION * d0]
    stops = np.ascontiguousarray(np.sort(kinks / v), dtype=np.float64)
    samples = np.zeros((n_samples, st.N_COLS))
    channels = np.zeros((n_samples, len(cribs)))
    transitions = np.empty((MAX_TRANSITIONS, 2))  # rows written before read (1.6 MB unzeroed)
    dents = np.zeros(((int(spec.duration * v / dent_spacing) + 16) if track_dents else 1, 3))
    extrema = np.zeros(st.N_EXTREMA)
    c = spec.contact
    wheel = st.Wheel(
        int(law),
        float(c.coefficient),
        float(c.yield_force),
        float(c.yield_indentation),
        float(c.johnson_coefficient),
        float(c.switch_width),
        float(spec.mass),
        float(spec.load),
        float(v),
    )

    tab = table_of(table)
    n_tr, n_dent, status = st.run(
        mt.arrays,
        tab,
        wheel,
        float(t0),
        float(h_max),
        stops,
        sample_t,
        *padded_parts(zeta, st.MODE_DTYPE),
        aligned_zeros((st.WORK_ROWS, padded_size(mt.n_modes)), st.MODE_DTYPE),
        # ζ̇ of a block of samples, for the model's cribs' inertia (run counts them the same way)
        aligned_zeros(
            (2 * st.RATE_BLOCK if mt.crib_ids else 2, padded_size(mt.n_modes)), st.MODE_DTYPE
        ),
        np.empty(4),
        float(y0),
        float(init.v_c),
        float(f0),
        bool(track_dents),
        int(max_steps),
        samples,
        channels,
        transitions,
        dents,
        extrema,
    )
    if status == st.TOO_MANY_STEPS:
        raise IntegrationError(f"more than {max_steps} steps on the track: raise max_steps")
    if status == st.TOO_MANY_TRANSITIONS:
        raise IntegrationError(
            f"more than {MAX_TRANSITIONS} transitions in one passage: the contact chatters"
        )
    rows = transitions[:n_tr]
    order = np.argsort(rows[:, 0], kind="stable")
    rows = rows[order]
    trans = tuple(
        Transition(float(t), TRANSITION_KINDS[int(k)], float(t) * v) for t, k in rows.tolist()
    )
    ever_lost = any(tr.kind == "loss" for tr in trans) or extrema[st.E_T_FLIGHT] > 0.0
    dn = dents[:n_dent] if track_dents else np.zeros((0, 3))
    s = samples
    return PassageOutput(
        t=s[:, st.C_T].copy(),
        x=s[:, st.C_X].copy(),
        y_c=s[:, st.C_YC].copy(),
        v_c=s[:, st.C_VC].copy(),
        y_ck=s[:, st.C_YCK].copy(),
        y_m=s[:, st.C_W].copy(),
        v_m=s[:, st.C_VW].copy(),
        delta=s[:, st.C_DELTA].copy(),
        force=s[:, st.C_FORCE].copy(),
        in_contact=s[:, st.C_CONTACT] > 0.5,
        transitions=trans,
        delta_c_t=dn[:, 0].copy(),
        delta_c_x=dn[:, 1].copy(),
        delta_c=dn[:, 2].copy(),
        steps=int(extrema[st.E_STEPS]),
        rejected_steps=0,
        rhs_evaluations=int(extrema[st.E_STEPS]),
        peak_force=float(extrema[st.E_PEAK_FORCE]),
        min_force=0.0 if ever_lost else float(extrema[st.E_MIN_FORCE]),
        max_indentation=float(extrema[st.E_PEAK_DELTA]),
        time_out_of_contact=float(extrema[st.E_T_FLIGHT]),
        channels={cid: channels[:, i].copy() for i, cid in enumerate(mt.crib_ids)},
    )
