"""Progress of long work on stderr: a bar with rate and ETA on a terminal, a line every
``every`` seconds otherwise (logs, CI).

    >>> import io
    >>> out = io.StringIO()
    >>> p = Progress(4, "passages", out, prefix="railtwin reanalyse", every=0.0)
    >>> p.advance(2); p.close()
    >>> "2/4 passages" in out.getvalue()
    True
"""

from __future__ import annotations

import math
import sys
import time
from typing import IO

BAR = 24


def duration_text(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``2 h 07 min``."""
    if not math.isfinite(seconds):
        return "?"
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Progress:
    """Counts work done out of ``total`` and shows it (see module doc)."""

    def __init__(
        self,
        total: int,
        unit: str,
        stream: IO[str] | None = None,
        *,
        prefix: str = "railtwin",
        every: float = 10.0,
        done: int = 0,
    ) -> None:
        self.total = total
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty()
        self.prefix = prefix
        self.every = every
        self.done = done
        self._start_done = done
        self._start = time.monotonic()
        self._last = -math.inf
        self._dirty = False

    def line(self) -> str:
        elapsed = time.monotonic() - self._start
        made = self.done - self._start_done
        rate = made / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else math.inf
        text = f"{self.done}/{self.total} {self.unit}, {rate:.1f}/s, ETA {duration_text(left)}"
        if self.tty:
            filled = BAR * self.done // max(self.total, 1)
            return f"{self.prefix}: [{'#' * filled}{'.' * (BAR - filled)}] {text}"
        return f"{self.prefix}: {text}"

    def advance(self, n: int = 1) -> None:
        self.done += n
        now = time.monotonic()
        if self.tty:
            if now - self._last >= 0.1 or self.done >= self.total:
                self.stream.write("\r" + self.line() + "\033[K")
                self._dirty = True
                self._last = now
        elif now - self._last >= self.every or self.done >= self.total:
            self.stream.write(self.line() + "\n")
            self._last = now
        self.stream.flush()

    def close(self) -> None:
        if self._dirty:
            self.stream.write("\n")
            self.stream.flush()
            self._dirty = False
