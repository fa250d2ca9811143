"""The light client (issue 16, item 8): the schemas package alone, its JSON Schemas, the
example clients.

The schemas package must work with nothing but pydantic: checked on its import graph
(every import of every module) and by importing it in an isolated interpreter (``-I -S``:
no site-packages) that sees only pydantic and its own dependencies.
"""

from __future__ import annotations

import ast
import importlib
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from schemas import export
from schemas.messages import MESSAGE_SCHEMA_VERSION

ROOT = Path(__file__).resolve().parents[1]
SCHEMAS = ROOT / "schemas"
CLIENTS = ROOT / "examples" / "clients"
PYDANTIC_AND_ITS_DEPENDENCIES = (
    "pydantic",
    "pydantic_core",
    "annotated_types",
    "typing_extensions",
    "typing_inspection",
)
HEAVY = ("numpy", "scipy", "numba", "zenoh", "mcap", "rerun", "sim_core", "service")


def imported_modules(path: Path) -> set[str]:
    """Top-level names of every module ``path`` imports, at any depth of its code."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_schemas_import_only_the_standard_library_and_pydantic() -> None:
    allowed = set(sys.stdlib_module_names) | {"schemas", "pydantic", "pydantic_core"}
    for path in sorted(SCHEMAS.glob("*.py")):
        assert imported_modules(path) <= allowed, (path.name, imported_modules(path) - allowed)


def test_schemas_work_in_an_interpreter_with_nothing_but_pydantic(tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / "schemas").symlink_to(SCHEMAS, target_is_directory=True)
    for name in PYDANTIC_AND_ITS_DEPENDENCIES:
        origin = Path(importlib.import_module(name).__file__ or "")
        source = origin.parent if origin.name == "__init__.py" else origin
        (site / source.name).symlink_to(source)
    code = f"""
import json, pkgutil, sys
sys.path.insert(0, {str(site)!r})
import schemas
for m in pkgutil.iter_modules(schemas.__path__):
    __import__("schemas." + m.name)
from schemas.messages import WheelPassage, WheelRef
p = WheelPassage.model_validate_json(json.dumps({{
    "passage_id": "p", "train_id": "t", "axle_index": 0, "side": "left", "timestamp": 0.0,
    "speed": 30.0, "load": 9e4, "mass": 900.0, "radius": 0.46, "direction": "end2_leading",
    "wheel": {{"vehicle_id": "V", "wheelset": 1, "side": "left"}}, "new_in_1_9": 1,
    "schema_version": "1.9"}}))
assert p.wheel == WheelRef.parse("V/1/left")
heavy = sorted(m for m in sys.modules if m.split(".")[0] in {HEAVY!r})
print(json.dumps({{"heavy": heavy, "file": schemas.__file__}}))
"""
    out = subprocess.run(
        [sys.executable, "-I", "-S", "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got["heavy"] == []
    assert got["file"].startswith(str(site))


def test_the_distribution_needs_only_pydantic() -> None:
    meta = tomllib.loads((SCHEMAS / "pyproject.toml").read_text(encoding="utf-8"))
    project = meta["project"]
    assert project["name"] == "railtwin-schemas"
    assert [re.split(r"[<>=!~ ]", d)[0] for d in project["dependencies"]] == ["pydantic"]
    # its version follows the messages' schema version (major.minor)
    assert project["version"].rsplit(".", 1)[0] == MESSAGE_SCHEMA_VERSION
    assert meta["tool"]["setuptools"]["package-dir"] == {"schemas": "."}
    assert "json/*.schema.json" in meta["tool"]["setuptools"]["package-data"]["schemas"]


def test_the_committed_json_schemas_match_the_models() -> None:
    diff = export.differences(export.JSON_DIR)
    assert diff == [], "regenerate with: python -m schemas.export\n" + "\n".join(diff)
    names = {p.name.removesuffix(".schema.json") for p in export.JSON_DIR.glob("*.json")}
    assert {"WheelPassage", "PassageResult", "Diagnosis", "Health", "ServiceError"} <= names
    wheel_passage = json.loads((export.JSON_DIR / "WheelPassage.schema.json").read_text())
    assert wheel_passage["$defs"]["WheelRef"]["required"] == ["vehicle_id", "wheelset", "side"]


def test_export_writes_and_notices_drift(tmp_path: Path) -> None:
    assert export.main(["--out", str(tmp_path)]) == 0
    assert export.main(["--out", str(tmp_path), "--check"]) == 0
    health = tmp_path / "Health.schema.json"
    doc = json.loads(health.read_text())
    doc["properties"].pop("uptime")
    health.write_text(json.dumps(doc))
    (tmp_path / "Gone.schema.json").write_text("{}")
    assert export.differences(tmp_path) == [
        "not a model any more: Gone.schema.json",
        "differs from the model: Health.schema.json",
    ]
    assert export.main(["--out", str(tmp_path), "--check"]) == 1
    export.main(["--out", str(tmp_path)])
    assert export.differences(tmp_path) == []


CLIENT_SCRIPTS = ["send_passage.py", "watch_diagnoses.py", "wheel_history.py", "follow_alarms.py"]


@pytest.mark.parametrize("name", [*CLIENT_SCRIPTS, "common.py"])
def test_example_clients_are_short_and_parse(name: str) -> None:
    text = (CLIENTS / name).read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 40
    assert imported_modules(CLIENTS / name) <= (
        set(sys.stdlib_module_names) | {"zenoh", "schemas", "common"}
    )


@pytest.mark.parametrize("name", CLIENT_SCRIPTS)
def test_example_clients_show_help(name: str) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}  # as if railtwin-schemas were installed
    out = subprocess.run(
        [sys.executable, name, "--help"],
        cwd=CLIENTS,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(f"usage: {name.removesuffix('.py')}")
    assert "--connect" in out.stdout and "--mode" in out.stdout


def test_railtwin_schema_out_writes_what_is_committed(tmp_path: Path) -> None:
    from service.cli.main import main as cli_main

    assert cli_main(["schema", "--out", str(tmp_path / "json")]) == 0
    assert export.differences(tmp_path / "json") == []
    assert cli_main(["schema", "Health", "--out", str(tmp_path)]) == 2  # NAME and --out


def test_send_passage_gets_its_result_from_a_twin() -> None:
    """The example client against a twin (stub physics, in this process) over loopback."""
    from tests.test_network import Site

    site = Site("km12")
    try:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        out = subprocess.run(
            [
                sys.executable,
                "send_passage.py",
                "--site",
                "km12",
                "--connect",
                site.endpoint,
                "--wheel",
                "31-80-4751-123-4/2/left",
                "--direction",
                "end1_leading",
            ],
            cwd=CLIENTS,
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    finally:
        site.close()
    assert out.returncode == 0, out.stderr
    assert "of wheel 31-80-4751-123-4/2/left on railtwin/km12/passage" in out.stdout
    assert "'peak_force':" in out.stdout, out.stdout
    assert site.twin.passages_done == 1
