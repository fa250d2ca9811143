"""The reduced track's disk cache: the same model back, a broken entry replaced, an off switch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_core.track import store
from sim_core.track.modal import ModalTrack, _reduce, reduce_track
from sim_core.track.spec import Support, TrackSpec

TRACK = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))


def _fresh(x1: float) -> ModalTrack:
    _reduce.cache_clear()
    return reduce_track(TRACK, 0.0, x1, cutoff=1500.0)


def test_a_kept_reduction_is_the_computed_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    a = _fresh(1.2)
    assert len(list(tmp_path.glob(f"*{store.SUFFIX}"))) == 1
    b = _fresh(1.2)
    assert a is not b
    for f in ("lam", "rows", "resid", "bubble", "crib_rows"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    assert a.static_compliance(0.3) == b.static_compliance(0.3)


def test_a_broken_entry_is_recomputed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    a = _fresh(1.8)
    (entry,) = tmp_path.glob(f"*{store.SUFFIX}")
    good = entry.read_bytes()
    damaged = good[:-9] + bytes([good[-9] ^ 1]) + good[-8:]
    for broken in (b"not a zip", b"", good[: len(good) // 2], damaged):
        entry.write_bytes(broken)
        b = _fresh(1.8)
        assert np.array_equal(a.lam, b.lam)
        assert store.load(entry.stem) is not None  # rewritten
    assert not list(tmp_path.glob("*.tmp"))


def test_off_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", "off")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    _fresh(2.4)
    assert not list(tmp_path.rglob(f"*{store.SUFFIX}"))
