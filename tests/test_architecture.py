"""The import rules of docs/architecture.md hold in the code (imports parsed with ``ast``).

Every import counts: at module level, inside functions (lazy imports) and under
``TYPE_CHECKING``. A new folder of ``service/`` must be given its rule here and in
docs/architecture.md before it can be imported from.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PACKAGES_MAY_IMPORT: dict[str, set[str]] = {
    "sim_core": {"sim_core"},
    "schemas": {"schemas"},
    "validation": {"sim_core", "schemas", "service", "validation"},
    "service": {"sim_core", "schemas", "service"},
}
"""Top-level packages of the repository and the ones of them each may import."""

SERVICE_MAY_IMPORT: dict[str, set[str]] = {
    "wire": {"wire"},
    "recording": {"recording", "wire"},
    "physics": {"physics", "wire"},
    "twin": {"twin", "wire", "recording", "physics.port"},
    "clients": {"clients", "wire", "recording", "physics"},
    "fleet": {"fleet", "wire"},
    "distributed": {"distributed", "wire", "recording", "physics", "clients", "fleet"},
    "cli": {"cli", "wire", "recording", "physics", "twin", "clients", "fleet", "distributed"},
}
"""Subsystems of ``service/`` and what each may import of the others (``physics.port``: only
that module of ``physics``)."""

FORBIDDEN_FOR_PHYSICS_FREE = {"sim_core", "numba"}
"""What a subsystem that must not load the physics may not import (the twin and wire)."""


def imports_of(path: Path) -> Iterator[tuple[int, str]]:
    """(line, module) of every import in ``path``; ``from a import b`` gives ``a.b`` too
    (``b`` may be a module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
            for alias in node.names:
                yield node.lineno, f"{node.module}.{alias.name}"


def python_files(package: str) -> list[Path]:
    return sorted(p for p in (ROOT / package).rglob("*.py") if ".venv" not in p.parts)


def test_every_service_folder_has_a_rule() -> None:
    folders = {
        p.name for p in (ROOT / "service").iterdir() if p.is_dir() and (p / "__init__.py").exists()
    }
    assert folders <= set(SERVICE_MAY_IMPORT), (
        f"service/ folders without an import rule: {sorted(folders - set(SERVICE_MAY_IMPORT))}"
    )
    loose = sorted(p.name for p in (ROOT / "service").glob("*.py") if p.name != "__init__.py")
    assert not loose, f"modules directly in service/ (each belongs to a subsystem): {loose}"


@pytest.mark.parametrize("package", sorted(PACKAGES_MAY_IMPORT))
def test_packages_import_only_what_they_may(package: str) -> None:
    allowed = PACKAGES_MAY_IMPORT[package]
    bad = [
        f"{path.relative_to(ROOT)}:{line}: {module}"
        for path in python_files(package)
        for line, module in imports_of(path)
        if module.split(".")[0] in PACKAGES_MAY_IMPORT and module.split(".")[0] not in allowed
    ]
    assert not bad, (
        f"{package}/ may import only {sorted(allowed)} of the repository:\n" + "\n".join(bad)
    )


@pytest.mark.parametrize("subsystem", sorted(SERVICE_MAY_IMPORT))
def test_service_subsystems_import_only_what_they_may(subsystem: str) -> None:
    allowed = SERVICE_MAY_IMPORT[subsystem]
    bad = []
    for path in python_files(f"service/{subsystem}"):
        for line, module in imports_of(path):
            parts = module.split(".")
            if parts[0] != "service" or len(parts) < 2 or parts[1] == "__init__":
                continue
            target = parts[1]
            dotted = ".".join(parts[1:3])
            if target in allowed or dotted in allowed:
                continue
            if len(parts) == 2 and any(a.startswith(f"{target}.") for a in allowed):
                continue  # ``from service.physics import port``: its module is checked as well
            bad.append(f"{path.relative_to(ROOT)}:{line}: {module}")
    assert not bad, (
        f"service/{subsystem}/ may import only {sorted(allowed)} of service/:\n" + "\n".join(bad)
    )


@pytest.mark.parametrize("subsystem", ["twin", "wire"])
def test_the_twin_and_the_wire_load_no_physics(subsystem: str) -> None:
    bad = [
        f"{path.relative_to(ROOT)}:{line}: {module}"
        for path in python_files(f"service/{subsystem}")
        for line, module in imports_of(path)
        if module.split(".")[0] in FORBIDDEN_FOR_PHYSICS_FREE
    ]
    assert not bad, "\n".join(bad)


def test_the_rules_catch_a_forbidden_import(tmp_path: Path) -> None:
    """The parser sees lazy and TYPE_CHECKING imports (what the rules above rely on)."""
    source = tmp_path / "m.py"
    source.write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from service.physics.worker import PhysicsPool\n"
        "def f() -> None:\n    import service.cli.main\n"
        "from service.physics import port\n",
        encoding="utf-8",
    )
    found = {m for _, m in imports_of(source)}
    assert {"service.physics.worker", "service.cli.main", "service.physics.port"} <= found


def test_importing_the_twin_loads_no_physics() -> None:
    """The twin talks to physics through the port only: importing it loads no sim_core."""
    import subprocess
    import sys

    code = (
        "import sys, service.twin.twin; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('sim_core', 'numba') "
        "or m.startswith('service.physics.') and m != 'service.physics.port' "
        "and m != 'service.physics.measurement_error'))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()
    assert out == "[]"
