"""A rail on discrete supports or a slab, and the detector's crib channels (MODEL.md §8).

- ``spec``: the track and the cribs as data (``TrackSpec``, ``RailSection``, ``Support``, ``Crib``);
- ``beam``: one rail element's matrices and shape functions (Timoshenko / Euler–Bernoulli);
- ``layout``: the finite stretch standing for the endless track (absorbing ends);
- ``assembly``: the track's M, C, K from its parts;
- ``modal``: the reduction to complex modes with the static residual (``ModalTrack``);
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
