"""Realtime pacing: a passage's series go out in chunks as the wheel would reach their end,
its result when the wheel leaves the site (``railtwin serve --pace realtime``)."""

from __future__ import annotations

import heapq
import threading
import time
from dataclasses import dataclass, field

from pydantic import BaseModel

from service.twin.output import Output


@dataclass(order=True)
class _Due:
    """A paced publication: at ``due`` (monotonic s)."""

    due: float
    seq: int
    key: str = field(compare=False)
    model: type[BaseModel] = field(compare=False)
    data: bytes = field(compare=False)


class Pacer:
    """A thread that publishes what is scheduled when it is due."""

    def __init__(self, output: Output) -> None:
        self.output = output
        self._due: list[_Due] = []
        self._seq = 0
        self._cv = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="railtwin-pacer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Publish what is still scheduled at once, then end the thread."""
        if self._thread is None:
            return
        with self._cv:
            self._stopping = True
            self._cv.notify()
        self._thread.join()

    def schedule(self, due: float, key: str, model: type[BaseModel], data: bytes) -> None:
        with self._cv:
            self._seq += 1
            heapq.heappush(self._due, _Due(due, self._seq, key, model, data))
            self._cv.notify()

    def _run(self) -> None:
        keys = self.output.keys
        while True:
            with self._cv:
                while True:
                    if self._stopping and not self._due:
                        return
                    now = time.monotonic()
                    if self._due and (self._due[0].due <= now or self._stopping):
                        item = heapq.heappop(self._due)
                        break
                    timeout = self._due[0].due - now if self._due else None
                    self._cv.wait(timeout)
            kind = keys.kind_of(item.key) or "output"
            self.output.put(item.key, f"{keys.prefix}/{kind}", item.model, item.data)
