"""Re-analysis on a real Dask cluster (a LocalCluster of 2 worker processes) over an archive
written by the twin's own MCAP writer: pairing across rotated parts, idempotence, results
bitwise those of one process, a worker killed mid-run, the whole run killed with -9 and
resumed, and bad input answered in one line with exit status 2."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import pytest

from schemas.site import SiteConfig
from service.cli.common import CommandError
from service.distributed.archive import Archive, read_archive
from service.distributed.archive_gen import Template, templates, write_archive
from service.distributed.cluster import ClusterInfo, open_client
from service.distributed.reanalysis import DirSink, StoreSink, reanalyse
from service.distributed.tasks import WarmUp, diagnose_batch
from service.fleet.store import Reanalysed, open_store
from service.physics.model_version import model_version
from service.wire.site import load_site

ROOT = Path(__file__).resolve().parents[1]
SITE_FILE = ROOT / "examples" / "site_compliant.toml"
PASSAGES = 16


@pytest.fixture(scope="module")
def site() -> SiteConfig:
    return load_site(SITE_FILE)


@pytest.fixture(scope="module")
def pool(site: SiteConfig) -> list[Template]:
    return templates(site, 8, flat_every=4)


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory, site: SiteConfig, pool: list[Template]) -> Path:
    d = tmp_path_factory.mktemp("archive")
    files = write_archive(site, d, PASSAGES, pool, max_mb=0.1)
    assert len(files) > 1, "the archive should be in rotated parts"
    return d


@pytest.fixture(scope="module")
def archive(logs: Path, site: SiteConfig) -> Archive:
    return read_archive([logs], site.site_id, site.diagnosis.pairing_timeout)


@pytest.fixture(scope="module")
def cluster(site: SiteConfig) -> Iterator[tuple[object, ClusterInfo]]:
    with open_client(workers=2, warm=WarmUp(site.model_dump_json())) as c:
        yield c


def _body(text: str | None) -> dict[str, object]:
    assert text is not None
    doc: dict[str, object] = json.loads(text)
    doc.pop("wall_time")
    return doc


def test_the_archive_is_read_across_its_parts_and_paired(archive: Archive) -> None:
    assert len(archive.files) > 1
    assert (len(archive.pairs), archive.passages, archive.measurements) == (PASSAGES,) * 3
    assert archive.unpaired_passages == archive.unpaired_measurements == archive.duplicates == 0


def test_reanalysis_is_idempotent_and_bitwise_one_process(
    tmp_path: Path, site: SiteConfig, archive: Archive, cluster: tuple[object, ClusterInfo]
) -> None:
    client, info = cluster
    version = model_version(site)
    db = str(tmp_path / "fleet.db")
    sink = StoreSink(open_store(db), site.site_id, version.key)
    first = reanalyse(client, info, archive, site, version, sink, batch=3)  # type: ignore[arg-type]
    assert first.diagnosed == PASSAGES and first.failed == 0 and first.tasks == 6
    rows = sink.rows()
    assert len(rows) == PASSAGES and sink.store.count() == PASSAGES
    assert sum(first.by_verdict[v].get("passages", 0) for v in first.by_verdict) == PASSAGES
    again = reanalyse(client, info, archive, site, version, sink)  # type: ignore[arg-type]
    assert again.diagnosed == 0 and again.already_stored == PASSAGES
    assert len(sink.rows()) == PASSAGES and sink.store.count() == PASSAGES
    assert again.by_verdict == first.by_verdict
    # every diagnosis carries its model version and is bitwise that of one process
    local = diagnose_batch(
        [(p.passage_id, p.passage, p.measured) for p in archive.pairs], site.model_dump_json()
    )
    stored = {r.passage_id: r for r in rows}
    for o in local:
        doc = _body(stored[o.key].body)
        assert doc["model_version"] == version.model_dump()
        assert doc == _body(o.data), o.key
    sink.close()


def test_a_new_model_reports_what_changed(
    tmp_path: Path, site: SiteConfig, archive: Archive, cluster: tuple[object, ClusterInfo]
) -> None:
    """A stricter remove limit is another model version: the flats rise to remove."""
    client, info = cluster
    sink = DirSink(tmp_path, site.site_id, model_version(site).key)
    reanalyse(client, info, archive, site, model_version(site), sink)  # type: ignore[arg-type]
    strict = site.model_copy(
        update={
            "diagnosis": site.diagnosis.model_copy(
                update={"remove_length": 0.031, "inspect_length": 0.03, "watch_length": 0.02}
            )
        }
    )
    v2 = model_version(strict)
    assert v2.key != model_version(site).key
    report = reanalyse(client, info, archive, strict, v2, DirSink(tmp_path, site.site_id, v2.key))  # type: ignore[arg-type]
    assert report.rose_to_remove, report.table()
    assert report.by_verdict["remove"]["changed"] == len(report.rose_to_remove)
    assert all(w["wheel_id"] for w in report.rose_to_remove)
    assert "rose to remove" in report.table()


class KillingSink(DirSink):
    """Kills one worker (SIGKILL) when the first batch comes back."""

    def __init__(self, client: object, *args: object) -> None:
        super().__init__(*args)  # type: ignore[arg-type]
        self.client = client
        self.killed = False

    def write(self, rows: Sequence[Reanalysed]) -> None:
        if not self.killed:
            pids = self.client.run(os.getpid)  # type: ignore[attr-defined]
            os.kill(sorted(pids.values())[0], signal.SIGKILL)
            self.killed = True
        super().write(rows)


def test_a_worker_killed_mid_run_is_retried_without_duplicates(
    tmp_path: Path, site: SiteConfig, archive: Archive, cluster: tuple[object, ClusterInfo]
) -> None:
    client, info = cluster
    version = model_version(site)
    sink = KillingSink(client, tmp_path, site.site_id, version.key)
    report = reanalyse(client, info, archive, site, version, sink, batch=2)  # type: ignore[arg-type]
    assert sink.killed
    ids = [r.passage_id for r in sink.rows()]
    assert len(ids) == len(set(ids)) == PASSAGES
    assert report.diagnosed == PASSAGES


def _run_cli(*args: str, **kw: object) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "service.cli.reanalyse", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        **kw,  # type: ignore[call-overload]
    )


def _stored(db: Path) -> list[tuple[str, str]]:
    if not db.exists():
        return []
    try:
        with sqlite3.connect(db) as c:
            return list(c.execute("SELECT passage_id, model_version FROM reanalysis"))
    except sqlite3.OperationalError:
        return []  # the table is not made yet


def test_killed_with_9_and_started_again_stores_all_once(logs: Path, tmp_path: Path) -> None:
    db = tmp_path / "fleet.db"
    args = (str(logs), "--site", str(SITE_FILE), "--workers", "2", "--db", str(db), "--batch", "1")
    proc = _run_cli(*args)
    deadline = time.monotonic() + 120
    while len(_stored(db)) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the command, its scheduler and its workers
    proc.communicate()
    before = len(_stored(db))
    assert before > 0, "killed before it stored anything"
    again = _run_cli(*args, "--format", "json")
    out, err = again.communicate(timeout=180)
    assert again.returncode == 0, err
    rows = _stored(db)
    assert len(rows) == len(set(rows)) == PASSAGES
    report = json.loads(out)
    assert report["already_stored"] == before and report["diagnosed"] == PASSAGES - before
    with sqlite3.connect(db) as c:
        assert c.execute("SELECT COUNT(*) FROM diagnosis").fetchone()[0] == PASSAGES


def _cli(*argv: str) -> tuple[int, str]:
    from service.cli import reanalyse as cli

    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    cli.register(sub)  # type: ignore[arg-type]
    args = parser.parse_args(["reanalyse", *argv])
    try:
        return args.func(args), ""
    except CommandError as exc:
        return exc.code, str(exc)


@pytest.mark.parametrize("case", ["not_mcap", "truncated", "scheduler", "discrete"])
def test_bad_input_is_one_line_and_exit_2(case: str, tmp_path: Path, logs: Path) -> None:
    site, extra = str(SITE_FILE), ["--out", str(tmp_path / "out")]
    log = tmp_path / "x.mcap"
    if case == "not_mcap":
        log.write_text("{bad", encoding="utf-8")
        want = "not an MCAP log"
    elif case == "truncated":
        whole = sorted(logs.glob("*.mcap"))[0].read_bytes()
        log.write_bytes(whole[: len(whole) // 2])
        want = "cut short"
    elif case == "scheduler":
        from service.wire.zenoh_session import free_tcp_endpoint

        port = free_tcp_endpoint().rsplit(":", 1)[-1]
        log = sorted(logs.glob("*.mcap"))[0]
        extra += ["--scheduler", f"tcp://127.0.0.1:{port}", "--scheduler-timeout", "1"]
        want = "cannot reach the Dask scheduler"
    else:  # a rail on sleepers with no detector measures nothing the diagnosis fits
        text = (ROOT / "examples" / "site.toml").read_text(encoding="utf-8")
        no_detector = tmp_path / "no_detector.toml"
        no_detector.write_text(text[: text.index("[[detector.cribs]]")], encoding="utf-8")
        site = str(no_detector)
        want = "foundation is 'discrete' with no detector"
    code, message = _cli(str(log), "--site", site, *extra)
    assert code == 2 and want in message and "\n" not in message, message


def test_a_study_goes_on_past_a_failing_case(
    tmp_path: Path, cluster: tuple[object, ClusterInfo]
) -> None:
    import pyarrow.parquet as pq

    from service.distributed.study import StudyError, load_spec, run_study, table_of

    spec = tmp_path / "study.toml"
    base = ROOT / "examples" / "ideal_flat.json"
    spec.write_text(
        f'base = "{base}"\n[grid]\nspeed = [10.0, -5.0, 20.0]\npasses = [1, 2]\n'
        'duration = [0.01]\n[random]\ndraws = 1\nseed = 3\nfields = { "wheel.load" = '
        "{ low = 38e3, high = 40e3 } }\n",
        encoding="utf-8",
    )
    base_doc, cases = load_spec(spec)
    assert len(cases) == 6 and all(38e3 <= c["wheel.load"] <= 40e3 for c in cases)
    assert load_spec(spec)[1] == cases  # the seed makes the draws
    client, info = cluster
    rows, _, tasks = run_study(client, info, base_doc, cases, batch=2)
    assert tasks == 3
    params = sorted({k for c in cases for k in c})
    pq.write_table(table_of(rows, params), tmp_path / "t.parquet")
    table = pq.read_table(tmp_path / "t.parquet").to_pylist()
    assert [r["case"] for r in table] == list(range(6))
    failed = [r for r in table if r["error"] is not None]
    assert {r["speed"] for r in failed} == {-5.0} and len(failed) == 2
    assert "speed" in failed[0]["error"] and failed[0]["peak_force"] is None
    ok = [r for r in table if r["error"] is None]
    assert all(r["peak_force"] > 0 for r in ok) and {r["passes"] for r in ok} == {1, 2}
    spec.write_text(f'base = "{base}"\n[grid]\n"wheel.colour" = [1]\n', encoding="utf-8")
    with pytest.raises(StudyError, match=r"'wheel\.colour' is not a field"):
        load_spec(spec)
    spec.write_text(f'base = "{base}"\n[grids]\nspeed = [1.0]\n', encoding="utf-8")
    with pytest.raises(StudyError, match="grids"):
        load_spec(spec)
