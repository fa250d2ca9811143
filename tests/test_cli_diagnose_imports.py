"""``railtwin diagnose`` imports only what the diagnosis needs (its start-up is part of the
1 s a diagnosis may take as a whole command)."""

from __future__ import annotations

import subprocess
import sys

SERVICE_ONLY = ("zenoh", "mcap", "rerun", "pyarrow", "scipy.signal", "scipy.stats")


def test_diagnose_path_skips_the_service_imports() -> None:
    code = (
        "import sys\n"
        "from service.cli.main import build_parser\n"
        "p = build_parser(['diagnose', '--site', 's', '--passage', 'p', '--measured', 'm'])\n"
        "assert 'diagnose' in p._subparsers._group_actions[0].choices\n"
        "import service.physics.diagnosis\n"
        f"print(sorted(m for m in {SERVICE_ONLY!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_other_command_lines_still_get_every_command() -> None:
    from service.cli.main import build_parser

    choices = build_parser(["--help"])._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    assert {"simulate", "diagnose", "serve", "replay"} <= set(choices)
