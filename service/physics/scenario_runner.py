"""Run one validated ``Scenario`` through sim_core and package the ``Result``.

This is the only place where the JSON contract (``schemas``) meets the physics
(``sim_core``): it turns the pydantic scenario into sim_core objects, calls
``simulate_passes`` and turns its arrays back into the contract's result.

    >>> from schemas.scenario import Scenario, EXAMPLE_JSON
    >>> result = run_scenario(Scenario.model_validate_json(EXAMPLE_JSON))  # doctest: +SKIP
    >>> result.summary.contact_losses  # doctest: +SKIP
    0
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from schemas import result as res
from schemas import scenario as sc
from service.physics import inputs as physics_inputs

if TYPE_CHECKING:  # sim_core is imported when a scenario runs: ``railtwin --help`` stays quick
    from numpy.typing import ArrayLike

    from sim_core.contact_laws import ContactModel
    from sim_core.materials import DerivedQuantities
    from sim_core.multipass import MultiPassOutput
    from sim_core.passage import PassageOutput, PassageSpec
    from sim_core.rail import RailProfile
    from sim_core.summary import PassageSummary

Progress = Callable[[int, int], None]
"""progress(done, total): called with the number of passes completed so far."""

SUMMARY_FIELDS = tuple(res.Summary.model_fields)


def build_spec(scenario: sc.Scenario, contact: ContactModel) -> PassageSpec:
    """``PassageSpec`` of the scenario with its ``ContactModel`` (``physics_inputs.contact_model``)."""
    from sim_core.passage import InitialState, PassageSpec

    i = scenario.initial
    initial = None if i is None else InitialState(i.y_c, i.v_c, i.y_m, i.v_m)
    w = scenario.wheel
    return PassageSpec(
        mass=w.mass,
        load=w.load,
        speed=scenario.speed,
        duration=scenario.duration,
        sample_rate=scenario.sample_rate,
        contact=contact,
        foundation=physics_inputs.foundation(scenario.foundation),
        initial=initial,
        rtol=scenario.rtol,
        cribs=physics_inputs.cribs(scenario.detector),
    )


def run_scenario(scenario: sc.Scenario, progress: Progress | None = None) -> res.Result:
    """Simulate every pass of ``scenario`` and return the contract's ``Result``.

    ``progress(done, total)`` is called as passes complete (if sim_core's
    ``simulate_passes`` reports per pass; else once at the start and once at the end).
    Raises whatever sim_core raises on a runtime failure (the CLI maps it to exit 1).
    """
    from sim_core.multipass import simulate_passes

    started = time.perf_counter()
    w = scenario.wheel
    contact, derived = physics_inputs.contact_model(
        scenario.contact, scenario.material, radius=w.radius, load=w.load, mass=w.mass
    )
    spec = build_spec(scenario, contact)
    wheel = physics_inputs.wheel_outline(w.outline, w.radius)
    rail = physics_inputs.rail_profile(scenario.rail)

    kwargs: dict[str, Any] = {
        "passes": scenario.passes,
        "phase": scenario.wheel.phase,
        "constraint": scenario.constraint,
        "curvature_stiffness": scenario.curvature_stiffness,
    }
    reports_progress = progress is not None and _accepts(simulate_passes, "progress")
    if progress is not None:
        progress(0, scenario.passes)
        if reports_progress:
            report = progress
            # sim_core calls progress(done, total, summary) after each passage
            kwargs["progress"] = lambda done, total, *_: report(done, total)
    out = simulate_passes(wheel, rail, spec, **kwargs)
    if progress is not None and not reports_progress:
        progress(scenario.passes, scenario.passes)
    wall = time.perf_counter() - started
    return package_result(scenario, derived, out, wall)


WARM_UP_CASES: tuple[dict[str, Any], ...] = (
    {},
    {"wheel": {"outline": {"kind": "flat", "length": 0.05}}, "rail": {"kind": "flat"}},
    {
        "wheel": {"outline": {"kind": "rounded_flat", "length": 0.08, "depth": 1e-3}},
        "rail": {"kind": "sampled", "x": [0.0, 0.5, 1.0], "y": [0.0, -1e-5, 0.0]},
        "contact": "johnson",
        "foundation": {"kind": "compliant", "mass": 100.0, "stiffness": 2.31e8, "damping": 0.0},
        "curvature_stiffness": True,
    },
    {
        "rail": {"kind": "flat"},
        "contact": "hertz_plastic",
        "initial": {"y_c": 0.0, "v_c": -0.5, "y_m": 0.0, "v_m": 0.0},
        "passes": 2,
        "speed": 27.8,
    },
)
"""Edits of the contract's example that together touch every compiled path of the runner:
round and flat wheels, cosine, flat and sampled rails, the three laws, both foundations,
the curvature-dependent stiffness, dents and the dented rail."""


def warm_up(duration: float = 0.004) -> float:
    """Load (or compile) sim_core's compiled functions by running tiny scenarios; returns s.

    Batch runs call it once before the first scenario, so that no scenario's
    ``stats.wall_time`` includes the one-off cost (about 0.5 s from numba's
    cache, minutes without one). Failures here are not fatal: the real
    scenario then pays for the compilation and reports its own errors.
    """
    from schemas.scenario import EXAMPLE_JSON

    started = time.perf_counter()
    base = sc.Scenario.model_validate_json(EXAMPLE_JSON).model_dump(mode="json")
    for edit in WARM_UP_CASES:
        data = _merged(base, {"duration": duration, "sample_rate": 1e4, **edit})
        try:
            run_scenario(sc.Scenario.model_validate(data))
        except Exception:  # warming up only: the real scenario reports its own errors
            continue
    return time.perf_counter() - started


def _merged(base: dict[str, Any], edit: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``edit`` applied; nested dicts merge, except tagged unions ("kind") replace."""
    out = dict(base)
    for key, value in edit.items():
        old = out.get(key)
        if isinstance(value, dict) and isinstance(old, dict) and "kind" not in value:
            out[key] = _merged(old, value)
        else:
            out[key] = value
    return out


def package_result(
    scenario: sc.Scenario, derived: DerivedQuantities, out: MultiPassOutput, wall_time: float
) -> res.Result:
    """Turn sim_core's ``MultiPassOutput`` into the contract's ``Result``."""
    last = out.last
    series = _series(last, _channel_arrays(scenario, last))
    transitions = [  # sim_core's TransitionKind is the contract's (tests/test_transition_kinds.py)
        res.Transition(t=float(tr.t), kind=tr.kind, x=float(tr.x)) for tr in last.transitions
    ]
    summaries = [_summary(s) for s in out.summaries]
    rail_after = None
    if out.rail_after is not None:
        x, y = _rail_samples(out.rail_after, last.x)
        rail_after = res.RailSamples(x=x, y=y)
    stats = res.RunStats(
        steps=int(last.steps),
        rejected_steps=int(last.rejected_steps),
        rhs_evaluations=int(last.rhs_evaluations),
        wall_time=max(0.0, float(wall_time)),
    )
    return res.Result(
        scenario=scenario,
        derived=res.Derived(
            contact_coefficient=float(derived.contact_coefficient),
            static_indentation=float(derived.static_indentation),
            contact_frequency=float(derived.contact_frequency),
            yield_force=_opt_float(derived.yield_force),
            yield_indentation=_opt_float(derived.yield_indentation),
        ),
        series=series,
        transitions=transitions,
        summary=summaries[-1],
        rail_after=rail_after,
        passes_summary=summaries,
        stats=stats,
    )


SERIES_FLOATS = ("t", "x", "y_c", "v_c", "y_ck", "y_m", "delta", "force", "v_m")
"""The ``Series`` fields ``_series`` fills from the passage's float arrays, in order."""


def _channel_arrays(scenario: sc.Scenario, last: PassageOutput) -> dict[str, np.ndarray] | None:
    """The detector's channels, crib by crib in the detector's order; None without one."""
    if scenario.detector is None:
        return None
    missing = [c.id for c in scenario.detector.cribs if c.id not in last.channels]
    if missing:
        raise RuntimeError(f"sim_core returned no channel for the cribs {missing}")
    return {c.id: last.channels[c.id] for c in scenario.detector.cribs}


def _series(last: PassageOutput, channels: dict[str, np.ndarray] | None) -> res.Series:
    """The contract's ``Series`` of the last pass.

    ``Series`` asks every float to be finite and every series as long as ``t``. numpy checks
    both on the arrays, and the model is then built without pydantic's pass over each of its
    ~24 000 values (0.9 -> 0.5 ms on the site case: 1 351 samples, 8 channels; most of what is
    left is making the lists). Arrays that fail go through the model's own validation, which
    raises its own error. ``tests/test_scenario_runner_series.py`` holds the two paths equal
    and the model's fields to the ones checked here."""
    floats = {
        name: np.asarray(getattr(last, name), dtype=np.float64).ravel() for name in SERIES_FLOATS
    }
    contact = np.asarray(last.in_contact, dtype=bool).ravel()
    chans = {k: np.asarray(v, dtype=np.float64).ravel() for k, v in (channels or {}).items()}
    n = floats["t"].size
    every = [*floats.values(), *chans.values()]
    values: dict[str, Any] = {name: a.tolist() for name, a in floats.items()}
    values["in_contact"] = contact.tolist()
    values["channels"] = None if channels is None else {k: a.tolist() for k, a in chans.items()}
    if contact.size == n and all(a.size == n and bool(np.isfinite(a).all()) for a in every):
        return res.Series.model_construct(None, **values)
    return res.Series(**values)


def _summary(s: PassageSummary) -> res.Summary:
    values: dict[str, Any] = {}
    for name in SUMMARY_FIELDS:
        v = getattr(s, name)
        if name == "contact_losses":
            values[name] = int(v)
        elif v is None:
            values[name] = None
        else:
            values[name] = float(v)
    return res.Summary(**values)


def _rail_samples(rail: RailProfile, x_grid: ArrayLike) -> tuple[list[float], list[float]]:
    """(x, y) samples of a sim_core ``RailProfile``.

    A dented rail is a sampled profile: its own samples. Any other profile (no
    dent was left) is evaluated on ``x_grid``, the wheel positions of the last pass.
    """
    x = np.asarray(getattr(rail, "x", ()), dtype=np.float64)
    if x.size:
        return _floats(x), _floats(rail.y)
    grid = np.asarray(x_grid, dtype=np.float64)
    return _floats(grid), _floats(rail.height(grid))


def _floats(a: Any) -> list[float]:
    values: list[float] = np.asarray(a, dtype=np.float64).ravel().tolist()
    return values


def _opt_float(v: Any) -> float | None:
    return None if v is None else float(v)


def _accepts(func: Callable[..., Any], name: str) -> bool:
    try:
        params = inspect.signature(func).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())
