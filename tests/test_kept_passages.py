"""The twin's kept passages are bounded in number and in bytes (a long run's memory)."""

from __future__ import annotations

import doctest

import pytest

import service.twin.kept_passages
from service.twin.kept_passages import KeptPassages


def test_bounded_in_number_and_in_bytes() -> None:
    kept: KeptPassages[int] = KeptPassages(max_count=100, max_bytes=10_000)
    for i in range(1000):  # small passages: the count bounds
        kept.add(f"p{i}", i, 10)
    assert len(kept) == 100 and kept.bytes == 1000
    assert list(kept) == [f"p{i}" for i in range(900, 1000)]
    for i in range(1000, 1100):  # sampled outlines: the bytes bound
        kept.add(f"p{i}", i, 3000)
    assert len(kept) == 3 and kept.bytes == 9000
    assert kept.get("p1099") == 1099 and "p999" not in kept


def test_a_passage_seen_again_is_the_newest_and_counted_once() -> None:
    kept: KeptPassages[str] = KeptPassages(max_count=2, max_bytes=100)
    kept.add("a", "first", 40)
    kept.add("b", "b", 40)
    kept.add("a", "again", 50)  # "b" is now the oldest
    kept.add("c", "c", 10)
    assert list(kept) == ["a", "c"] and kept.bytes == 60 and kept.get("a") == "again"


def test_the_newest_stays_however_large() -> None:
    kept: KeptPassages[str] = KeptPassages(max_count=10, max_bytes=100)
    kept.add("small", "s", 10)
    kept.add("huge", "h", 1000)
    assert list(kept) == ["huge"] and kept.bytes == 1000


def test_bounds_must_make_sense() -> None:
    with pytest.raises(ValueError, match="max_count must be >= 1"):
        KeptPassages(max_count=0)


def test_the_worked_example_holds() -> None:
    result = doctest.testmod(service.twin.kept_passages)
    assert result.attempted >= 1 and result.failed == 0
