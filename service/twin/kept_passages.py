"""The latest valid passages, by id, bounded in number and in bytes.

The twin keeps them to pair a measurement that arrives after its passage and to
refuse a passage id received earlier in the run. A round wheel's passage takes
~2 kB in memory, but one with a sampled outline of 4 096 points ~260 kB (its JSON
~160 kB): 10 000 of those would hold 2.6 GB, so the bound is in bytes of JSON too.

>>> kept = KeptPassages(max_count=3, max_bytes=1000)
>>> for pid, size in (("a", 100), ("b", 100), ("c", 700), ("d", 300)):
...     kept.add(pid, f"passage {pid}", size)
>>> list(kept), kept.bytes          # "a" and "b" went: 700 + 300 = 1000 bytes
(['c', 'd'], 1000)
>>> kept.get("c"), kept.get("a")
('passage c', None)
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator
from typing import Generic, TypeVar

T = TypeVar("T")

KEPT_PASSAGES = 10_000
"""Valid passages kept (by id, the latest) for measurements that arrive after them."""
KEPT_PASSAGE_BYTES = 64 * 2**20
"""...and at most this many bytes of their JSON (the oldest go first)."""


class KeptPassages(Generic[T]):
    """An insertion-ordered map id → passage; the oldest go past ``max_count`` or
    ``max_bytes`` (the newest always stays, however large)."""

    def __init__(self, max_count: int = KEPT_PASSAGES, max_bytes: int = KEPT_PASSAGE_BYTES) -> None:
        if max_count < 1 or max_bytes < 0:
            raise ValueError(
                f"max_count must be >= 1 and max_bytes >= 0, not {max_count} and {max_bytes}"
            )
        self.max_count = max_count
        self.max_bytes = max_bytes
        self.bytes = 0
        self._kept: OrderedDict[str, tuple[T, int]] = OrderedDict()

    def add(self, passage_id: str, passage: T, nbytes: int) -> None:
        """Keep ``passage`` (``nbytes`` of JSON) as the newest; drop the oldest beyond the bounds."""
        old = self._kept.pop(passage_id, None)
        if old is not None:
            self.bytes -= old[1]
        self._kept[passage_id] = (passage, nbytes)
        self.bytes += nbytes
        while len(self._kept) > self.max_count or (
            self.bytes > self.max_bytes and len(self._kept) > 1
        ):
            _, (_, gone) = self._kept.popitem(last=False)
            self.bytes -= gone

    def get(self, passage_id: str) -> T | None:
        kept = self._kept.get(passage_id)
        return kept[0] if kept is not None else None

    def __contains__(self, passage_id: object) -> bool:
        return passage_id in self._kept

    def __iter__(self) -> Iterator[str]:
        return iter(self._kept)

    def __len__(self) -> int:
        return len(self._kept)
