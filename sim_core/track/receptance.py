"""The track's point receptance α(f) = w/F at a rail position: from the finite-element model
directly, and from the reduced modal model (what the stepper integrates).

The direct one solves (K + iωC − ω²M)·u = N(x) per frequency; the modal one sums the
kept complex modes and adds the static residual. Their agreement up to the cutoff is
the reduction's own check; the direct one against ROSE's is the model's
(``validation/track_validation.py``, docs/MODEL.md §8).

Worked example (at 0 Hz both are the static compliance):

    >>> import numpy as np
    >>> from sim_core.track.spec import Support, TrackSpec
    >>> from sim_core.track.modal import reduce_track
    >>> t = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))
    >>> mt = reduce_track(t, 0.0, 1.2, cutoff=2000.0)
    >>> a = modal_receptance(mt, 0.3, np.array([0.0]))[0]
    >>> bool(abs(a.real / mt.static_compliance(0.3) - 1) < 1e-9)
    True
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from sim_core.track.assembly import assemble
from sim_core.track.modal import ModalTrack


def _load_vector(mt: ModalTrack, x: float, n_dofs: int) -> NDArray[np.float64]:
    e, n = mt.shapes_at(x)
    d = 2 * (e + mt.first_element)
    b = np.zeros(n_dofs)
    b[d : d + 4] = n
    return b


def fe_receptance(mt: ModalTrack, x: float, freqs: NDArray[np.float64]) -> NDArray[np.complex128]:
    """α(f) of the full finite-element model at x, m/N (a downward force, a downward deflection)."""
    mats = assemble(mt.track, mt.layout)
    b = _load_vector(mt, x, mats.k.shape[0])
    out = np.empty(freqs.size, dtype=np.complex128)
    for i, f in enumerate(freqs):
        w = 2.0 * np.pi * f
        u = sla.solve(mats.k + 1j * w * mats.c - w * w * mats.m, b.astype(np.complex128))
        out[i] = b @ u
    # the element's local deflection under a load between its nodes, as the reduced model has
    return out + mt.bubble_compliance(x)


def modal_receptance(
    mt: ModalTrack, x: float, freqs: NDArray[np.float64]
) -> NDArray[np.complex128]:
    """α(f) of the reduced model at x (modes plus the static residual), m/N."""
    r = mt.rows_at(x)
    s = 2j * np.pi * np.asarray(freqs)[:, None]
    # ζ = R·F/(s − λ) for a unit downward force; its downward deflection is −Σ Re(R·ζ)
    # taken as the analytic continuation: a pair (λ, λ̄), whose R² holds the weight 2, gives
    # (R²/2)/(s−λ) + conj(R²/2)/(s−λ̄)
    hg = r * r / mt.weight
    pair = mt.weight > 1.0
    terms = np.where(
        pair, hg / (s - mt.lam) + np.conj(hg) / (s - np.conj(mt.lam)), hg / (s - mt.lam)
    )
    return -terms.sum(axis=1) + mt.residual_compliance(x)
