"""``railtwin recover``: logs cut by a crash lose nothing that was flushed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from schemas.messages import RejectedInput
from service.cli import main as cli_main
from service.mcap_log import McapLog
from service.mcap_recover import read_any, salvage


def _log(tmp_path: Path, n: int, flush_every: int) -> tuple[Path, list[int]]:
    """A log of n messages flushed every ``flush_every``; file sizes after each flush."""
    log = McapLog(tmp_path, "run", chunk_size=1 << 20)
    sizes = []
    for i in range(n):
        log.write("railtwin/x/passage/rejected", RejectedInput,
                  json.dumps({"i": i}).encode(), 1_000 + i)
        if i % flush_every == flush_every - 1:
            log.flush()
            assert log._file is not None
            log._file.flush()
            sizes.append(log._file.tell())
    path = log.files[0]
    assert log._file is not None
    log._file.flush()
    return path, sizes


@pytest.mark.parametrize("cut_after_flush", [0, 3, 9])
def test_everything_flushed_before_the_cut_is_recovered(tmp_path: Path,
                                                        cut_after_flush: int) -> None:
    path, sizes = _log(tmp_path, 100, 10)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: sizes[cut_after_flush] + 17])  # a torn record after the flush
    with cut.open("rb") as f, pytest.raises(Exception):  # noqa: B017 - any reader error
        list(make_reader(f).iter_messages())
    kept = [json.loads(m.data)["i"] for m in salvage(cut)]
    assert kept == list(range(10 * (cut_after_flush + 1)))
    out = tmp_path / "fixed.mcap"
    assert cli_main(["recover", str(cut), "--out", str(out)]) == 0
    with out.open("rb") as f:
        msgs = [json.loads(m.data)["i"] for _, _, m in make_reader(f).iter_messages()]
    assert msgs == kept
    assert [json.loads(m.data)["i"] for m in read_any([out])] == kept


def test_recover_refuses_to_overwrite_its_input(tmp_path: Path) -> None:
    path, _ = _log(tmp_path, 10, 5)
    assert cli_main(["recover", str(path), "--out", str(path)]) == 2
    assert cli_main(["recover", str(tmp_path / "missing.mcap"), "--out",
                     str(tmp_path / "o.mcap")]) == 2
