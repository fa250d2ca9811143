"""The modes' arrays padded and aligned for the stepper's vector loops (``sim_core.track.lanes``)."""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.track import lanes
from sim_core.track.stepper import MODE_DTYPE


@pytest.mark.parametrize(
    ("m", "padded"), [(0, 0), (1, 16), (15, 16), (16, 16), (17, 32), (401, 416)]
)
def test_padded_size_rounds_up_to_a_cache_line(m: int, padded: int) -> None:
    assert lanes.padded_size(m) == padded


def test_padded_size_refuses_a_negative_count() -> None:
    with pytest.raises(ValueError, match="number of modes"):
        lanes.padded_size(-1)


@pytest.mark.parametrize("shape", [(7,), (3, 416), (2, 5, 32)])
def test_aligned_zeros_start_on_a_cache_line(shape: tuple[int, ...]) -> None:
    for dtype in (np.float32, np.float64):
        a = lanes.aligned_zeros(shape, dtype)
        assert a.shape == shape and a.dtype == dtype and a.flags.c_contiguous
        assert a.ctypes.data % lanes.ALIGN == 0
        assert not a.any()


def test_padded_modes_keep_the_modes_and_pad_every_row() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, 401))
    p = lanes.padded_modes(a, MODE_DTYPE, fill=lanes.PAD_LAMBDA)
    assert p.shape == (5, 416) and p.dtype == MODE_DTYPE
    np.testing.assert_array_equal(p[:, :401], a.astype(MODE_DTYPE))
    assert np.all(p[:, 401:] == np.float32(lanes.PAD_LAMBDA))
    # every row starts on a cache line
    assert p.ctypes.data % lanes.ALIGN == 0 and p.strides[0] % lanes.ALIGN == 0


def test_the_reduced_track_pads_with_inert_modes() -> None:
    """``ModalTrack.arrays``: padding modes decay (λ = PAD_LAMBDA) and carry no load and no
    deflection (zero rows), so that a zero state stays zero."""
    from sim_core.track.modal import reduce_track
    from sim_core.track.spec import Support, TrackSpec

    track = TrackSpec.discrete(
        sleeper_spacing=0.6,
        first_sleeper=0.3,
        pad=Support(2.0e8, 3.0e4),
        sleeper_mass=150.0,
        ballast=Support(1.2e8, 8.0e4),
    )
    mt = reduce_track(track, 0.0, 1.2, (), cutoff=2000.0)
    md = mt.arrays
    m = mt.n_modes
    mp = lanes.padded_size(m)
    for arr in (md.lam_r, md.lam_i, md.row_r, md.row_i):
        assert arr.shape[-1] == mp
        assert arr.ctypes.data % lanes.ALIGN == 0
    assert np.all(md.lam_r[m:] == np.float32(lanes.PAD_LAMBDA))
    assert not md.lam_i[m:].any() and not md.row_r[:, m:].any() and not md.row_i[:, m:].any()
    np.testing.assert_array_equal(md.lam_r[:m], mt.lam.real.astype(MODE_DTYPE))


def test_padded_parts_are_the_two_padded_modes_to_the_bit() -> None:
    rng = np.random.default_rng(9)
    for shape in [(401,), (3, 401), (2, 5, 17), (0, 33)]:
        a = rng.normal(size=shape) + 1j * rng.normal(size=shape)
        r, i = lanes.padded_parts(a, MODE_DTYPE, fill=lanes.PAD_LAMBDA)
        np.testing.assert_array_equal(r, lanes.padded_modes(a.real, MODE_DTYPE, lanes.PAD_LAMBDA))
        np.testing.assert_array_equal(i, lanes.padded_modes(a.imag, MODE_DTYPE))
        if r.size:
            assert r.ctypes.data % lanes.ALIGN == 0 and i.ctypes.data % lanes.ALIGN == 0
    # a strided view (the real part of a complex array's transpose) reads the same
    a = rng.normal(size=(40, 7)) + 1j * rng.normal(size=(40, 7))
    r, i = lanes.padded_parts(a.T, MODE_DTYPE)
    np.testing.assert_array_equal(r[:, :40], a.T.real.astype(MODE_DTYPE))
