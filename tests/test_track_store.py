"""The reduced track's disk cache: the same model back, a broken entry replaced, an off switch."""

from __future__ import annotations

from collections import OrderedDict
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


def test_the_cache_is_bounded_least_recently_used_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """At its bound the cache drops the entry read longest ago (a read touches it), and
    earlier formats' entries first; the entry just written always stays, and a file the cache
    did not write is never touched."""
    import os

    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    monkeypatch.delenv("RAILTWIN_TRACK_CACHE_MAX_MB", raising=False)
    arrays = {"a": np.zeros(1000)}
    store.save("one", arrays)
    store.save("two", arrays)
    legacy = tmp_path / f"{'0' * store.KEY_LENGTH}.npz"  # an earlier format's entry
    legacy.write_bytes(b"x" * 100)
    foreign = tmp_path / "mine.npz"  # the user's own file in the directory
    foreign.write_bytes(b"y" * 100)
    size = (tmp_path / f"one{store.SUFFIX}").stat().st_size
    # "one" written before "two", then read: "two" is now the least recently used
    os.utime(tmp_path / f"one{store.SUFFIX}", (900.0, 900.0))
    os.utime(tmp_path / f"two{store.SUFFIX}", (1000.0, 1000.0))
    assert store.load("one") is not None  # touches it
    # room for two entries and the legacy file: the least recently used alone would leave
    # the legacy file; it goes first, then "two"
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE_MAX_MB", str((2 * size + 100) / 1024 / 1024))
    store.save("three", arrays)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["mine.npz", f"one{store.SUFFIX}", f"three{store.SUFFIX}"]
    # exactly at the bound nothing more goes; a bound of 0 keeps only the entry just written
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE_MAX_MB", str(2 * size / 1024 / 1024))
    assert store.evict(tmp_path) == 0
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE_MAX_MB", "0")
    store.save("four", arrays)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"four{store.SUFFIX}", "mine.npz"]
    # an unreadable bound is the default, never an error
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE_MAX_MB", "lots")
    assert store.max_bytes() == store.MAX_MB * 1024 * 1024


def test_workers_evicting_at_once_delete_no_more_than_needed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An entry another worker deleted between this one's scan and its unlink counts as gone:
    one entry over the bound costs one entry, not one a worker."""
    import os

    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    monkeypatch.delenv("RAILTWIN_TRACK_CACHE_MAX_MB", raising=False)
    for i in range(5):
        store.save(f"e{i}", {"a": np.zeros(1000)})
        os.utime(tmp_path / f"e{i}{store.SUFFIX}", (1000.0 + i, 1000.0 + i))
    size = (tmp_path / f"e0{store.SUFFIX}").stat().st_size
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE_MAX_MB", str(4 * size / 1024 / 1024))
    unlink = os.unlink

    def raced(path: str | os.PathLike[str]) -> None:
        unlink(path)  # the other worker got there first
        raise FileNotFoundError(path)

    monkeypatch.setattr(os, "unlink", raced)
    assert store.evict(tmp_path) == 0  # this worker deleted nothing itself
    monkeypatch.setattr(os, "unlink", unlink)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        f"e{i}{store.SUFFIX}" for i in range(1, 5)
    ]


def test_a_crashed_writers_file_is_cleaned_when_stale(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A ``.tmp`` left by a writer that died before its rename goes at the next eviction once
    older than ``STALE_TMP_S``; a fresh one (a writer at work) stays."""
    import os

    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    stale = tmp_path / "abc.tmp"
    fresh = tmp_path / "def.tmp"
    stale.write_bytes(b"x")
    fresh.write_bytes(b"y")
    old = stale.stat().st_mtime - store.STALE_TMP_S - 10.0
    os.utime(stale, (old, old))
    store.save("k" * 40, {"a": np.zeros(4)})
    assert not stale.exists()
    assert fresh.exists()


def test_an_entry_served_from_memory_is_still_marked_used(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A long-running twin reads its track once and then serves it from memory: its entry's
    mtime is still refreshed (every ``TOUCH_INTERVAL`` at most), so that the bound evicts
    other entries before the one in use."""
    import os

    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    monkeypatch.setattr(store, "_touched", OrderedDict())
    a = _fresh(1.5)
    (entry,) = tmp_path.glob(f"*{store.SUFFIX}")
    os.utime(entry, (1e9, 1e9))  # 2001: the least recently used of any cache
    assert reduce_track(TRACK, 0.0, 1.5, cutoff=1500.0) is a  # from memory, not the file
    assert entry.stat().st_mtime == 1e9  # touched with the write, not again within the interval
    monkeypatch.setattr(store, "_touched", OrderedDict())  # the interval has passed
    assert reduce_track(TRACK, 0.0, 1.5, cutoff=1500.0) is a
    assert entry.stat().st_mtime > 1e9
    assert not store.touch(("no such track",))  # no such entry: nothing, no error


def test_touch_remembers_the_most_recent_entries_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``touch`` keeps the last touch of at most ``TOUCHED_KEPT`` entries (a calibrating twin
    makes a new one each step): at the bound all are kept; one more forgets the oldest,
    which is then touched again on its next use."""
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    monkeypatch.setattr(store, "_touched", OrderedDict())
    keys = [("track", i) for i in range(store.TOUCHED_KEPT + 1)]
    for k in keys:
        (tmp_path / f"{store.key(k)}{store.SUFFIX}").write_bytes(b"x")
    for k in keys[:-1]:
        assert store.touch(k)
    assert len(store._touched) == store.TOUCHED_KEPT
    assert not store.touch(keys[0])  # remembered: within the interval, not touched again
    assert store.touch(keys[-1])  # one more: the one touched longest ago (keys[0]) goes
    assert len(store._touched) == store.TOUCHED_KEPT
    assert keys[0] not in store._touched and keys[1] in store._touched
    assert store.touch(keys[0])  # forgotten: touched again


def test_an_entry_keeps_its_layout_and_its_arrays_start_on_cache_lines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A reduction read back has the layout the track makes (nodes, sleepers, absorbers), not
    made again, even with a gauge a hair below a sleeper; every array read lies on a cache
    line."""
    from sim_core.track.spec import Crib

    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    cribs = (Crib("c1", 1.2 - 1e-9, 1.4),)  # a gauge 1e-9 below the sleeper at 1.2
    _reduce.cache_clear()
    a = reduce_track(TRACK, 0.0, 1.8, cribs, cutoff=1500.0)
    # the layout's quirk the entry must keep: that sleeper's node is the gauge's, 1e-9 away
    assert tuple(a.layout.x[a.layout.sleeper_nodes].tolist()) != a.layout.sleepers
    _reduce.cache_clear()
    b = reduce_track(TRACK, 0.0, 1.8, cribs, cutoff=1500.0)
    assert a is not b
    for f in ("x", "sleeper_nodes", "absorb"):
        assert np.array_equal(getattr(a.layout, f), getattr(b.layout, f))
    assert a.layout.sleepers == b.layout.sleepers
    (entry,) = tmp_path.glob(f"*{store.SUFFIX}")
    arrays = store.load(entry.stem)
    assert arrays is not None
    assert all(v.ctypes.data % store.ALIGN == 0 for v in arrays.values() if v.ndim and v.size)


def test_an_entry_whose_layout_does_not_fit_is_made_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An entry that passes its CRC but whose layout arrays do not fit together (a sleeper node
    past the nodes) is not used: the reduction is made again and the entry rewritten."""
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", str(tmp_path))
    a = _fresh(1.8)
    (entry,) = tmp_path.glob(f"*{store.SUFFIX}")
    arrays = store.load(entry.stem)
    assert arrays is not None
    bad = {k: np.array(v) for k, v in arrays.items()}
    bad["sleeper_nodes"][-1] = bad["x"].size + 5
    store.save(entry.stem, bad)
    b = _fresh(1.8)
    assert np.array_equal(a.lam, b.lam) and a.layout.sleepers == b.layout.sleepers
    again = store.load(entry.stem)
    assert again is not None and int(again["sleeper_nodes"][-1]) < again["x"].size
