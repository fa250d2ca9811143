"""The cribs' rail inertia, added a block of samples and four cribs at a time
(``sim_core.track.stepper._crib_inertia``), against the plain sum Σ Re(A_i·ζ̇)."""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.track.lanes import aligned_zeros, padded_size
from sim_core.track.modal import reduce_track
from sim_core.track.spec import Crib, Support, TrackSpec
from sim_core.track.stepper import CRIB_GROUP, MODE_DTYPE, RATE_BLOCK, _crib_inertia


def _five_cribs() -> tuple[Crib, ...]:
    return tuple(Crib(f"c{i}", 0.4 + 0.6 * i, 0.5 + 0.6 * i) for i in range(5))


@pytest.fixture(scope="module")
def modes():  # type: ignore[no-untyped-def]
    track = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))
    return reduce_track(track, 0.0, 3.0, _five_cribs(), cutoff=1500.0)


def test_crib_rows_are_padded_with_zero_rows_to_whole_groups(modes) -> None:  # type: ignore[no-untyped-def]
    md = modes.arrays
    assert md.crib_lo.size == 5
    assert md.crib_r.shape[0] == md.crib_i.shape[0] == 8 and 8 % CRIB_GROUP == 0
    assert not md.crib_r[5:].any() and not md.crib_i[5:].any()


@pytest.mark.parametrize("count", [1, 7, RATE_BLOCK])
def test_block_adds_each_cribs_inertia_to_its_own_samples(modes, count: int) -> None:  # type: ignore[no-untyped-def]
    md = modes.arrays
    m = padded_size(modes.n_modes)
    rng = np.random.default_rng(count)
    rates = aligned_zeros((2 * RATE_BLOCK, m), MODE_DTYPE)
    rates[: 2 * count, : modes.n_modes] = rng.normal(size=(2 * count, modes.n_modes))
    first = 3
    channels = np.zeros((first + count + 2, 5))
    channels[first : first + count] = 1.0  # the load term already there
    _crib_inertia(md, rates, channels, first, count)
    a = modes.crib_rows.reshape(5, modes.n_modes)
    zd = rates[0 : 2 * count : 2, : modes.n_modes] + 1j * rates[1 : 2 * count : 2, : modes.n_modes]
    want = 1.0 + (zd.astype(np.complex128) @ a.T).real
    scale = np.abs(zd) @ np.abs(a.T) + 1.0
    assert np.all(np.abs(channels[first : first + count] - want) <= 1e-5 * scale)
    # the samples before and after the block are left alone
    assert not channels[:first].any() and not channels[first + count :].any()
