"""``railtwin warm``: compile the physics into numba's cache, the independent parts in parallel.

    railtwin warm [--site SITE.toml]... [--only-sites] [--jobs N]
    python -m service.cli.warm [...]                  # the same, without the entry point

A first start otherwise compiles the whole physics in the service's one worker
process, one function after the other (minutes on a cold cache). The compiled
code falls into steps that share few compiled functions (``Step``): the integrator
(``passage``: ``sim_core.integrate.loop.integrate`` and the kernels it calls; ``events``:
its event and record kernels), the constraint's tabulation paths in two halves
(``searches``, ``sweeps``: ``sim_core.constraint.warm_up_constraint``), the stepper of a rail
on sleepers (``track``) and the dent press and rough-rail synthesis (``rail``). This
command compiles them in ``--jobs`` processes at once (default: one per CPU), the longest
first (``STEP_COST``), each writing its functions to numba's cache (``NUMBA_CACHE_DIR``; the
Makefile points it at ``.venv/numba-cache``), then runs the service's own warm-up for each
``--site`` (default: ``examples/site.toml``, a rail on sleepers with a detector, and
``examples/site_compliant.toml``, the paper's lumped foundation), which loads them from the
cache and compiles what is left.

By default it compiles the whole physics on every rail kind (``make venv``: the tests use
all of it). ``--only-sites`` compiles what the ``--site`` files need (``plan_for``): the
constraint's paths on their rails' kinds, the integrator only for a lumped foundation, the
track's stepper only for a rail on supports. ``make demo``'s first run uses it: about half
the compiling (measured: 58 s against 127 s on 2 cores).

It also byte-compiles railtwin's own packages (``compile_sources``): Python reads a module's
cached bytecode even where it does not write it (``PYTHONDONTWRITEBYTECODE``, set in many
container images), and an editable install's sources are the checkout's, which pip does not
compile. Without it every ``railtwin diagnose`` compiled some 55 modules from source, 0.07 s
of its start-up (measured).

Running it again on a warm cache only loads (seconds). Each process writes a function's
cache entry whole (numba writes a file aside, then renames it), and a function compiled by
two processes at once is simply written twice with the same content.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, cast

import sim_core  # noqa: F401  (first: it points numba's cache at the venv's, sim_core/__init__)
from schemas.site import SiteConfig
from service.cli.common import CommandError
from service.cli.inputs import load_site_file
from service.wire.site import load_site
from sim_core.constraint.warm_up import CONSTRAINT_PARTS, RAIL_KINDS, ConstraintPart
from sim_core.rail import RailKind

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SITES = (ROOT / "examples" / "site.toml", ROOT / "examples" / "site_compliant.toml")
"""The example sites: a rail on sleepers with a detector (``make demo``), and the paper's
lumped foundation (the diagnosis's)."""

Step = Literal["passage", "events", "searches", "sweeps", "track", "rail"]
"""What one process compiles at a time: ``passage`` the integrator from its top (the step
loop, the Runge–Kutta steps, ...), ``events`` the integrator's event and record kernels,
which the loop reaches last, ``searches`` and ``sweeps`` the constraint's two halves
(``sim_core.constraint.CONSTRAINT_PARTS``), ``track`` the stepper of a rail on supports,
``rail`` the dent press and the synthesis of a rough rail (the measurements' generator)."""

STEP_COST: dict[Step, float] = {
    "passage": 86.0,
    "sweeps": 61.0,
    "searches": 38.0,
    "events": 15.0,
    "track": 12.0,
    "rail": 5.0,
}
"""Cold compile of each step, s of CPU (measured on the 2-core CI machine; scheduling order
only: the longest first, each to the first free process)."""

LUMPED = ("rigid", "compliant")
"""Foundation kinds the integrator serves (a rail on supports has its own stepper)."""


@dataclass(frozen=True)
class Plan:
    """What to compile: the steps, longest first, and the rail kinds the constraint's paths
    are warmed on."""

    steps: tuple[Step, ...]
    rails: tuple[RailKind, ...]


def plan_for(sites: list[SiteConfig] | None) -> Plan:
    """Everything (``None``: the whole physics, every rail kind), or what ``sites`` need:
    the constraint's paths on their rails' kinds, the integrator only where a foundation
    is lumped, the track's stepper only where the rail lies on supports.

    >>> plan_for(None).steps
    ('passage', 'sweeps', 'searches', 'events', 'track', 'rail')
    """
    if sites is None:
        steps: set[Step] = set(STEP_COST)
        rails: tuple[RailKind, ...] = RAIL_KINDS
    else:
        from service.physics.site_physics import SitePhysics

        steps = {"searches", "sweeps", "rail"}
        kinds: set[RailKind] = set()
        for site in sites:
            steps |= {"passage", "events"} if site.foundation.kind in LUMPED else {"track"}
            kinds |= set(SitePhysics(site).rail_kinds())
        rails = tuple(k for k in RAIL_KINDS if k in kinds)
    return Plan(tuple(sorted(steps, key=lambda st: -STEP_COST[st])), rails)


def warm_group(steps: tuple[str, ...], rails: tuple[RailKind, ...] = RAIL_KINDS) -> float:
    """Compile (or load) ``steps`` in this process, the constraint's on ``rails``; returns
    the wall time (s)."""
    start = time.perf_counter()
    for step in steps:
        if step == "passage":
            _warm_integrator()
        elif step == "events":
            _warm_integrator_kernels()
        elif step in CONSTRAINT_PARTS:
            from sim_core.constraint import warm_up_constraint

            warm_up_constraint((cast(ConstraintPart, step),), rails)
        elif step == "rail":
            _warm_rail()
        elif step == "track":
            _warm_track()
        else:
            raise ValueError(f"unknown warm-up step {step!r} (known: {', '.join(STEP_COST)})")
    return time.perf_counter() - start


def _warm_integrator() -> None:
    """One short passage on a flat rail and a compliant foundation.

    ``integrate`` is compiled whole on its first call (every mode, every event, both
    foundations, every contact law: one signature), so one passage compiles it all.
    """
    import numpy as np

    from sim_core.constraint import flat_constraint
    from sim_core.contact_laws import ContactLaw, ContactModel
    from sim_core.materials import Material, derive
    from sim_core.passage import Foundation, PassageSpec, simulate_passage

    d = derive(Material(2.14e11, 0.3), radius=0.46, load=60e3, mass=600.0)
    spec = PassageSpec(
        mass=600.0,
        load=60e3,
        speed=30.0,
        duration=0.002,
        sample_rate=1e4,
        contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient),
        foundation=Foundation.compliant(150.0, 2e8, 7e4),
    )
    out = simulate_passage(flat_constraint(), spec)
    if not np.isfinite(out.force).all():
        raise RuntimeError("the warm-up passage gave a non-finite force")


def _warm_track() -> None:
    """One short passage on a rail on sleepers with a crib: compiles the track's stepper
    (one signature, whatever the track, the contact law or the number of cribs)."""
    import numpy as np

    from sim_core.constraint import flat_constraint
    from sim_core.contact_laws import ContactLaw, ContactModel
    from sim_core.materials import Material, derive
    from sim_core.passage import PassageSpec, simulate_passage
    from sim_core.track.spec import Crib, Support, TrackSpec

    d = derive(Material(2.14e11, 0.3), radius=0.46, load=60e3, mass=600.0)
    track = TrackSpec.discrete(
        sleeper_spacing=0.6,
        first_sleeper=0.3,
        pad=Support(2.0e8, 3.0e4),
        sleeper_mass=150.0,
        ballast=Support(1.2e8, 8.0e4),
    )
    spec = PassageSpec(
        mass=600.0,
        load=60e3,
        speed=30.0,
        duration=0.03,
        sample_rate=1e4,
        contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient),
        foundation=track,
        cribs=(Crib("c1", 0.4, 0.8),),
    )
    out = simulate_passage(flat_constraint(), spec)
    if not (np.isfinite(out.force).all() and np.isfinite(out.channels["c1"]).all()):
        raise RuntimeError("the warm-up passage on a track gave a non-finite force or channel")


def _warm_rail() -> None:
    """The dent press on a cosine rail and a rough rail's synthesis: what a site's warm-up
    and the measurements' generator would otherwise compile after the pool."""
    import numpy as np

    from sim_core.rail import RailProfile
    from sim_core.rail_pass import DentedRail
    from sim_core.roughness import power_law_psd, random_roughness

    rail = DentedRail.of(RailProfile.cosine(2e-6, 0.06), 0.0, 1.0)
    rail.pressed(np.array([0.5]), np.array([-1e-5]), 0.46).profile.height(np.array([0.5]))
    k = np.linspace(1.0, 100.0, 8)
    random_roughness(1.0, 1e-3, k, power_law_psd(k, 1e-8, 2.0), seed=0)


def _warm_integrator_kernels() -> None:
    """Compile the integrator's event and record kernels, without running them, for the
    signature the step loop calls them with, the last it reaches first."""
    import numba
    import numpy as np

    from sim_core.constraint import flat_constraint
    from sim_core.integrate import events as ev
    from sim_core.integrate import loop as it
    from sim_core.integrate import records as rec
    from sim_core.integrate.model import force_rate
    from sim_core.integrate.types import Params, Work, table_of

    tab = table_of(flat_constraint())
    par = Params.build(
        law=0,
        c=1e11,
        f_y=0.0,
        d_y=0.0,
        theta=0.0,
        hyst=0.0,
        mass=600.0,
        load=6e4,
        speed=30.0,
        compliant=False,
        f_mass=1.0,
        f_stiff=0.0,
        f_damp=0.0,
        rtol=1e-8,
        atol_y=1e-12,
        atol_v=1e-9,
        hmax_contact=1e-4,
        c2max=0.0,
        track_dents=False,
        dent_dx=1e-4,
    )
    w = Work(
        np.zeros((13, 4)),
        np.zeros(13),
        np.zeros(4),
        np.zeros(4),
        np.zeros((2, 8)),
        np.zeros(128),
        np.zeros(128),
    )
    y, coef, rows = np.zeros(4), w.coef, np.zeros((8, 3))
    i, f, b = 0, 0.0, False
    calls: list[tuple[Any, tuple[Any, ...]]] = [
        (it.step_after_event, (i, f, f, f, f, coef, par, tab, i)),
        (it.land_on_event, (i, f, y, par, tab, i)),
        (rec.record_dents, (rows, i, f, f, coef, par, tab, i)),
        (force_rate, (f, f, f, coef, par, tab, b, i)),
        (ev.find_root, (i, f, f, f, f, f, f, f, coef, par, tab, f, f, i, i)),
        (ev.first_crossing, (i, f, f, coef, par, tab, i, i)),
        (ev.detect_in_flight, (f, f, w, par, tab, y, i)),
    ]
    for dispatcher, args in calls:
        dispatcher.compile(tuple(numba.typeof(a) for a in args))


PACKAGES = ("schemas", "service", "sim_core")
"""railtwin's own packages, byte-compiled by ``compile_sources``."""


def compile_sources(packages: tuple[str, ...] = PACKAGES) -> bool:
    """Write the bytecode of every module of ``packages`` into its ``__pycache__``, whatever
    ``sys.dont_write_bytecode`` says (``compileall`` writes it explicitly); True if every
    module compiled. Packages are found without importing them."""
    import compileall
    import importlib.util

    ok = True
    for name in packages:
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.submodule_search_locations:
            raise ValueError(f"railtwin warm: no package {name!r} to byte-compile")
        for directory in spec.submodule_search_locations:
            ok = bool(compileall.compile_dir(directory, quiet=1)) and ok
    return ok


def warm(
    site_files: Path | list[Path], jobs: int, out: Any = sys.stdout, *, only_sites: bool = False
) -> float:
    """Byte-compile railtwin's packages, compile the plan's steps in ``jobs`` processes (the
    whole physics, or with ``only_sites`` what the sites need), then each site's warm-up
    here; total s."""
    sites = [site_files] if isinstance(site_files, Path) else list(site_files)
    start = time.perf_counter()
    if not compile_sources():
        print("railtwin warm: some modules did not byte-compile", file=out, flush=True)
    plan = plan_for([load_site(f) for f in sites] if only_sites else None)
    print(
        f"railtwin warm: {', '.join(plan.steps)}; constraint paths on {', '.join(plan.rails)} "
        "rails",
        file=out,
        flush=True,
    )
    if jobs > 1:
        ctx = multiprocessing.get_context("spawn")  # fresh interpreters: nothing compiled yet
        with concurrent.futures.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            futures = {st: pool.submit(warm_group, (st,), plan.rails) for st in plan.steps}
            for st, fut in futures.items():
                print(f"railtwin warm: {st} compiled in {fut.result():.1f} s", file=out, flush=True)
    else:
        for st in plan.steps:
            took = warm_group((st,), plan.rails)
            print(f"railtwin warm: {st} compiled in {took:.1f} s", file=out, flush=True)
    for site_file in sites:
        t0 = time.perf_counter()
        _warm_site(site_file)
        print(
            f"railtwin warm: site {site_file.name} warmed up in {time.perf_counter() - t0:.1f} s",
            file=out,
            flush=True,
        )
    return time.perf_counter() - start


def _warm_site(site_file: Path) -> None:
    """What ``railtwin serve`` runs before it is ready, once (``SitePhysics.warm_up`` and the
    diagnosis's)."""
    from service.physics.diagnosis import Diagnoser
    from service.physics.site_physics import SitePhysics

    site = load_site(site_file)
    physics = SitePhysics(site)
    physics.warm_up()
    Diagnoser(site, physics=physics).warm_up()


def _default_jobs() -> int:
    return max(1, min(len(STEP_COST), os.cpu_count() or 1))


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--site",
        type=Path,
        action="append",
        default=None,
        help="site file whose warm-up runs last (repeatable; default: examples/site.toml and "
        "examples/site_compliant.toml)",
    )
    p.add_argument(
        "--only-sites",
        action="store_true",
        help="compile only what the --site files need (their rails' kinds, their foundations' "
        "steppers), not the whole physics: make demo's first run",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=_default_jobs(),
        help=f"processes compiling at once (default: {_default_jobs()})",
    )


def handler(args: argparse.Namespace) -> int:
    if args.jobs < 1:
        print("railtwin warm: --jobs must be >= 1", file=sys.stderr)
        return 2
    sites: list[Path] = args.site or list(DEFAULT_SITES)
    for site in sites:  # refused now, not after minutes of compiling
        try:
            load_site_file(site, served=True)
        except CommandError as exc:
            print(f"railtwin warm: {exc}", file=sys.stderr)
            return exc.code
    cache = os.environ.get("NUMBA_CACHE_DIR", "numba's default (__pycache__ beside the sources)")
    print(
        f"railtwin warm: compiling the physics into {cache} ({args.jobs} process"
        f"{'es' if args.jobs > 1 else ''})",
        flush=True,
    )
    total = warm(sites, args.jobs, only_sites=args.only_sites)
    print(f"railtwin warm: done in {total:.1f} s", flush=True)
    return 0


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "warm",
        help="compile the physics into numba's cache (parallel)",
        description=__doc__.split("\n")[0],
    )
    add_arguments(p)
    p.set_defaults(func=handler)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin warm", description=__doc__.split("\n")[0])
    add_arguments(p)
    return handler(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
