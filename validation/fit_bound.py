"""What bounds each length and kind miss: the truth's cost on the fit's own windows.

For every flat of both sources the fit is asked, besides its answer, for the cost of the
true flat (kind, length, depth factor) on the same windows (``estimate_flat(compare=...)``,
the lowest over the damping ratios searched; ``truth_bounds.cost_fields``, stored in each
validation row). Set against the answer's cost and the χ²
bound that makes the length interval, it says what kind of miss each one is:

- ``search``: the truth costs less than the answer: the twin would prefer it, the search
  did not reach it;
- ``ambiguous``: the truth costs more, but within the bound: the record does not tell the
  two apart (the interval covers it);
- ``model``: the truth costs more than the bound: the twin's windows (a wheel arriving at
  the flat in steady rolling, on the site file's even rail) fit the wrong flat better than
  the right one, and no search can help;
- ``screened``: the screen dismissed the record as a round wheel's, and no fit ran.

    .venv/bin/python -m validation.fit_bound [--only W06,W30]
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any, Literal

from service.physics.diagnosis import Diagnoser
from validation.truth_bounds import costs_of
from validation.wide_set import (
    cases_parser,
    chosen_ids,
    fitted_fields,
    load_case,
    run_all,
    true_flat,
)

MissKind = Literal["search", "ambiguous", "model", "screened"]


@dataclass(frozen=True)
class FitRow:
    """One flat of a validation source: the answer and the truth on the same windows."""

    case: str
    kind: str
    length: float
    speed_kmh: float
    zeta: float
    found_kind: str | None
    found_length: float
    cost_best: float | None
    cost_truth: float | None
    bound: float | None
    explained: bool

    @classmethod
    def from_result(cls, r: dict[str, Any]) -> FitRow | None:
        """The row of a flat's validation result (``truth_bounds.cost_fields`` in it; a
        ``KeyError`` if they are not), None for a round wheel."""
        if r["kind"] == "round":
            return None

        def number(key: str) -> float | None:
            return None if r[key] is None else float(r[key])

        return cls(
            str(r["case"]),
            str(r["kind"]),
            float(r["true_length"]),
            float(r["speed_kmh"]),
            float(r["true_damping_ratio"]),
            r["found_kind"],
            float(r["found_length"]),
            number("cost_best"),
            number("cost_truth"),
            number("cost_bound"),
            bool(r["explained"]),
        )

    @property
    def ratio(self) -> float:
        """The truth's cost over the answer's (infinite where no fit ran)."""
        if self.cost_truth is None or not self.cost_best:
            return float("inf")
        return self.cost_truth / self.cost_best

    @property
    def length_ok(self) -> bool:
        return abs(self.found_length - self.length) <= max(0.005, 0.1 * self.length)

    @property
    def kind_ok(self) -> bool:
        return self.found_kind == self.kind

    @property
    def miss(self) -> MissKind | None:
        if self.length_ok and self.kind_ok:
            return None
        if self.cost_truth is None or self.bound is None:
            return "screened"
        if self.ratio < 1.0:
            return "search"
        return "ambiguous" if self.ratio <= self.bound else "model"


def fit_rows(results: list[dict[str, Any]]) -> list[FitRow]:
    """The ``FitRow`` of every flat among validation ``results``."""
    return [r for r in (FitRow.from_result(x) for x in results) if r is not None]


def fit_row(case_id: str) -> FitRow | None:
    """The fit of one wide-set passage with its truth's cost (None for a round wheel): one
    diagnosis asked for the truth's cost (which changes nothing of the answer)."""
    c = load_case(case_id)
    flat = true_flat(c)
    if flat is None:
        return None
    d = Diagnoser(c.site)
    diag, curves = d.diagnose(c.passage, c.measured, compare=[flat])
    return FitRow.from_result(
        {
            "case": case_id,
            "kind": flat[0],
            "true_length": flat[1],
            "speed_kmh": c.passage.speed * 3.6,
            "true_damping_ratio": c.zeta,
            **fitted_fields(diag, curves, 0.0),
            **costs_of(curves.force_estimate, d.options),
        }
    )


def summary(rows: list[FitRow]) -> str:
    misses = [r for r in rows if r.miss is not None]
    lines = [
        "| case | truth | km/h | ζ | found | truth's cost / answer's | χ² bound | explained | miss |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in misses:
        lines.append(
            f"| {r.case} | {r.kind} {r.length * 1e3:.1f} mm | {r.speed_kmh:.0f} | {r.zeta:.3f} "
            f"| {r.found_kind or 'none'} {r.found_length * 1e3:.1f} mm | {r.ratio:.2f} "
            f"| {r.bound or 0.0:.2f} | {'yes' if r.explained else 'no'} | {r.miss} |"
        )
    counts = {
        k: sum(r.miss == k for r in misses) for k in ("search", "ambiguous", "model", "screened")
    }
    lines += [
        "",
        f"- {len(misses)} of {len(rows)} flats miss the length or the kind: "
        f"{counts['model']} model (the truth costs more than the bound on the twin's own "
        f"windows), {counts['ambiguous']} ambiguous (within the bound), {counts['search']} "
        f"search (the truth costs less than the answer), {counts['screened']} screened (no fit "
        f"ran)",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    a = cases_parser("validation.fit_bound", __doc__).parse_args(argv)
    print(summary(fit_rows(run_all(chosen_ids(a)))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
