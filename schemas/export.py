"""Write (or check) the committed JSON Schemas in ``schemas/json/``: one file per model.

    python -m schemas.export            # rewrite schemas/json/*.schema.json from the models
    python -m schemas.export --check    # exit 1 if a committed file differs from the models
    python -m schemas.export --out DIR  # write them elsewhere

The models are the source of truth; the files are for clients in other languages
(and for the MCAP logs' readers). Needs nothing but pydantic.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from schemas import all_json_schemas

JSON_DIR = Path(__file__).resolve().parent / "json"
"""Where the committed schemas live (inside the package: installed with it)."""

SUFFIX = ".schema.json"


def schema_files() -> dict[str, str]:
    """{file name: JSON text} of every top-level model's JSON Schema."""
    return {
        f"{name}{SUFFIX}": json.dumps(schema, indent=2, ensure_ascii=False) + "\n"
        for name, schema in sorted(all_json_schemas().items())
    }


def differences(directory: Path) -> list[str]:
    """What differs between ``directory`` and the models: missing, stale or extra files."""
    want = schema_files()
    have = {p.name for p in directory.glob(f"*{SUFFIX}")} if directory.is_dir() else set()
    out = [f"missing: {n}" for n in sorted(set(want) - have)]
    out += [f"not a model any more: {n}" for n in sorted(have - set(want))]
    for name in sorted(set(want) & have):
        if json.loads((directory / name).read_text(encoding="utf-8")) != json.loads(want[name]):
            out.append(f"differs from the model: {name}")
    return out


def write(directory: Path) -> list[Path]:
    """Write every schema into ``directory`` (created) and remove stale ones; the paths."""
    directory.mkdir(parents=True, exist_ok=True)
    files = schema_files()
    for stale in directory.glob(f"*{SUFFIX}"):
        if stale.name not in files:
            stale.unlink()
    paths = []
    for name, text in files.items():
        path = directory / name
        path.write_text(text, encoding="utf-8")
        paths.append(path)
    return paths


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m schemas.export", description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=JSON_DIR, help=f"directory (default {JSON_DIR})")
    p.add_argument("--check", action="store_true", help="only compare; exit 1 on a difference")
    args = p.parse_args(argv)
    if args.check:
        diff = differences(args.out)
        for line in diff:
            print(line, file=sys.stderr)
        if diff:
            print("regenerate with: python -m schemas.export", file=sys.stderr)
        return 1 if diff else 0
    paths = write(args.out)
    print(f"wrote {len(paths)} JSON Schemas to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
