"""Run ``railtwin serve`` as a child process (for the demo, the benchmark and the tests).

    with ServiceProcess(site, listen=endpoint, recordings=dir) as svc:
        ...  # talk to it over Zenoh at ``endpoint``
    svc.output  # everything it printed; svc.mcap_files, svc.rrd_file

Starting waits for its "ready" line; leaving the block sends SIGTERM (the
clean shutdown path) and waits for it to finish its files.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import TracebackType

SERVE_LOG = "railtwin.serve: "
"""What the service's own log lines say after their time and level (``service.cli.logs``)."""
READY = SERVE_LOG + "ready"
MCAP_LOG = SERVE_LOG + "MCAP log "
RRD_LOG = SERVE_LOG + "Rerun recording "


class ServiceStartError(RuntimeError):
    """The service did not start or stop as it should."""


class ServiceProcess:
    def __init__(
        self,
        site: Path,
        *,
        listen: str | None,
        recordings: Path,
        extra_args: tuple[str, ...] = (),
        start_timeout: float = 300.0,
        echo: bool = False,
    ) -> None:
        self.args = [
            sys.executable,
            "-m",
            "service.cli.serve",
            "--site",
            str(site),
            *(("--listen", listen) if listen is not None else ()),  # None: --connect in extra_args
            "--recordings",
            str(recordings),
            *extra_args,
        ]
        self.start_timeout = start_timeout
        self.echo = echo
        self.lines: list[str] = []
        self._lines: queue.SimpleQueue[str | None] = queue.SimpleQueue()
        self.proc: subprocess.Popen[str] | None = None
        self.returncode: int | None = None

    def __enter__(self) -> ServiceProcess:
        self.start()
        return self

    def __exit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    def start(self) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(
            self.args,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
            cwd=Path(__file__).resolve().parents[2],
        )
        threading.Thread(target=self._pump, daemon=True).start()
        deadline = time.monotonic() + self.start_timeout
        while True:
            left = deadline - time.monotonic()
            try:
                line = self._lines.get(timeout=max(0.01, left))
            except queue.Empty:
                line = ""
            if line is None or left <= 0:
                self.stop()
                raise ServiceStartError("railtwin serve did not start:\n" + self.output)
            if READY in line:
                return

    def _pump(self) -> None:
        assert self.proc is not None and self.proc.stdout is not None
        for line in self.proc.stdout:
            line = line.rstrip("\n")
            self.lines.append(line)
            if self.echo:
                print(line, flush=True)
            self._lines.put(line)
        self._lines.put(None)

    def stop(self, timeout: float = 60.0) -> int:
        """SIGTERM, then wait; returns the exit status."""
        if self.proc is None:
            return -1
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            self.returncode = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.returncode = self.proc.wait()
        time.sleep(0.05)  # let the pump thread read the last lines
        return self.returncode

    @property
    def output(self) -> str:
        return "\n".join(self.lines)

    @property
    def mcap_files(self) -> list[Path]:
        return [Path(s.split(MCAP_LOG, 1)[1]) for s in self.lines if MCAP_LOG in s]

    @property
    def rrd_file(self) -> Path | None:
        found = [Path(s.split(RRD_LOG, 1)[1]) for s in self.lines if RRD_LOG in s]
        return found[0] if found else None
