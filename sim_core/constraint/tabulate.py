"""tabulate_constraint: the exact rigid constraint y_C^k(x_C) of MODEL.md §2 as a table, by the fastest exact method.

For a wheel outline r(θ) turned by φ = φ0 + x_C/R on a rail y_r(x):

    y_C^k(x_C) = max over ψ of [ y_r(x_C + ρ·sin ψ) + ρ·cos ψ ] - R,   ρ = r(ψ + φ)

(the height of the wheel centre relative to a round wheel on a flat rail).
The maximiser gives the contact point x_D = x_C + ρ·sin ψ. The result is a
:class:`~sim_core.constraint.table.ConstraintTable`: exact values and slopes on
nodes, cubic Hermite in between, and explicit kinks where the contact point
jumps (the wheel bridges a hollow, rolls on to a flat's corner, a concave rail
vertex, a step's corner).

Which method (one module each, all compiled with numba):

- a round wheel on a flat rail: y_C^k ≡ 0; an ideal flat on a flat rail: closed form
  (:mod:`sim_core.constraint.flat_rail`);
- a round wheel on a polyline rail (sampled, file, dented, step): the envelope of arcs and
  lines in closed form (:mod:`sim_core.constraint.round_polyline`);
- a round wheel on a cosine gentler than the wheel (|a|k²R <= 0.95): the rail's offset curve
  in closed form in the contact point, one period (:mod:`sim_core.constraint.round_cosine`);
- an out-of-round wheel on a flat or gentle cosine rail, an ideal flat on a cosine (its
  chord cut into the rail's crest windows, each in closed form,
  :mod:`sim_core.constraint.flat_cosine`), and a rounded flat or sampled outline on a cosine
  whose pieces cut into cells proved to hold at most one local maximum each
  (:mod:`sim_core.constraint.cosine_cells`): the piece sweep
  (:mod:`sim_core.constraint.wheel_pieces`);
- such a wheel whose cells are only partly certified (e.g. an l²/16R-deep flat on the
  paper's cosine: the hollow's middle bridges crests): the sweep wherever the uncertified
  cells cannot carry the wheel; in the windows where they can, a few cm per turn
  (:mod:`sim_core.constraint.cosine_hybrid`), a rounded flat's uncertified cells cut into
  boxes of wheel angle and rail phase with certified shapes, solved exactly per position
  (:mod:`sim_core.constraint.cosine_boxes`), or the ψ-search where those do not certify;
- an out-of-round wheel on a sampled rail: the wheel's pieces against the rail's
  segments inside the stretches where the out-of-roundness can reach the contact, the
  round wheel's closed form (made once per rail and radius, kept) elsewhere
  (:mod:`sim_core.constraint.polyline`);
- anything else, or ``method="general"``: the ψ-search (:mod:`sim_core.constraint.general`).

Periodic tables: a round wheel on a cosine (period λ) and any wheel on a flat
rail (period 2πR). Otherwise the table covers [x_start, x_end] plus a margin
of 10 mm + 2·dx on each side.

``resolution`` is the finest input feature: the rail's (sample spacing, λ/16)
and the wheel's (sample arc length, flat length/16), at most 10 mm. The default
node spacing ``dx`` is the resolution for the closed-form polyline case (its
pieces are exact between inserted nodes) capped at 1 mm, and half of it for the
general case capped at 2 mm.

Worked example (the paper's Fig. 3 reference): a round wheel (R = 0.475 m) on
a cosine rail a = 0.1 mm, λ = 5 cm reaches exactly ±a, and its fundamental is
0.93a (0.931), the 2nd harmonic 0.155a:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> t = tabulate_constraint(WheelOutline.round(0.475), RailProfile.cosine(1e-4, 0.05), 0.0, 1.0)
    >>> t.period, round(float(t.y.max()) / 1e-4, 9), round(float(t.y.min()) / 1e-4, 9)
    (0.05, 1.0, -1.0)
    >>> from sim_core.constraint.spectrum import amplitude_spectrum
    >>> amp = amplitude_spectrum(t, 0.0, 0.05, 2)
    >>> round(float(amp[1]) / 1e-4, 3), round(float(amp[2]) / 1e-4, 3)
    (0.931, 0.155)
"""

from __future__ import annotations

import math

from sim_core.constraint.cosine_hybrid import supports_cosine_hybrid, tabulate_cosine_hybrid
from sim_core.constraint.flat_rail import flat_constraint, ideal_flat_on_flat
from sim_core.constraint.general import tabulate_general
from sim_core.constraint.nodes import check_range
from sim_core.constraint.nodes import resolution as input_resolution
from sim_core.constraint.polyline import supports_polyline, tabulate_polyline
from sim_core.constraint.round_cosine import supports_round_cosine, tabulate_round_cosine
from sim_core.constraint.round_polyline import tabulate_round_polyline
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.wheel_pieces import supports as supports_pieces
from sim_core.constraint.wheel_pieces import tabulate_wheel_pieces
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["tabulate_constraint"]


def tabulate_constraint(
    wheel: WheelOutline,
    rail: RailProfile,
    x_start: float,
    x_end: float,
    *,
    phase: float = 0.0,
    dx: float | None = None,
    method: str = "auto",
) -> ConstraintTable:
    """The exact rigid constraint y_C^k of ``wheel`` on ``rail`` as a table.

    Args:
        wheel, rail: the geometry (MODEL.md §2).
        x_start, x_end: the stretch of wheel-centre positions x_C needed (m);
            non-periodic tables add a margin of 10 mm + 2·dx on both sides.
        phase: φ0 (rad): the wheel has turned by φ0 + x_C/R.
        dx: node spacing (m); default from the resolution (module docstring).
        method: ``"auto"``; ``"general"`` forces the ψ-search even where the
            closed form applies (for cross-checks).

    Worked example: an ideal flat of 61.6 mm on a flat rail lifts the wheel
    centre to R·cos(θ0 - |φ|) - R around φ = 0, with a kink at the flat's centre:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> t = tabulate_constraint(WheelOutline.ideal_flat(0.475, 0.0616), RailProfile.flat(), 0.0, 6.0)
    >>> round(t.period, 6), t.kinks.tolist(), round(float(t.y.min()) * 1e3, 4)
    (2.984513, [0.0], -0.9996)
    """
    a, b = check_range(x_start, x_end)
    if not math.isfinite(phase):
        raise ValueError(f"constraint: phase must be finite (rad), got {phase!r}")
    if method not in ("auto", "general"):
        raise ValueError(f"constraint: method must be 'auto' or 'general', got {method!r}")
    R = wheel.nominal_radius
    resolution = input_resolution(wheel, rail)
    if dx is not None and not (math.isfinite(dx) and dx > 0):
        raise ValueError(f"constraint: dx must be a positive finite length (m), got {dx!r}")
    lo_h, hi_h = rail.height_range
    if (hi_h - lo_h) + wheel.max_depth + wheel.max_excess > 0.2 * R:
        raise ValueError(
            f"constraint: rail height range {hi_h - lo_h!r} m plus wheel out-of-roundness "
            f"{wheel.max_depth + wheel.max_excess!r} m is not small against R = {R!r} m"
        )
    if method == "general":
        return tabulate_general(wheel, rail, a, b, float(phase), dx, resolution)
    if wheel.kind == "round" and rail.kind == "flat":
        return flat_constraint(period=TWO_PI * R, resolution=resolution)
    if wheel.kind == "ideal_flat" and rail.kind == "flat":
        step = float(dx) if dx is not None else min(0.25 * resolution, 1e-3)
        return ideal_flat_on_flat(wheel, a, float(phase), step, resolution)
    if wheel.kind == "round" and rail.kind in ("sampled", "step"):
        return tabulate_round_polyline(R, rail, a, b, dx, resolution)
    if supports_round_cosine(wheel, rail):
        return tabulate_round_cosine(wheel, rail, a, b, dx, resolution)
    if supports_pieces(wheel, rail):
        return tabulate_wheel_pieces(wheel, rail, a, b, float(phase), dx, resolution)
    if supports_cosine_hybrid(wheel, rail):
        return tabulate_cosine_hybrid(wheel, rail, a, b, float(phase), dx, resolution)
    if supports_polyline(wheel, rail):
        return tabulate_polyline(wheel, rail, a, b, float(phase), dx, resolution)
    return tabulate_general(wheel, rail, a, b, float(phase), dx, resolution)
