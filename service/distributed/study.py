"""Parameter studies: a base scenario and the fields to vary, one row per case, on a Dask
cluster (``railtwin study``).

The spec (TOML)::

    base = "ideal_flat.json"          # a scenario file (relative to the spec), or a [base] table
    [grid]                            # every combination of these values
    speed = [5.0, 10.0, 20.0]
    "wheel.outline.length" = [0.03, 0.05]
    [random]                          # or/and: draws with a seed, each field uniform in [low, high]
    draws = 20                        # or picked among a list of values
    seed = 1
    fields = { "wheel.load" = { low = 40e3, high = 80e3 } }

Any scenario field by its dotted path (``passes`` included); a path the base scenario does
not have is refused (``StudyError``). Grid and draws combine: each grid point gets every
draw. A case whose scenario is invalid or whose simulation fails gets a row with its
``error``; the study goes on.
"""

from __future__ import annotations

import copy
import itertools
import json
import random
import time
import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

SUMMARY_COLUMNS = (
    "peak_force",
    "min_force",
    "contact_losses",
    "first_loss_time",
    "time_out_of_contact",
    "max_indentation",
    "max_dent",
)


class StudyError(ValueError):
    """The spec cannot be used (one line naming the field)."""


class Range(BaseModel):
    model_config = ConfigDict(extra="forbid")
    low: float
    high: float


class RandomSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    draws: int = Field(ge=1, le=100_000)
    seed: int = 0
    fields: dict[str, Range | list[Any]]


class StudySpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    base: str | dict[str, Any]
    grid: dict[str, list[Any]] = Field(default_factory=dict)
    random: RandomSpec | None = None


def _has_path(doc: Any, path: str) -> bool:
    for part in path.split("."):
        if not isinstance(doc, dict) or part not in doc:
            return False
        doc = doc[part]
    return True


def set_path(doc: dict[str, Any], path: str, value: Any) -> None:
    parts = path.split(".")
    for part in parts[:-1]:
        doc = doc[part]
    doc[parts[-1]] = value


def load_spec(path: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(base scenario as a dict, each case's parameters) of the spec at ``path``."""
    from schemas.scenario import Scenario

    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise StudyError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{path}: not valid TOML: {exc}") from None
    try:
        spec = StudySpec.model_validate(raw)
    except ValidationError as exc:
        e = exc.errors()[0]
        where = ".".join(str(p) for p in e["loc"])
        raise StudyError(f"{path}: {where}: {e['msg']}") from None
    if isinstance(spec.base, str):
        base_file = (path.parent / spec.base).resolve()
        try:
            base = json.loads(base_file.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise StudyError(f"{path}: base {spec.base}: cannot read a scenario: {exc}") from None
    else:
        base = spec.base
    try:
        base = Scenario.model_validate(base).model_dump(mode="json")
    except ValidationError as exc:
        e = exc.errors()[0]
        raise StudyError(f"{path}: base.{'.'.join(map(str, e['loc']))}: {e['msg']}") from None
    fields = [*spec.grid, *(spec.random.fields if spec.random else {})]
    for name in fields:
        if not _has_path(base, name):
            raise StudyError(f"{path}: {name!r} is not a field of the base scenario")
    for name, values in spec.grid.items():
        if not values:
            raise StudyError(f"{path}: grid.{name}: no values")
    points = [
        dict(zip(spec.grid, combo, strict=True)) for combo in itertools.product(*spec.grid.values())
    ]
    if spec.random is None:
        return base, points
    rng = random.Random(spec.random.seed)
    cases = []
    for point in points:
        for _ in range(spec.random.draws):
            case = dict(point)
            for name, dist in spec.random.fields.items():
                case[name] = (
                    rng.uniform(dist.low, dist.high)
                    if isinstance(dist, Range)
                    else (rng.choice(dist))
                )
            cases.append(case)
    return base, cases


def run_cases(
    batch: list[tuple[int, dict[str, Any]]], base: dict[str, Any]
) -> list[dict[str, Any]]:
    """One row per case: its parameters, its summary (the last pass's) or its error."""
    from schemas.scenario import Scenario
    from service.physics.scenario_runner import run_scenario

    rows = []
    for index, params in batch:
        row: dict[str, Any] = {"case": index, **params}
        start = time.perf_counter()
        try:
            doc = copy.deepcopy(base)
            for name, value in params.items():
                set_path(doc, name, value)
            result = run_scenario(Scenario.model_validate(doc))
            row.update(result.summary.model_dump())
            row["passes"] = len(result.passes_summary)
            row["error"] = None
        except ValidationError as exc:
            e = exc.errors()[0]
            row["error"] = f"invalid scenario: {'.'.join(map(str, e['loc']))}: {e['msg']}"
        except Exception as exc:  # a failed case is a row, the study goes on
            row["error"] = f"{type(exc).__name__}: {exc}"
        row["wall_time"] = time.perf_counter() - start
        rows.append(row)
    return rows


def table_of(rows: list[dict[str, Any]], params: list[str]) -> Any:
    """The rows as a pyarrow table: parameters (a non-scalar value as JSON), the summary,
    ``passes``, ``error``, ``wall_time``; in case order."""
    import pyarrow as pa

    rows = sorted(rows, key=lambda r: r["case"])
    cols: dict[str, list[Any]] = {"case": [r["case"] for r in rows]}
    for p in params:
        values = [r.get(p) for r in rows]
        if (
            any(isinstance(v, dict | list) for v in values)
            or len({type(v) for v in values if v is not None}) > 1
        ):
            values = [json.dumps(v) if v is not None else None for v in values]
        cols[p] = values
    for c in (*SUMMARY_COLUMNS, "passes", "error", "wall_time"):
        cols[c] = [r.get(c) for r in rows]
    return pa.table(cols)


def plot(table: Any, params: list[str], out: Path) -> Path | None:
    """Peak force against the first numeric parameter, one curve per value of the others."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = table.to_pylist()
    numeric = [
        p for p in params if all(isinstance(r[p], int | float) for r in data if r[p] is not None)
    ]
    if not numeric:
        return None
    x = numeric[0]
    others = [p for p in params if p != x]
    curves: dict[str, list[tuple[float, float]]] = {}
    for r in data:
        if r["error"] is not None or r["peak_force"] is None:
            continue
        label = ", ".join(f"{p}={r[p]}" for p in others) or "peak force"
        curves.setdefault(label, []).append((r[x], r["peak_force"] / 1e3))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, pts in curves.items():
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=label[:80])
    ax.set_xlabel(x)
    ax.set_ylabel("peak force [kN]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    png = out.with_suffix(".png")
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return png


def run_study(
    client: Any,
    info: Any,
    base: dict[str, Any],
    cases: list[dict[str, Any]],
    *,
    batch: int | None = None,
    stream: Any = None,
) -> tuple[list[dict[str, Any]], float, int]:
    """Every case on the cluster, batched; (rows, wall seconds, tasks)."""
    from service.distributed.cluster import IN_FLIGHT_PER_WORKER, run_batches
    from service.distributed.progress import Progress

    workers = max(1, info.workers)
    size = batch or max(1, min(16, len(cases) // (4 * workers)))
    items = list(enumerate(cases))
    batches = [items[i : i + size] for i in range(0, len(items), size)]
    progress = Progress(len(cases), "cases", stream, prefix="railtwin study")
    rows: list[dict[str, Any]] = []
    start = time.perf_counter()
    try:
        for _, got in run_batches(
            client, run_cases, batches, base, in_flight=IN_FLIGHT_PER_WORKER * workers
        ):
            rows.extend(got)
            progress.advance(len(got))
    finally:
        progress.close()
    return rows, time.perf_counter() - start, len(batches)
