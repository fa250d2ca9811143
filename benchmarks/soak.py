"""``make soak``: a long burst (memory must plateau), then kill -9 of every process mid-stream.

    .venv/bin/python -m benchmarks.soak [--burst 5000] [--rounds 4] [--max-growth-mb 48]
                                        [--kill-after 2000] [--skip-kill]

1. **Burst**: ``--rounds`` times, ``--burst`` passages (every 20th a bad payload) sent at
   once from this process to ``railtwin serve`` on loopback (the example site, recording
   on), each round when the previous one is answered. Checks answered + rejected = sent.
   The resident memory of each process of the service (service, recorder, physics
   worker) is sampled every 0.5 s and printed every tenth of the passages, and after
   each round once it is answered. **Asserts** that the whole tree grew by at most
   ``--max-growth-mb`` from the end of the middle round to the end of the last one
   (memory that plateaus, not memory that grows with the number of passages; before the
   recorder's queue was bounded and its ``.rrd`` split into parts, it grew ~6 MB per
   1 000 passages, 127 MB over the second half of 20 000).
2. **kill -9**: a second service gets ``--kill-after`` passages at once; after 1.5 s every
   one of its processes (service, physics worker, recorder) is killed with SIGKILL. Then
   ``railtwin recover`` turns its cut MCAP and what is left of its input journal (the
   parts not yet in a flushed MCAP chunk) into a finished log,
   and the report says how many of the inputs sent and of the results received are in it.

It runs for minutes (not part of ``make test``; the tests hold the same properties on
small numbers). Timings are noisy on shared cores; the memory figures are the point.
Nothing leaves loopback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from schemas.messages import WheelPassage
from service.cli.service_process import ServiceProcess
from service.clients.feeder import Collector, declare_passage_publisher, wait_matching
from service.recording.mcap_recover import recover, salvage
from service.wire.keyspace import SiteKeys
from service.wire.site import load_site
from service.wire.zenoh_session import build_config, free_tcp_endpoint, open_session

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "examples/site_compliant.toml"


def tree(pid: int) -> list[int]:
    """``pid`` and all its descendants (from /proc)."""
    children: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(d.name))
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(children.get(p, []))
    return out


def rss_mb(pids: list[int]) -> float:
    return sum(process_rss_mb(p) for p in pids)


def process_rss_mb(pid: int) -> float:
    """Resident memory of one process (VmRSS), MB; 0 if it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def role(pid: int, root: int) -> str:
    """service (the root), recorder (has the .rrd open), tracker (multiprocessing's
    resource tracker) or physics (a physics worker)."""
    if pid == root:
        return "service"
    try:
        if b"resource_tracker" in Path(f"/proc/{pid}/cmdline").read_bytes():
            return "tracker"
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            if os.readlink(fd).endswith(".rrd"):
                return "recorder"
    except OSError:
        pass
    return "physics"


def rss_by_role(root: int) -> dict[str, float]:
    """{role: MB} of the service's process tree (physics workers summed)."""
    out: dict[str, float] = {}
    for p in tree(root):
        r = role(p, root)
        out[r] = out.get(r, 0.0) + process_rss_mb(p)
    return out


def passages(n: int, prefix: str) -> list[bytes]:
    out = []
    for i in range(n):
        if i % 20 == 19:
            out.append(b'{"passage_id": "%s-bad%d", "speed": "fast"}' % (prefix.encode(), i))
            continue
        p = WheelPassage(
            passage_id=f"{prefix}-{i}",
            train_id=prefix,
            axle_index=i % 100,
            side="right",
            timestamp=time.time(),
            speed=44.4,
            load=50e3 + 100 * (i % 50),
            mass=600.0,
            radius=0.46,
        )
        out.append(p.model_dump_json().encode())
    return out


def answered_count(collector: Collector) -> int:
    with collector._lock:  # the subscriber's thread adds to it
        return sum(o.result_at is not None for o in collector.outcomes.values()) + len(
            collector.errors
        )


def burst(n: int, rounds: int, tmp: Path) -> dict[str, Any]:
    """``rounds`` bursts of ``n`` passages each to one service, each sent at once when the
    previous one is answered; the RSS of every process sampled every 0.5 s."""
    site = load_site(SITE)
    keys = SiteKeys(site.site_id)
    endpoint = free_tcp_endpoint()
    with (
        ServiceProcess(SITE, listen=endpoint, recordings=tmp / "burst", start_timeout=900.0) as svc,
        open_session(build_config(connect=[endpoint])) as session,
    ):
        assert svc.proc is not None
        root = svc.proc.pid
        collector = Collector(keys, decode_results=False)
        sub = session.declare_subscriber(keys.all_outputs, collector)
        pub = declare_passage_publisher(session, keys)
        wait_matching(pub, 30.0)
        samples: list[tuple[int, dict[str, float]]] = []
        journal: list[int] = []  # bytes of the input journal on disk, every 0.5 s
        stop = threading.Event()

        def watch() -> None:
            while not stop.wait(0.5):
                samples.append((answered_count(collector), rss_by_role(root)))
                journal.append(journal_bytes(tmp / "burst"))

        start_rss = rss_by_role(root)
        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        t0 = time.monotonic()
        round_end: list[dict[str, float]] = []
        for r in range(rounds):
            for data in passages(n, f"burst{r}"):
                pub.put(data)
            deadline = time.monotonic() + 900.0
            while answered_count(collector) < (r + 1) * n and time.monotonic() < deadline:
                time.sleep(0.2)
            time.sleep(1.0)  # the recorder catches up
            round_end.append(rss_by_role(root))
        elapsed = time.monotonic() - t0
        stop.set()
        watcher.join()
        sub.undeclare()
        answered = answered_count(collector)
        with collector._lock:
            results = sum(o.result_at is not None for o in collector.outcomes.values())
            rejected = len(collector.errors)
    total = n * rounds
    journal_left = journal_bytes(tmp / "burst")  # the service has stopped
    series = rss_series(samples, total, points=10)
    half = (
        round_end[len(round_end) // 2 - 1]
        if len(round_end) >= 2
        else next((m for a, m in samples if a >= total // 2), start_rss)
    )
    end = round_end[-1] if round_end else start_rss
    return {
        "sent": total,
        "results": results,
        "rejected": rejected,
        "answered": answered,
        "seconds": round(elapsed, 1),
        "passages_per_s": round(results / elapsed, 1),
        "rss_start_mb": rounded(start_rss),
        "rss_peak_mb": round(max((sum(m.values()) for _, m in samples), default=0.0)),
        "rss_at_half_mb": rounded(half),
        "rss_end_mb": rounded(end),
        "rss_after_each_round_mb": [rounded(m) for m in round_end],
        "rss_every_tenth_mb": series,
        "growth_second_half_mb": round(sum(end.values()) - sum(half.values()), 1),
        "journal_peak_mb": round(max(journal, default=0) / 2**20, 1),
        "journal_after_stop_bytes": journal_left,
        "recorder_notes": [line for line in svc.lines if "recording failures" in line],
    }


def journal_bytes(directory: Path) -> int:
    """Bytes of the input journal's parts in ``directory`` (parts come and go)."""
    total = 0
    for p in directory.glob("*.journal"):
        with contextlib.suppress(OSError):
            total += p.stat().st_size
    return total


def rounded(m: dict[str, float]) -> dict[str, float]:
    return {**{k: round(v, 1) for k, v in sorted(m.items())}, "total": round(sum(m.values()), 1)}


def rss_series(
    samples: list[tuple[int, dict[str, float]]], total: int, points: int
) -> list[dict[str, Any]]:
    """The first sample at or after each ``total/points`` passages answered."""
    out: list[dict[str, Any]] = []
    for k in range(1, points + 1):
        at = total * k // points
        found = next((m for a, m in samples if a >= at), None)
        if found is not None:
            out.append({"answered": at, **rounded(found)})
    return out


def kill_mid_stream(n: int, tmp: Path) -> dict[str, float]:
    site = load_site(SITE)
    keys = SiteKeys(site.site_id)
    endpoint = free_tcp_endpoint()
    payloads = passages(n, "kill")
    svc = ServiceProcess(SITE, listen=endpoint, recordings=tmp / "kill")
    svc.start()
    received: list[tuple[str, float]] = []
    with open_session(build_config(connect=[endpoint])) as session:

        def on_result(sample: object) -> None:
            key = str(sample.key_expr)  # type: ignore[attr-defined]
            if "/result/" in key:
                received.append((key.rsplit("/", 1)[1], time.monotonic()))

        sub = session.declare_subscriber(keys.all_outputs, on_result)
        pub = declare_passage_publisher(session, keys)
        wait_matching(pub, 30.0)
        for data in payloads:
            pub.put(data)
        time.sleep(1.5)
        pids = tree(svc.proc.pid)
        killed_at = time.monotonic()
        for p in pids:
            with contextlib.suppress(OSError):
                os.kill(p, signal.SIGKILL)
        svc.proc.wait()
        time.sleep(0.5)
        sub.undeclare()
    d = tmp / "kill"
    logs = sorted(d.glob("*.mcap"))
    journals = sorted(d.glob("*.journal"))
    journal_mb = sum(p.stat().st_size for p in journals) / 2**20
    cut_inputs = sum(1 for p in logs for m in salvage(p) if "/passage" in m.topic)
    out = d / "recovered.mcap"
    report = recover([*logs, *journals], out)
    msgs = list(salvage(out))
    inputs = {json.loads(m.data).get("passage_id") for m in msgs if m.topic.endswith("/passage")}
    results = {json.loads(m.data)["passage_id"] for m in msgs if "/result" in m.topic}
    got = {pid for pid, _ in received}
    lost_results = got - results
    late = [t for pid, t in received if pid in lost_results]
    return {
        "sent": n,
        "processes_killed": len(pids),
        "results_received": len(got),
        "inputs_in_cut_mcap": cut_inputs,
        "inputs_recovered": len(inputs),
        "inputs_from_journal_only": report.from_journal,
        "journal_parts_left": len(journals),
        "journal_left_mb": round(journal_mb, 1),
        "results_received_not_in_log": len(lost_results),
        "of_which_received_in_last_s_before_kill": sum(killed_at - t <= 1.0 for t in late),
        "answered_inputs_missing_from_log": len(got - inputs),
    }


def main() -> int:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.soak", description=__doc__.split("\n")[0]
    )
    p.add_argument("--burst", type=int, default=5_000, help="passages per round")
    p.add_argument(
        "--rounds", type=int, default=4, help="send the burst this many times to the same service"
    )
    p.add_argument(
        "--max-growth-mb",
        type=float,
        default=48.0,
        help="RSS growth of the whole tree allowed over the second half",
    )
    p.add_argument("--kill-after", type=int, default=2_000)
    p.add_argument("--skip-kill", action="store_true", help="only the burst")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        b = burst(a.burst, a.rounds, tmp)
        print("burst:", json.dumps(b, indent=1), flush=True)
        growth = b["growth_second_half_mb"]
        if b["answered"] != b["sent"] or growth > a.max_growth_mb:
            print(
                f"soak FAILED: answered {b['answered']} of {b['sent']}; the service's "
                f"processes grew by {growth:.0f} MB over the second half of the burst "
                f"(limit {a.max_growth_mb:g} MB)",
                flush=True,
            )
            return 1
        print(
            f"soak: memory bounded: {growth:+.0f} MB over the second half of "
            f"{b['sent']} passages (limit {a.max_growth_mb:g} MB)",
            flush=True,
        )
        if a.skip_kill:
            return 0
        k = kill_mid_stream(a.kill_after, tmp)
        print("kill -9:", json.dumps(k, indent=1), flush=True)
        valid = sum(1 for i in range(a.kill_after) if i % 20 != 19)
        if k["results_received_not_in_log"] or k["answered_inputs_missing_from_log"]:
            print(
                "soak FAILED: the recovered log lacks results or inputs the service had answered",
                flush=True,
            )
            return 1
        print(
            f"soak: kill -9 recovered {k['inputs_recovered']:.0f} of {valid} valid inputs "
            f"sent and every result received",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
