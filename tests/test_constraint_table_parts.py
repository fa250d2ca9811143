"""Tables made from parts of node rows, and the kinks' slope jumps read from a table.

``table_from_parts`` must give what ``table_from_nodes`` gives on the rows concatenated (and
sorted, when a part is out of order); ``kink_jumps_between`` what a search for each kink's
nearest node gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.constraint.nodes import NCOL, SL, SR, XD, K, V, X, table_from_nodes, table_from_parts
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.tabulate import tabulate_constraint
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline


def _rows(xs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    rows = np.zeros((xs.size, NCOL))
    rows[:, X] = xs
    rows[:, V] = rng.normal(size=xs.size) * 1e-6
    rows[:, SL] = rng.normal(size=xs.size) * 1e-3
    rows[:, SR] = rows[:, SL] + np.where(rng.random(xs.size) < 0.3, 1e-3, 0.0)
    rows[:, XD] = xs + 1e-4
    rows[:, K] = (rows[:, SR] != rows[:, SL]).astype(float)
    return rows


def _same(a: ConstraintTable, b: ConstraintTable) -> bool:
    return all(
        np.array_equal(getattr(a, f), getattr(b, f))
        for f in ("x", "y", "slope_left", "slope_right", "contact_x", "kinks")
    )


@pytest.mark.parametrize("merge", ["none", "inside", "across"])
def test_parts_in_order_are_the_rows_concatenated(merge: str) -> None:
    rng = np.random.default_rng(3)
    xs = np.sort(rng.uniform(0.0, 1.0, 400))
    if merge == "inside":  # two distinct positions closer than the round-off: one node
        xs[200] = xs[199] * (1.0 + 2e-14)
    rows = _rows(xs, rng)
    a, b = rows[:150], rows[150:]
    if merge == "across":  # b's first node on a's last one taken, to round-off
        b[0, X] = a[99, X] * (1.0 + 2e-14)
    # rows 0..99 of a, then all of b (source 1); a's rows 100..149 are left out
    parts = np.array([[0, 0, 100], [1, 0, b.shape[0]]], dtype=np.int64)
    got = table_from_parts(a, b, parts, 0.0, 1e-3, 1e-3)
    want = table_from_nodes(np.concatenate([a[:100], b]), 0.0, 1e-3, 1e-3)
    assert _same(got, want)
    assert got.x.size == (350 if merge == "none" else 349)


def test_parts_must_be_row_ranges() -> None:
    rows = _rows(np.linspace(0.0, 1.0, 5), np.random.default_rng(5))
    for bad in ([[0, 0, 6]], [[2, 0, 1]], [[0, 3, 2]]):
        with pytest.raises(ValueError, match="row range"):
            table_from_parts(rows, rows[:0], np.array(bad), 0.0, 1e-3, 1e-3)


def test_parts_out_of_order_are_sorted_and_nodes_out_of_order_refused() -> None:
    rng = np.random.default_rng(4)
    rows = _rows(np.sort(rng.uniform(0.0, 1.0, 100)), rng)
    parts = np.array([[0, 50, 100], [0, 0, 50]], dtype=np.int64)  # the second half first
    got = table_from_parts(rows, rows[:0], parts, 0.0, 1e-3, 1e-3)
    assert _same(got, table_from_nodes(rows, 0.0, 1e-3, 1e-3))
    with pytest.raises(ValueError, match="increasing"):
        table_from_nodes(np.concatenate([rows[50:], rows[:50]]), 0.0, 1e-3, 1e-3)


def _kink_jumps_by_search(t: ConstraintTable, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Each kink's jump at its nearest node, found by brute force (a periodic table's kink
    carried back into the period it keeps)."""
    kinks = t.kinks_between(a, b)
    jumps = []
    for xk in kinks:
        home = xk if t.period <= 0.0 else t.x[0] + (xk - t.x[0]) % t.period
        i = int(np.argmin(np.abs(t.x - home)))
        jumps.append(abs(t.slope_right[i] - t.slope_left[i]))
    return kinks, np.array(jumps)


@pytest.mark.parametrize(
    "rail",
    [
        RailProfile.sampled(
            np.linspace(-0.1, 6.1, 12401), 2e-6 * np.sin(np.linspace(0, 600, 12401))
        ),
        RailProfile.flat(),  # a flat wheel's table is periodic there: its kinks recur
    ],
    ids=["sampled", "periodic"],
)
def test_kink_jumps_are_read_at_each_kinks_node(rail: RailProfile) -> None:
    t = tabulate_constraint(WheelOutline.ideal_flat(0.46, 0.05), rail, 0.0, 6.0, phase=1.0)
    assert t.kinks.size > 0
    for a, b in ((-1e-12, 6.0 + t.resolution), (2.0, 2.8), (-5.0, 20.0), (0.5, 0.5)):
        k0, j0 = _kink_jumps_by_search(t, a, b)
        k1, j1 = t.kink_jumps_between(a, b)
        assert np.array_equal(k0, k1) and np.array_equal(j0, j1)


def test_kink_jumps_kept_by_the_tabulator_equal_the_node_walk() -> None:
    """``table_from_parts`` keeps each kink's jump (``kink_jump``); a table without them walks
    the nodes (``_kink_jumps``): the same positions and jumps, to the bit."""
    import dataclasses

    rail = RailProfile.sampled(
        np.linspace(-0.1, 6.1, 12401), 2e-6 * np.sin(np.linspace(0, 600, 12401))
    )
    t = tabulate_constraint(WheelOutline.ideal_flat(0.46, 0.05), rail, 0.0, 6.0, phase=1.0)
    assert t.kink_jump.shape == t.kinks.shape and t.kinks.size > 100
    bare = dataclasses.replace(t, kink_jump=np.empty(0))
    for a, b in ((-1e-12, 6.0 + t.resolution), (2.0, 2.8), (-5.0, 20.0), (0.5, 0.5), (3.0, 1.0)):
        k0, j0 = bare.kink_jumps_between(a, b)
        k1, j1 = t.kink_jumps_between(a, b)
        assert np.array_equal(k0, k1) and np.array_equal(j0, j1)
    # a kink exactly at an end: (x0, x1] as before
    k = float(t.kinks[10])
    for a, b in ((k, k + 0.01), (k - 0.01, k)):
        assert np.array_equal(t.kink_jumps_between(a, b)[0], bare.kink_jumps_between(a, b)[0])
    with pytest.raises(ValueError, match="kink_jump"):
        dataclasses.replace(t, kink_jump=np.ones(3))


def test_round_rows_of_six_columns_make_the_same_table() -> None:
    """Rows of ``ROUND_NCOL`` columns (a round wheel's on a polyline, kink flag at ``ROUND_K``)
    give the table their ten-column form gives, beside ten-column rows, in order or sorted."""
    from sim_core.constraint.nodes import ROUND_K, ROUND_NCOL

    rng = np.random.default_rng(12)
    full = _rows(np.sort(rng.uniform(0.0, 1.0, 300)), rng)
    small = _rows(np.sort(rng.uniform(1.0, 1.2, 20)), rng)
    six = np.zeros((full.shape[0], ROUND_NCOL))
    six[:, :ROUND_K] = full[:, :ROUND_K]
    six[:, ROUND_K] = full[:, K]
    assert np.any(six[:, ROUND_K] > 0)
    in_order = np.array([[0, 0, 300], [1, 0, 20]], dtype=np.int64)
    want = table_from_parts(full, small, in_order, 0.0, 1e-3, 1e-3)
    assert _same(table_from_parts(six, small, in_order, 0.0, 1e-3, 1e-3), want)
    assert np.array_equal(
        table_from_nodes(six, 0.0, 1e-3, 1e-3).kinks, table_from_nodes(full, 0.0, 1e-3, 1e-3).kinks
    )
    swapped = np.array([[0, 150, 300], [0, 0, 150]], dtype=np.int64)  # sorted on the way
    assert _same(
        table_from_parts(six, small, swapped, 0.0, 1e-3, 1e-3),
        table_from_parts(full, small, swapped, 0.0, 1e-3, 1e-3),
    )
