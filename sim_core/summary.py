"""The contract's per-passage summary (CONTRACT.md ``summary``) from a passage's output.

Worked example: a wheel that never leaves the rail reports no losses and no
time out of contact; its peak force comes from the continuous solution.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim_core.passage import PassageOutput


@dataclass(frozen=True)
class PassageSummary:
    """Peak and minimum contact force (N), contact losses, first loss time (s,
    None without loss), time out of contact (s), largest indentation (m) and
    deepest permanent dent (m, 0 if elastic)."""

    peak_force: float
    min_force: float
    contact_losses: int
    first_loss_time: float | None
    time_out_of_contact: float
    max_indentation: float
    max_dent: float


def summarize(output: PassageOutput, max_dent: float = 0.0) -> PassageSummary:
    """Summary of one passage; ``max_dent`` comes from ``sim_core.dents``."""
    losses = [tr.t for tr in output.transitions if tr.kind == "loss"]
    return PassageSummary(
        peak_force=output.peak_force,
        min_force=output.min_force,
        contact_losses=len(losses),
        first_loss_time=losses[0] if losses else None,
        time_out_of_contact=output.time_out_of_contact,
        max_indentation=output.max_indentation,
        max_dent=max_dent,
    )
