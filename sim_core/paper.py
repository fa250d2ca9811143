"""The paper's Figs. 3–9 recomputed: parameters, one function per figure, the facts.

Pure physics (no plotting, no I/O): every ``figN()`` runs the set-up of
MODEL.md §6 with sim_core and returns a small frozen dataclass holding the
arrays a figure draws and a ``facts`` dict of plain floats/ints/lists — the
numbers ``tests/test_paper_figures.py`` asserts and ``service.cli.figures``
writes to ``facts.json``.

The paper's parameters: m = 400 kg, P = 10·m·g, R = 0.475 m, E = 2.14e11 Pa,
ν = 0.3 (both bodies), cosine rail a = 0.1 mm, λ = 5 cm, Y = 600/700/800 MPa.
Excitation frequencies f = V/λ: Figs. 4 and 6 are drawn at 56 Hz, f0 = 270.6 Hz
and 2f0 = 541.2 Hz (MODEL.md §6: the paper quotes f0 ≈ 280 Hz, but the exact f0
of its parameters is 270.6 Hz and its pictures are those of f0 and 2f0); the
paper's rounded 280 and 560 Hz are reported alongside (``at_280_*``,
``at_560_*`` facts), not drawn. Fig. 9 stays at the paper's 280 Hz.

Conventions chosen here (the paper leaves them open):

- "Losses per period" count the located ``loss`` transitions whose time falls
  in excitation period k = floor(t·f).
- "Time out of contact" is the integrator's exact flight time over the window.
- F_max "in the first 20 periods" is the continuous peak of a passage that
  ends after 20 periods (same initial state as the long run).
- Fig. 4/6/9 run with a constant Hertz coefficient on the exact constraint;
  Fig. 4 also reports F_max with the curvature-dependent coefficient the
  paper uses (MODEL.md §3), because at resonance that number is sensitive
  (MODEL.md §7).

``quick=True`` shortens the long windows (for smoke tests); the facts the
tests assert always come from the full runs.

Worked example: the static curves need no integration,

    >>> r = fig5()
    >>> round(r.facts["johnson_force_at_2dy_over_fy"], 2), round(r.facts["final_over_dy"], 3)
    (4.0, 0.268)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint import (
    amplitude_spectrum,
    curvature_stiffness_scale,
    flat_constraint,
    profile_constraint,
    tabulate_constraint,
)
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import (
    HERTZ_PLASTIC,
    ContactLaw,
    ContactModel,
    contact_potential,
    hertz_plastic_unloading,
    johnson_unloading,
)
from sim_core.dents import dent_profile
from sim_core.materials import DerivedQuantities, Material, derive
from sim_core.passage import Foundation, InitialState, PassageOutput, PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline

Array = NDArray[np.float64]

# --- the paper's parameters -------------------------------------------------------------------

MASS = 400.0
"""m, the rolling (unsprung) mass (kg)."""
GRAVITY = 9.81
LOAD = 10.0 * MASS * GRAVITY
"""P = 10·m·g = 39 240 N."""
RADIUS = 0.475
"""R = R* (m)."""
YOUNGS_MODULUS = 2.14e11
POISSON_RATIO = 0.3
AMPLITUDE = 1e-4
"""a of the cosine rail (m)."""
WAVELENGTH = 0.05
"""λ of the cosine rail (m)."""
FLAT_LENGTH = 0.0616
"""Chord of the ideal flat of Fig. 3 (m), d ≈ 1 mm."""
YIELD_STRESSES = (6e8, 7e8, 8e8)
"""Y (Pa) of Figs. 6 and 8."""
F0 = 270.6
"""The contact resonance f0 of the paper's parameters to 0.1 Hz (Hz): ``derived()``
gives 270.603. MODEL.md §6's numbers are at 270.6 and 541.2 Hz exactly; at
resonance they move with the last digit (F_max in the first 20 periods is 22.9P
at 270.6 Hz, 22.5P at 270.603 Hz)."""
FREQUENCIES = (56.0, F0, 2.0 * F0)
"""f = V/λ of Fig. 4 (Hz): below resonance, f0 and 2f0 (Fig. 6 uses 2f0)."""
PAPER_FREQUENCIES = (280.0, 560.0)
"""The paper's rounded f0 and 2f0 (Hz): reported in the facts, not drawn."""
PERIODS = 300
"""Excitation periods of Figs. 4, 6 and 9."""
EARLY_PERIODS = 20
"""The window of "F_max in the first 20 periods"."""
SAMPLES_PER_PERIOD = 200
FIG8_SPEED = 100.0 / 3.6
"""V of Fig. 8 (m/s)."""
FIG8_VELOCITY = -0.3
"""ẏ_C at the start of Fig. 8 (m/s)."""
FIG8_DURATION = 0.06
"""Fig. 8's window (s): 1.7 m of rail, five to seven dents."""
FIG9_FREQUENCY = 280.0
FIG9_STIFFNESS_DIVISOR = 5.0
"""k = (linearised contact stiffness at P)/5."""
FIG9_MASS_RATIOS = (10.0, 1.0, 0.25)
"""M/m of Fig. 9."""

QUICK_PERIODS = 40
"""Window of the long runs with ``quick=True``."""


def material(yield_stress: float | None = None) -> Material:
    return Material(YOUNGS_MODULUS, POISSON_RATIO, yield_stress)


def derived(yield_stress: float | None = None) -> DerivedQuantities:
    """C, δ0, f0, k_lin (and F_Y, δ_Y with a yield stress) of the paper's wheel."""
    return derive(material(yield_stress), radius=RADIUS, load=LOAD, mass=MASS)


def contact_model(law: ContactLaw, yield_stress: float | None = None) -> ContactModel:
    d = derived(yield_stress)
    return ContactModel(
        law, d.contact_coefficient, d.yield_force or 0.0, d.yield_indentation or 0.0
    )


@functools.cache
def cosine_rail() -> RailProfile:
    return RailProfile.cosine(AMPLITUDE, WAVELENGTH)


@functools.cache
def cosine_constraint(kind: str = "exact") -> ConstraintTable:
    """The round wheel's constraint on the cosine rail (periodic, cached).

    ``kind``: ``"exact"`` (MODEL.md §2), ``"profile"`` (the profile is the
    constraint) or ``"curvature"`` (exact, with the curvature-dependent Hertz
    coefficient of MODEL.md §3 attached).
    """
    rail = cosine_rail()
    if kind == "profile":
        return profile_constraint(rail, 0.0, 1.0)
    table = tabulate_constraint(WheelOutline.round(RADIUS), rail, 0.0, 1.0)
    if kind == "curvature":
        scale = curvature_stiffness_scale(table, rail, RADIUS)
        return replace(table, stiffness_scale=scale)
    if kind != "exact":
        raise ValueError(f"constraint kind must be exact, profile or curvature, got {kind!r}")
    return table


# --- shared run helpers -------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Run:
    """One passage reduced to what the figures and facts need (SI units)."""

    label: str
    frequency: float
    t: Array
    y_c: Array
    v_c: Array
    delta: Array
    force: Array
    y_m: Array
    losses_per_period: NDArray[np.int64]
    facts: dict[str, Any] = field(default_factory=dict)


def _passage(
    frequency: float,
    periods: int,
    contact: ContactModel,
    table: ConstraintTable,
    foundation: Foundation | None = None,
) -> PassageOutput:
    spec = PassageSpec(
        mass=MASS,
        load=LOAD,
        speed=frequency * WAVELENGTH,
        duration=periods / frequency,
        sample_rate=frequency * SAMPLES_PER_PERIOD,
        contact=contact,
        foundation=foundation or Foundation.rigid(),
    )
    return simulate_passage(table, spec)


def _losses_per_period(out: PassageOutput, frequency: float, periods: int) -> NDArray[np.int64]:
    tl = np.array([tr.t for tr in out.transitions if tr.kind == "loss"])
    k = np.floor(tl * frequency * (1.0 + 1e-12)).astype(np.int64)
    k = k[(k >= 0) & (k < periods)]
    return np.bincount(k, minlength=periods).astype(np.int64)


def _cosine_run(
    label: str,
    frequency: float,
    periods: int,
    contact: ContactModel,
    constraint: str = "exact",
    foundation: Foundation | None = None,
) -> Run:
    """A passage over the cosine rail and its facts (whole window and first 20 periods)."""
    table = cosine_constraint(constraint)
    out = _passage(frequency, periods, contact, table, foundation)
    early_n = min(EARLY_PERIODS, periods)
    early = _passage(frequency, early_n, contact, table, foundation)
    per = _losses_per_period(out, frequency, periods)
    early_per = _losses_per_period(early, frequency, early_n)
    duration = periods / frequency
    yields = sum(tr.kind == "yield" for tr in out.transitions)
    facts: dict[str, Any] = {
        "frequency_hz": frequency,
        "periods": periods,
        "constraint": constraint,
        "law": contact.law.name.lower(),
        "peak_force_over_load": out.peak_force / LOAD,
        "early_peak_force_over_load": early.peak_force / LOAD,
        "min_delta_m": float(out.delta.min()),
        "max_gap_m": float(max(0.0, -out.delta.min())),
        "max_rise_m": float(out.y_c.max() - out.y_c[0]),
        "losses": int(per.sum()),
        "early_losses": int(early_per.sum()),
        "early_losses_per_period": early_per.tolist(),
        "periods_with_exactly_one_loss": int(np.count_nonzero(per == 1)),
        "first_period_without_exactly_one_loss": (
            int(np.argmax(per != 1)) if np.any(per != 1) else periods
        ),
        "fraction_out_of_contact": out.time_out_of_contact / duration,
        "early_fraction_out_of_contact": early.time_out_of_contact / (early_n / frequency),
        "yields": int(yields),
        "max_delta_m": out.max_indentation,
    }
    return Run(
        label=label,
        frequency=frequency,
        t=out.t,
        y_c=out.y_c,
        v_c=out.v_c,
        delta=out.delta,
        force=out.force,
        y_m=out.y_m,
        losses_per_period=per,
        facts=facts,
    )


# --- Fig. 3 -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Fig3:
    """Rigid constraints and their amplitude spectra.

    cosine_x, cosine_rail, cosine_constraint: one wavelength (m).
    cosine_amplitudes: A[0..10] in harmonics of λ (m).
    flat_x, flat_constraint: one wheel turn from the flat's centre (m).
    flat_amplitudes: A[0..40] in harmonics of the wheel turn 2πR (m).
    """

    cosine_x: Array
    cosine_rail: Array
    cosine_constraint: Array
    cosine_amplitudes: Array
    flat_x: Array
    flat_constraint: Array
    flat_amplitudes: Array
    facts: dict[str, Any]


@functools.cache
def fig3() -> Fig3:
    table = cosine_constraint("exact")
    x = np.linspace(0.0, WAVELENGTH, 1001)
    yc = table.evaluate(x)
    amp = amplitude_spectrum(table, 0.0, WAVELENGTH, 10)
    fine = table.evaluate(np.linspace(0.0, WAVELENGTH, 200_001))
    wheel = WheelOutline.ideal_flat(RADIUS, FLAT_LENGTH)
    turn = 2.0 * math.pi * RADIUS
    ftab = tabulate_constraint(wheel, RailProfile.flat(), -0.5 * turn, 0.5 * turn)
    fx = np.linspace(-0.5 * turn, 0.5 * turn, 20_001)
    fy = ftab.evaluate(fx)
    famp = amplitude_spectrum(ftab, -0.5 * turn, turn, 40)
    facts = {
        "cosine_max_over_a": float(fine.max()) / AMPLITUDE,
        "cosine_min_over_a": float(fine.min()) / AMPLITUDE,
        "cosine_harmonics_over_a": (amp[1:] / AMPLITUDE).tolist(),
        "flat_depth_m": wheel.flat_depth,
        "flat_min_constraint_m": float(fy.min()),
        "flat_harmonics_m": famp[1:].tolist(),
        "flat_10th_over_1st": float(famp[10] / famp[1]),
        "flat_max_over_min_harmonic_1_to_10": float(famp[1:11].max() / famp[1:11].min()),
    }
    return Fig3(x, cosine_rail().height(x), yc, amp, fx, fy, famp, facts)


# --- Fig. 4 -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Fig4:
    """Hertz on the cosine rail at 56 Hz, f0 = 270.6 Hz, 2f0 = 541.2 Hz: one :class:`Run` each."""

    runs: tuple[Run, ...]
    facts: dict[str, Any]


@functools.cache
def fig4(quick: bool = False) -> Fig4:
    periods = QUICK_PERIODS if quick else PERIODS
    hertz = contact_model(ContactLaw.HERTZ)
    runs = tuple(_cosine_run(f"{f:g} Hz", f, periods, hertz) for f in FREQUENCIES)
    facts: dict[str, Any] = {f"{r.frequency:g}": r.facts for r in runs}
    curved = _passage(FREQUENCIES[1], EARLY_PERIODS, hertz, cosine_constraint("curvature"))
    facts["f0_curvature_stiffness_early_peak_force_over_load"] = curved.peak_force / LOAD
    facts["contact_frequency_hz"] = derived().contact_frequency
    # the paper's rounded frequencies (MODEL.md §6 gives both): not drawn
    exact = cosine_constraint("exact")
    f280, f560 = PAPER_FREQUENCIES
    early_280 = _passage(f280, EARLY_PERIODS, hertz, exact)
    facts["at_280_early_peak_force_over_load"] = early_280.peak_force / LOAD
    out_560 = _passage(f560, periods, hertz, exact)
    facts["at_560_peak_force_over_load"] = out_560.peak_force / LOAD
    facts["at_560_periods_with_exactly_one_loss"] = int(
        np.count_nonzero(_losses_per_period(out_560, f560, periods) == 1)
    )
    return Fig4(runs, facts)


# --- Fig. 5 and Fig. 7: static curves ----------------------------------------------------------


@dataclass(frozen=True, eq=False)
class StaticCurves:
    """Static F(δ) curves on 0…2δ_Y in units of δ_Y and F_Y."""

    delta_over_dy: Array
    hertz: Array
    loading: Array
    unloading: Array
    facts: dict[str, Any]


def _static_setup() -> tuple[float, float, float]:
    d = derived(YIELD_STRESSES[0])
    assert d.yield_force is not None and d.yield_indentation is not None
    return d.contact_coefficient, d.yield_force, d.yield_indentation


@functools.cache
def fig5() -> StaticCurves:
    c, f_y, d_y = _static_setup()
    u = np.linspace(0.0, 2.0, 2001)
    delta = u * d_y
    johnson = contact_model(ContactLaw.JOHNSON, YIELD_STRESSES[0])
    loading = johnson.force(delta)
    unloading, d_r, d_f = johnson_unloading(
        delta, 2.0 * d_y, f_y, d_y, c, johnson.johnson_coefficient
    )
    hertz = c * delta**1.5
    above = (unloading > loading * (1.0 + 1e-9)) & (u > 0.0)
    idx = np.flatnonzero(above)
    facts = {
        "johnson_force_at_2dy_over_fy": float(loading[-1] / f_y),
        "recovery_over_dy": d_r / d_y,
        "final_over_dy": d_f / d_y,
        "unloading_above_loading_from": float(u[idx[0]]) if idx.size else None,
        "unloading_above_loading_to": float(u[idx[-1]]) if idx.size else None,
        "yield_force_n": f_y,
        "yield_indentation_m": d_y,
    }
    return StaticCurves(u, hertz / f_y, loading / f_y, unloading / f_y, facts)


@functools.cache
def fig7() -> StaticCurves:
    c, f_y, d_y = _static_setup()
    u = np.linspace(0.0, 2.0, 2001)
    delta = u * d_y
    hpp = contact_model(ContactLaw.HERTZ_PLASTIC, YIELD_STRESSES[0])
    loading = hpp.force(delta)
    unloading, d_r, d_f = hertz_plastic_unloading(delta, 2.0 * d_y, f_y, d_y)
    plateau = loading[u >= 1.0]
    facts = {
        "plateau_min_over_fy": float(plateau.min() / f_y),
        "plateau_max_over_fy": float(plateau.max() / f_y),
        "recovery_over_dy": d_r / d_y,
        "final_over_dy": d_f / d_y,
        "unloading_at_2dy_over_fy": float(unloading[-1] / f_y),
    }
    return StaticCurves(u, c * delta**1.5 / f_y, loading / f_y, unloading / f_y, facts)


# --- Fig. 6 -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Fig6:
    """Johnson vs Hertz at 2f0 = 541.2 Hz: Hertz, Johnson at Y = 800, 700, 600 MPa."""

    runs: tuple[Run, ...]
    facts: dict[str, Any]


@functools.cache
def fig6(quick: bool = False) -> Fig6:
    periods = QUICK_PERIODS if quick else PERIODS
    f = FREQUENCIES[2]
    runs = [_cosine_run("Hertz", f, periods, contact_model(ContactLaw.HERTZ))]
    for y in sorted(YIELD_STRESSES, reverse=True):
        model = contact_model(ContactLaw.JOHNSON, y)
        run = _cosine_run(f"Johnson, Y = {y / 1e6:.0f} MPa", f, periods, model)
        run.facts["yield_force_over_load"] = model.yield_force / LOAD
        runs.append(run)
    facts: dict[str, Any] = {"hertz": runs[0].facts}
    for y, run in zip(sorted(YIELD_STRESSES, reverse=True), runs[1:], strict=True):
        facts[f"johnson_{y / 1e6:.0f}"] = run.facts
    # The same comparison at the paper's rounded 560 Hz (reported, not drawn): there
    # the peak force stays below F_Y(800 MPa), Johnson's law never acts and both laws
    # give the same time out of contact.
    f560 = PAPER_FREQUENCIES[1]
    for law in (ContactLaw.HERTZ, ContactLaw.JOHNSON):
        out = _passage(f560, periods, contact_model(law, YIELD_STRESSES[2]), cosine_constraint())
        key = f"at_560_{law.name.lower()}_800"
        facts[f"{key}_fraction_out_of_contact"] = out.time_out_of_contact * f560 / periods
        facts[f"{key}_peak_force_over_load"] = out.peak_force / LOAD
        facts[f"{key}_yields"] = sum(tr.kind == "yield" for tr in out.transitions)
    return Fig6(tuple(runs), facts)


# --- Fig. 8 -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Fig8Case:
    yield_stress: float
    t: Array
    y_c: Array
    force: Array
    energy: Array
    dent_x: Array
    dent_depth: Array
    facts: dict[str, Any]


@dataclass(frozen=True, eq=False)
class Fig8:
    cases: tuple[Fig8Case, ...]
    facts: dict[str, Any]


def _dent_peaks(x: Array, depth: Array) -> tuple[list[float], list[float]]:
    """(position of the deepest point, depth) of each separate dent."""
    on = depth > 1e-9
    edges = np.diff(np.concatenate(([0], on.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    xs, ds = [], []
    for s, e in zip(starts, ends, strict=True):
        i = s + int(np.argmax(depth[s:e]))
        xs.append(float(x[i]))
        ds.append(float(depth[i]))
    return xs, ds


@functools.cache
def fig8() -> Fig8:
    cases = []
    for y in YIELD_STRESSES:
        model = contact_model(ContactLaw.HERTZ_PLASTIC, y)
        spec = PassageSpec(
            mass=MASS,
            load=LOAD,
            speed=FIG8_SPEED,
            duration=FIG8_DURATION,
            sample_rate=2e5,
            contact=model,
            initial=InitialState(v_c=FIG8_VELOCITY),
        )
        out = simulate_passage(flat_constraint(), spec)
        pot = np.array(
            [
                contact_potential(
                    float(dl),
                    HERTZ_PLASTIC,
                    model.coefficient,
                    model.yield_force,
                    model.yield_indentation,
                    model.johnson_coefficient,
                )
                for dl in out.delta
            ]
        )
        energy = 0.5 * MASS * out.v_c**2 + LOAD * out.y_c + pot
        dx, depth = dent_profile(out, model)
        px, pd = _dent_peaks(dx, depth)
        kinetic0 = 0.5 * MASS * FIG8_VELOCITY**2
        facts = {
            "yield_stress_pa": y,
            "yield_force_over_load": model.yield_force / LOAD,
            "energy_drift_over_initial_kinetic": float((energy.max() - energy.min()) / kinetic0),
            "dent_positions_m": px,
            "dent_depths_m": pd,
            "dent_spacings_m": np.diff(px).tolist(),
            "peak_force_over_load": out.peak_force / LOAD,
            "losses": sum(tr.kind == "loss" for tr in out.transitions),
        }
        cases.append(Fig8Case(y, out.t, out.y_c, out.force, energy, dx, depth, facts))
    return Fig8(tuple(cases), {f"{c.yield_stress / 1e6:.0f}": c.facts for c in cases})


# --- Fig. 9 -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Fig9:
    """Compliant foundation at 280 Hz: rigid, M = 10m, m, 0.25m (exact constraint) and
    M = 0.25m with the profile as the constraint."""

    runs: tuple[Run, ...]
    facts: dict[str, Any]


@functools.cache
def fig9(quick: bool = False) -> Fig9:
    periods = QUICK_PERIODS if quick else PERIODS
    f = FIG9_FREQUENCY
    hertz = contact_model(ContactLaw.HERTZ)
    k = derived().contact_stiffness / FIG9_STIFFNESS_DIVISOR
    runs = [_cosine_run("rigid", f, periods, hertz)]
    keys = ["rigid"]
    for ratio in FIG9_MASS_RATIOS:
        fd = Foundation.compliant(ratio * MASS, k)
        runs.append(_cosine_run(f"M = {ratio:g}m", f, periods, hertz, "exact", fd))
        keys.append(f"exact_{ratio:g}m")
    for ratio in FIG9_MASS_RATIOS:
        fd = Foundation.compliant(ratio * MASS, k)
        runs.append(
            _cosine_run(f"M = {ratio:g}m, profile as constraint", f, periods, hertz, "profile", fd)
        )
        keys.append(f"profile_{ratio:g}m")
    facts: dict[str, Any] = dict(zip(keys, (r.facts for r in runs), strict=True))
    facts["foundation_stiffness_n_per_m"] = k
    # the foundation mode with the wheel held still: M between k and the contact spring
    k_lin = derived().contact_stiffness
    facts["foundation_mode_hz"] = {
        f"{ratio:g}m": math.sqrt((k + k_lin) / (ratio * MASS)) / (2 * math.pi)
        for ratio in FIG9_MASS_RATIOS
    }
    return Fig9(tuple(runs), facts)


def all_facts(quick: bool = False) -> dict[str, Any]:
    """Every figure's facts, keyed ``fig3`` … ``fig9``."""
    return {
        "fig3": fig3().facts,
        "fig4": fig4(quick).facts,
        "fig5": fig5().facts,
        "fig6": fig6(quick).facts,
        "fig7": fig7().facts,
        "fig8": fig8().facts,
        "fig9": fig9(quick).facts,
    }
