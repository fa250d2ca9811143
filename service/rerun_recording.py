"""The service run's Rerun recording: one headless ``.rrd`` with every passage.

Entities (one per passage ``<p>`` under each quantity, so that a view of a
quantity overlays every wheel of the run along the site):

| entity | what | unit |
|---|---|---|
| ``force/<p>`` | contact force F | kN |
| ``force/<p>/transitions`` | markers: losses/returns of contact, yield/unyield | kN |
| ``indentation/<p>`` | indentation δ (negative: out of contact) | µm |
| ``motion/y_c/<p>``, ``motion/y_ck/<p>`` | wheel centre y_C and rigid constraint y_C^k | µm |
| ``rail/profile`` | the site's rail as the service started | µm |
| ``rail/dent/<p>`` | accumulated dent depth after passage p (only when it dented) | µm |
| ``events`` | one text line per passage (peak force, losses, dent) | |
| ``diagnosis/measured``, ``diagnosis/fit`` | measured and best-fit force of each diagnosis | kN |
| ``diagnosis/impacts`` | markers: the fitted flat under the wheel | kN |
| ``diagnosis/verdict`` | one text line per diagnosis (verdict, flat, peak forces) | |

The time line ``x_mm`` is the wheel centre's position along the site in
millimetres (a sequence: Rerun time lines are integers or times); ``passage``
numbers the passages, ``diagnosis`` the diagnoses (the ``diagnosis/*`` entities are
the same for every wheel: select one on that time line). All series go in with ``send_columns`` (one call per
entity and passage). The default blueprint stacks force, indentation, y_C/y_C^k
and the rail, on the ``x_mm`` time line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import NDArray

from schemas.diagnosis import Diagnosis
from schemas.messages import PassageResult, RailState

X_TIMELINE = "x_mm"
PASSAGE_TIMELINE = "passage"
DIAGNOSIS_TIMELINE = "diagnosis"
VERDICT_LEVELS = {"ok": "INFO", "watch": "WARN", "inspect": "WARN", "remove": "ERROR"}
TRANSITION_COLORS = {
    "loss": (230, 60, 60),
    "contact": (60, 160, 60),
    "yield": (240, 160, 0),
    "unyield": (120, 120, 240),
}


def default_blueprint() -> rrb.Blueprint:
    """Force on top (the thing to look at), then indentation, motion and the rail."""
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.TimeSeriesView(
                name="Contact force F [kN] along the site [mm]", origin="/force",
                plot_legend=rrb.PlotLegend(visible=False),
            ),
            rrb.TimeSeriesView(
                name="Indentation δ [µm]", origin="/indentation",
                plot_legend=rrb.PlotLegend(visible=False),
            ),
            rrb.Horizontal(
                rrb.TimeSeriesView(
                    name="Wheel centre y_C and constraint y_C^k [µm]", origin="/motion",
                    plot_legend=rrb.PlotLegend(visible=False),
                ),
                rrb.TimeSeriesView(name="Rail: profile and dents [µm]", origin="/rail"),
                rrb.TextLogView(name="Passages", origin="/events"),
            ),
            rrb.Horizontal(
                rrb.TimeSeriesView(name="Diagnosis: measured and fitted force [kN]",
                                   origin="/diagnosis"),
                rrb.TextLogView(name="Verdicts", origin="/diagnosis/verdict"),
                column_shares=[3, 1],
            ),
            row_shares=[3, 2, 2, 2],
        ),
        rrb.TimePanel(timeline=X_TIMELINE, state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
    )


def x_index(x_m: NDArray[np.float64]) -> NDArray[np.int64]:
    """Positions in m → the ``x_mm`` sequence."""
    return np.rint(np.asarray(x_m) * 1000.0).astype(np.int64)


class RerunRecording:
    """Writes one ``.rrd``; not thread-safe (the twin's recorder thread owns it)."""

    def __init__(self, path: Path, site_id: str, *, recording_id: str | None = None) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.rec = rr.RecordingStream(f"railtwin-{site_id}", recording_id=recording_id)
        self.rec.save(str(path), default_blueprint=default_blueprint())
        self._passages = 0
        self._diagnoses = 0
        self._closed = False

    def log_rail(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> None:
        """The site's rail profile (µm) along the site."""
        self.rec.log("rail/profile", rr.SeriesLines(names="rail y_r [µm]"), static=True)
        self.rec.send_columns(
            "rail/profile",
            indexes=[rr.TimeColumn(X_TIMELINE, sequence=x_index(x))],
            columns=rr.Scalars.columns(scalars=np.asarray(y) * 1e6),
        )

    def log_dent(self, passage_id: str, state: RailState) -> None:
        """The accumulated dent depth after ``passage_id`` (µm, positive down)."""
        entity = f"rail/dent/{passage_id}"
        self.rec.log(entity, rr.SeriesLines(names=f"dent after {passage_id} [µm]"), static=True)
        self.rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(X_TIMELINE, sequence=x_index(np.asarray(state.x)))],
            columns=rr.Scalars.columns(scalars=np.asarray(state.dent) * 1e6),
        )

    def log_passage(self, result: PassageResult) -> None:
        """Force, indentation, y_C, y_C^k, transitions and a text line for one passage."""
        pid = result.passage_id
        x = np.asarray(result.x)
        xs = x_index(x)
        n = len(xs)
        index = [
            rr.TimeColumn(X_TIMELINE, sequence=xs),
            rr.TimeColumn(PASSAGE_TIMELINE, sequence=np.full(n, self._passages, dtype=np.int64)),
        ]
        force = np.asarray(result.force)
        series = (
            (f"force/{pid}", force * 1e-3, f"{pid} F [kN]"),
            (f"indentation/{pid}", np.asarray(result.indentation) * 1e6, f"{pid} δ [µm]"),
            (f"motion/y_c/{pid}", np.asarray(result.y_c) * 1e6, f"{pid} y_C [µm]"),
            (f"motion/y_ck/{pid}", np.asarray(result.y_ck) * 1e6, f"{pid} y_C^k [µm]"),
        )
        for entity, values, _name in series:
            self.rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))
        if result.transitions:
            tx = np.array([tr.x if tr.x is not None else result.speed * tr.t
                           for tr in result.transitions])
            tf = np.interp(tx, x, force) * 1e-3 if n else np.zeros(len(tx))
            colors = [TRANSITION_COLORS[tr.kind] for tr in result.transitions]
            entity = f"force/{pid}/transitions"
            self.rec.log(
                entity, rr.SeriesPoints(markers="circle", marker_sizes=4.0,
                                        names=f"{pid} transitions"), static=True,
            )
            self.rec.send_columns(
                entity,
                indexes=[
                    rr.TimeColumn(X_TIMELINE, sequence=x_index(tx)),
                    rr.TimeColumn(PASSAGE_TIMELINE,
                                  sequence=np.full(len(tx), self._passages, dtype=np.int64)),
                ],
                columns=[
                    *rr.Scalars.columns(scalars=tf),
                    *rr.SeriesPoints.columns(colors=colors),
                ],
            )
        s = result.summary
        self.rec.set_time(X_TIMELINE, sequence=0)
        self.rec.set_time(PASSAGE_TIMELINE, sequence=self._passages)
        self.rec.log(
            "events",
            rr.TextLog(
                f"{pid}: peak {s.peak_force / 1e3:.1f} kN, {s.contact_losses} contact losses, "
                f"max δ {s.max_indentation * 1e6:.1f} µm, dent {s.max_dent * 1e6:.2f} µm",
                level="WARN" if s.contact_losses or s.max_dent > 0 else "INFO",
            ),
        )
        self._passages += 1

    def log_diagnosis(
        self, diag: Diagnosis, t: NDArray[np.float64], measured: NDArray[np.float64],
        fitted: NDArray[np.float64], x: NDArray[np.float64], impacts_x: NDArray[np.float64],
    ) -> None:
        """Measured vs fitted force (kN) along the site, the impacts and the verdict.

        ``t`` (s) are the measured times, ``x`` (m) the wheel centre's positions then;
        ``impacts_x`` (m) where the fitted flat meets the rail.
        """
        del t  # the series go along x_mm, like the passages
        if self._diagnoses == 0:
            self.rec.log("diagnosis/measured", rr.SeriesLines(
                names="measured F [kN]", colors=(120, 120, 120)), static=True)
            self.rec.log("diagnosis/fit", rr.SeriesLines(
                names="fit F [kN]", colors=(230, 60, 60)), static=True)
            self.rec.log("diagnosis/impacts", rr.SeriesPoints(
                markers="cross", marker_sizes=6.0, names="impacts"), static=True)
        n = len(x)
        index = [
            rr.TimeColumn(X_TIMELINE, sequence=x_index(x)),
            rr.TimeColumn(DIAGNOSIS_TIMELINE, sequence=np.full(n, self._diagnoses, dtype=np.int64)),
        ]
        self.rec.send_columns("diagnosis/measured", indexes=index,
                              columns=rr.Scalars.columns(scalars=measured * 1e-3))
        self.rec.send_columns("diagnosis/fit", indexes=index,
                              columns=rr.Scalars.columns(scalars=fitted * 1e-3))
        if len(impacts_x) and n:
            order = np.argsort(x)
            f = np.interp(impacts_x, x[order], fitted[order]) * 1e-3
            self.rec.send_columns(
                "diagnosis/impacts",
                indexes=[
                    rr.TimeColumn(X_TIMELINE, sequence=x_index(impacts_x)),
                    rr.TimeColumn(DIAGNOSIS_TIMELINE,
                                  sequence=np.full(len(impacts_x), self._diagnoses,
                                                   dtype=np.int64)),
                ],
                columns=rr.Scalars.columns(scalars=f),
            )
        flat = diag.flat
        found = (f"{flat.kind} {flat.length * 1e3:.1f} mm "
                 f"[{flat.length_low * 1e3:.1f}, {flat.length_high * 1e3:.1f}]"
                 if flat is not None else "no flat")
        self.rec.set_time(X_TIMELINE, sequence=0)
        self.rec.set_time(DIAGNOSIS_TIMELINE, sequence=self._diagnoses)
        self.rec.log("diagnosis/verdict", rr.TextLog(
            f"{diag.passage_id}: {diag.verdict.upper()}, {found}, measured peak "
            f"{diag.peak_force_measured / 1e3:.0f} kN, fit peak {diag.peak_force_fit / 1e3:.0f} kN"
            + (f"; {'; '.join(diag.reasons)}" if diag.reasons else ""),
            level=VERDICT_LEVELS[diag.verdict],
        ))
        self._diagnoses += 1

    def close(self) -> None:
        """Flush and write the footer."""
        if not self._closed:
            self._closed = True
            self.rec.flush()
            rr.disconnect(self.rec)
