"""The track's calibrated parameters: log-factors on the nominal values.

A ballasted track (``discrete``) is calibrated in its pad stiffness and damping, sleeper
mass, ballast stiffness and damping; a slab in its pad's. The rail (a rolled section) and
the sleeper spacing (surveyed) are taken as they are. The estimator works in
z = ln(value / nominal): the factors are what is uncertain (±30 % is ordinary), and a factor
stays positive.

    >>> from sim_core.track.spec import Support, TrackSpec
    >>> t = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))
    >>> names(t), values(t)
    (('pad.stiffness', 'pad.damping'), (60000000.0, 15000.0))
    >>> import numpy as np
    >>> scaled(t, np.array([np.log(2.0), 0.0])).pad
    Support(stiffness=120000000.0, damping=15000.0)
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from sim_core.track.spec import Support, TrackSpec

__all__ = ["DISCRETE", "SLAB", "names", "scaled", "values"]

DISCRETE = ("pad.stiffness", "pad.damping", "sleeper_mass", "ballast.stiffness", "ballast.damping")
"""A ballasted track's calibrated parameters, in the site file's names."""

SLAB = ("pad.stiffness", "pad.damping")
"""A slab track's."""


def names(track: TrackSpec) -> tuple[str, ...]:
    """The parameters calibrated on ``track``'s kind."""
    return DISCRETE if track.kind == "discrete" else SLAB


def values(track: TrackSpec) -> tuple[float, ...]:
    """``track``'s values of ``names(track)``."""
    out = [track.pad.stiffness, track.pad.damping]
    if track.kind == "discrete":
        assert track.ballast is not None
        out += [track.sleeper_mass, track.ballast.stiffness, track.ballast.damping]
    return tuple(float(v) for v in out)


def scaled(track: TrackSpec, z: NDArray[np.float64]) -> TrackSpec:
    """``track`` with each calibrated value multiplied by exp(z_i)."""
    f = [float(v) for v in np.exp(np.asarray(z, dtype=np.float64))]
    if len(f) != len(names(track)):
        raise ValueError(f"{len(f)} log-factors for the {len(names(track))} parameters")
    pad = Support(track.pad.stiffness * f[0], track.pad.damping * f[1])
    if track.kind == "slab":
        return dataclasses.replace(track, pad=pad)
    assert track.ballast is not None
    return dataclasses.replace(
        track,
        pad=pad,
        sleeper_mass=track.sleeper_mass * f[2],
        ballast=Support(track.ballast.stiffness * f[3], track.ballast.damping * f[4]),
    )
