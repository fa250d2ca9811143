"""The twin's crib channels: a wheel (round or flat) on the site's track, through the site's chain.

The forward model of the diagnosis from channels. The wheel rolls over the site's rail on
discrete supports or slab (``sim_core.under_rail``: ``simulate_passage`` with the detector's
cribs), from static equilibrium ``RUN_IN`` m before the first gauge, and each crib's channel
is passed through the site's measuring chain (``sensor.SensorModel``) and read at the
record's instants. Times are the site's: t = 0 when the wheel centre is at x = 0.

Every run at one site covers one of two fixed stretches, so that the track is reduced to its
modes once per stretch (kept in memory and on disk) whatever the wheel:

- the *fit* stretch, from ``RUN_IN`` before the first gauge to ``RUN_OUT`` past the last;
- the *line* stretch, from ``RUN_IN`` before x = 0 to the site's end (the record's window,
  where the line-speed forecast's contact peak is taken).

A fit's run may simulate only parts of the fit stretch (``CribSite.run_spans``: the windows
it compares, each from static equilibrium ``RUN_IN`` before it) on the same reduced track.

The rail in the fit is even: a site does not know its rail's roughness (MODEL.md §8).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.contact_laws import ContactModel
from sim_core.diagnosis.crib_screen import round_template
from sim_core.diagnosis.forward import RailTables, Tread, wheel_table
from sim_core.diagnosis.sensor import SensorModel
from sim_core.passage import PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.track.modal import reduce_track
from sim_core.track.passage import simulate_on_track
from sim_core.track.spec import Crib, TrackSpec

__all__ = ["RUN_IN", "RUN_OUT", "CribRun", "CribSite", "CribWheel"]

RUN_IN = 0.5
"""m of steady rolling simulated before a stretch's start (from static equilibrium there)."""

RUN_OUT = 0.3
"""m simulated past the last gauge (the chain's delay and the wheel leaving the crib)."""

RTOL = 1e-6
"""The integrator's tolerance in the fit (forces to ~1e-5 of P, far below the noise)."""


@dataclass(frozen=True)
class CribWheel:
    """What is known of the wheel: m (kg), P (N), R (m) and its contact law."""

    mass: float
    load: float
    radius: float
    contact: ContactModel


@dataclass(frozen=True)
class CribRun:
    """One simulated passage as the site records it.

    ``channels``: rows per crib at the requested instants (N, after the chain);
    ``peak_force``: the contact force's peak over the stretch (N, continuous);
    ``t``/``force``: the contact force at the simulation's rate."""

    channels: NDArray[np.float64]
    peak_force: float
    t: NDArray[np.float64]
    force: NDArray[np.float64]


class CribSite:
    """A site with a detector: its track, cribs, chain and the two stretches."""

    def __init__(
        self, track: TrackSpec, cribs: tuple[Crib, ...], sensor: SensorModel, length: float
    ) -> None:
        if not cribs:
            raise ValueError("crib site: the detector has no cribs")
        self.track = track
        self.cribs = cribs
        self.sensor = sensor
        self.length = length
        self.fit_stretch = (
            min(c.x_a for c in cribs) - RUN_IN,
            max(c.x_b for c in cribs) + RUN_OUT,
        )
        self.line_stretch = (-RUN_IN, max(length, self.fit_stretch[1]))
        self.rails = RailTables(RailProfile.flat())

    def prepare(self) -> None:
        """Reduce the track over both stretches (seconds, once; then from the disk store)."""
        for x0, x1 in (self.fit_stretch, self.line_stretch):
            self.track.prepare(round(x0, 9), round(x1, 9), self.cribs)

    def run(
        self,
        wheel: CribWheel,
        speed: float,
        flat: Tread | None,
        t_out: NDArray[np.float64],
        *,
        line: bool = False,
        measurement_rate: float = 10_000.0,
        rails: RailTables | None = None,
        spans: Sequence[tuple[float, float]] | None = None,
    ) -> CribRun:
        """The wheel with ``flat`` (None: round) at ``speed`` over the fit (or ``line``)
        stretch; channels at ``t_out`` (instants outside the stretch read 0 before it and
        the last value after it). ``rails``: the rail rolled over (default the site's
        even rail; a synthetic record hands in a rough one).

        ``spans``: only these stretches [x_s, x_e] of the fit stretch are simulated, each
        from static equilibrium ``RUN_IN`` before it (``run_spans``); instants outside them
        read the round template."""
        if spans is not None and not line:
            return self.run_spans(wheel, speed, flat, t_out, spans, measurement_rate)
        x0, x1 = self.line_stretch if line else self.fit_stretch
        rate = self.sensor.fine_rate(measurement_rate)
        t0 = x0 / speed
        duration = (x1 - x0) / speed
        rail = self.rails if rails is None else rails
        table = wheel_table(wheel.radius, flat, rail, x0, x1 + 2.0 * speed / rate)
        spec = PassageSpec(
            mass=wheel.mass,
            load=wheel.load,
            speed=speed,
            duration=duration,
            sample_rate=rate,
            contact=wheel.contact,
            foundation=self.track,
            rtol=RTOL,
            t0=t0,
            cribs=self.cribs,
        )
        out = simulate_passage(table, spec, track_dents=False)
        chans = np.empty((len(self.cribs), t_out.size))
        for i, c in enumerate(self.cribs):
            filtered = self.sensor.filter(out.channels[c.id], rate)
            chans[i] = np.interp(t_out, out.t, filtered, left=0.0)
        return CribRun(chans, float(out.peak_force), out.t, out.force)

    def run_spans(
        self,
        wheel: CribWheel,
        speed: float,
        flat: Tread | None,
        t_out: NDArray[np.float64],
        spans: Sequence[tuple[float, float]],
        measurement_rate: float = 10_000.0,
    ) -> CribRun:
        """``run`` over the fit stretch's ``spans`` only: a fit compares the record with the
        twin in windows around the flat's impacts (1-2 in a record), a small part of the
        stretch, and a run's cost grows with the travel simulated (the stepper's step is
        at most 20 µs). Each span (merged with the next where their run-ins would overlap)
        starts from static equilibrium ``RUN_IN`` before it on the fit stretch's reduced
        track (the same modes: no new reduction); instants outside every span read the round
        template (``crib_screen.round_template``); the peak force is over the spans."""
        lo_fit, hi_fit = self.fit_stretch
        merged: list[list[float]] = []  # [start of the run, end, start of the span]
        for xs, xe in sorted(spans):
            a, b = max(xs - RUN_IN, lo_fit), min(xe, hi_fit)
            if b <= max(a, xs):
                continue
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b, xs])
        chans = round_template(self.cribs, speed, wheel.load, t_out, self.sensor)
        if not merged:
            return CribRun(chans, wheel.load, np.empty(0), np.empty(0))
        model = reduce_track(self.track, round(lo_fit, 9), round(hi_fit, 9), self.cribs)
        rate = self.sensor.fine_rate(measurement_rate)
        table = wheel_table(wheel.radius, flat, self.rails, lo_fit, hi_fit + 2.0 * speed / rate)
        peak = 0.0
        ts: list[NDArray[np.float64]] = []
        fs: list[NDArray[np.float64]] = []
        for a, b, xs in merged:
            spec = PassageSpec(
                mass=wheel.mass,
                load=wheel.load,
                speed=speed,
                duration=(b - a) / speed,
                sample_rate=rate,
                contact=wheel.contact,
                foundation=self.track,
                rtol=RTOL,
                t0=a / speed,
                cribs=self.cribs,
            )
            out = simulate_on_track(table, spec, self.track, model=model, track_dents=False)
            keep = (t_out >= xs / speed) & (t_out <= b / speed)  # the run-in is not read
            for i, c in enumerate(self.cribs):
                filtered = self.sensor.filter(out.channels[c.id], rate)
                chans[i, keep] = np.interp(t_out[keep], out.t, filtered)
            peak = max(peak, float(out.peak_force))
            ts.append(out.t)
            fs.append(out.force)
        return CribRun(chans, peak, np.concatenate(ts), np.concatenate(fs))

    def in_fit_stretch(self, t: NDArray[np.float64], speed: float) -> NDArray[np.bool_]:
        """Which record instants the fit stretch covers (the run-in excluded)."""
        x = speed * t
        lo = self.fit_stretch[0] + RUN_IN
        return np.asarray((x >= lo) & (x <= self.fit_stretch[1]), dtype=np.bool_)


def line_times(length: float, speed: float, rate: float) -> NDArray[np.float64]:
    """The detector's sampling instants while the wheel crosses [0, length] at ``speed``."""
    n = math.floor(length / speed * rate) + 1
    return np.arange(n, dtype=np.float64) / rate
