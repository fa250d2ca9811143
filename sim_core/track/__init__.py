"""A rail on discrete supports or a slab, and the detector's crib channels (MODEL.md §8).

``TrackSpec`` is one of the kinds of ``sim_core.under_rail.UnderRail``; the passage goes
through ``sim_core.passage.simulate_passage`` like any other.

- ``spec``: the track and the cribs as data (``TrackSpec``, ``RailSection``, ``Support``, ``Crib``);
- ``beam``: one rail element's matrices and shape functions (Timoshenko / Euler–Bernoulli);
- ``layout``: the finite stretch standing for the endless track (absorbing ends);
- ``assembly``: the track's M, C, K from its parts;
- ``modal``: the reduction to complex modes with the static residual (``ModalTrack``);
- ``store``: reductions kept on disk, one file a track, stretch and cribs;
- ``stepper``: the compiled exact-mode stepper with located contact events;
- ``passage``: one passage end to end (``simulate_on_track``);
- ``receptance``: the track's point receptance, from the FE model and from the reduced one.
"""

from sim_core.track.spec import (
    MAX_CRIBS,
    Crib,
    RailSection,
    Support,
    TrackError,
    TrackSpec,
    check_cribs,
)

__all__ = ["MAX_CRIBS", "Crib", "RailSection", "Support", "TrackError", "TrackSpec", "check_cribs"]
