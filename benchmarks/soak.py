"""``make soak``: a burst of 10 000 passages, then kill -9 of every process mid-stream.

    .venv/bin/python -m benchmarks.soak [--burst 10000] [--kill-after 2000]

1. **Burst**: ``--burst`` passages (every 20th a bad payload) sent at once from this
   process to ``railtwin serve`` on loopback (the example site, recording on). Checks
   answered + rejected = sent, and samples the resident memory of the service's whole
   process tree every 0.5 s.
2. **kill -9**: a second service gets ``--kill-after`` passages at once; after 1.5 s every
   one of its processes (service, physics worker, recorder) is killed with SIGKILL. Then
   ``railtwin recover`` turns its cut MCAP and its input journal into a finished log,
   and the report says how many of the inputs sent and of the results received are in it.

Prints a table; asserts nothing (it runs for minutes; the tests hold the same properties
on small numbers). Nothing leaves loopback.
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

from schemas.messages import WheelPassage
from service.feeder import Collector, declare_passage_publisher, wait_matching
from service.keyspace import SiteKeys
from service.mcap_recover import recover, salvage
from service.service_process import ServiceProcess
from service.site import load_site
from service.zenoh_session import build_config, free_tcp_endpoint, open_session

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "examples/site.toml"


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
    total = 0
    for p in pids:
        try:
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1])
        except OSError:
            continue
    return total / 1024


def passages(n: int, prefix: str) -> list[bytes]:
    out = []
    for i in range(n):
        if i % 20 == 19:
            out.append(b'{"passage_id": "%s-bad%d", "speed": "fast"}' % (prefix.encode(), i))
            continue
        p = WheelPassage(passage_id=f"{prefix}-{i}", train_id=prefix, axle_index=i % 100,
                         side="right", timestamp=time.time(), speed=44.4,
                         load=50e3 + 100 * (i % 50), mass=600.0, radius=0.46)
        out.append(p.model_dump_json().encode())
    return out


def burst(n: int, tmp: Path) -> dict[str, float]:
    site = load_site(SITE)
    keys = SiteKeys(site.site_id)
    endpoint = free_tcp_endpoint()
    payloads = passages(n, "burst")
    with ServiceProcess(SITE, listen=endpoint, recordings=tmp / "burst") as svc, \
            open_session(build_config(connect=[endpoint])) as session:
        collector = Collector(keys, decode_results=False)
        sub = session.declare_subscriber(keys.all_outputs, collector)
        pub = declare_passage_publisher(session, keys)
        wait_matching(pub, 30.0)
        pids = tree(svc.proc.pid)
        peak, samples = 0.0, []
        stop = threading.Event()

        def watch() -> None:
            nonlocal peak
            while not stop.wait(0.5):
                m = rss_mb(tree(svc.proc.pid))
                samples.append(m)
                peak = max(peak, m)

        watcher = threading.Thread(target=watch, daemon=True)
        start_rss = rss_mb(pids)
        watcher.start()
        t0 = time.monotonic()
        for data in payloads:
            pub.put(data)
        deadline = time.monotonic() + 900.0
        answered = 0
        while time.monotonic() < deadline:
            with collector._lock:  # the subscriber's thread adds to it
                answered = (sum(o.result_at is not None for o in collector.outcomes.values())
                            + len(collector.errors))
            if answered >= n:
                break
            time.sleep(0.2)
        elapsed = time.monotonic() - t0
        stop.set()
        watcher.join()
        sub.undeclare()
        with collector._lock:
            results = sum(o.result_at is not None for o in collector.outcomes.values())
    return {"sent": n, "results": results, "rejected": len(collector.errors),
            "answered": answered, "seconds": elapsed, "passages_per_s": results / elapsed,
            "rss_start_mb": start_rss, "rss_peak_mb": peak,
            "rss_end_mb": samples[-1] if samples else start_rss}


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
    cut_inputs = sum(1 for p in logs for m in salvage(p) if "/passage" in m.topic)
    out = d / "recovered.mcap"
    report = recover([*logs, *journals], out)
    msgs = list(salvage(out))
    inputs = {json.loads(m.data).get("passage_id") for m in msgs if m.topic.endswith("/passage")}
    results = {json.loads(m.data)["passage_id"] for m in msgs if "/result" in m.topic}
    got = {pid for pid, _ in received}
    lost_results = got - results
    late = [t for pid, t in received if pid in lost_results]
    return {"sent": n, "processes_killed": len(pids), "results_received": len(got),
            "inputs_in_cut_mcap": cut_inputs, "inputs_recovered": len(inputs),
            "inputs_from_journal_only": report.from_journal,
            "results_received_not_in_log": len(lost_results),
            "of_which_received_in_last_s_before_kill": sum(killed_at - t <= 1.0 for t in late),
            "answered_inputs_missing_from_log": len(got - inputs)}


def main() -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.soak", description=__doc__.split("\n")[0])
    p.add_argument("--burst", type=int, default=10_000)
    p.add_argument("--kill-after", type=int, default=2_000)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        b = burst(a.burst, tmp)
        print("burst:", json.dumps(b, indent=1), flush=True)
        k = kill_mid_stream(a.kill_after, tmp)
        print("kill -9:", json.dumps(k, indent=1), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
