"""The service run's Rerun recording: one headless ``.rrd``, a fixed set of entities.

Every passage goes to the same entities under the site's id ``<site>`` (so the
entity tree does not grow with the run: a months-long run has as many
entities as a run of one wheel; ``tests/test_service_rerun.py``):

| entity | what | unit |
|---|---|---|
| ``<site>/force`` | contact force F of every wheel | N |
| ``<site>/force/transitions`` | markers: losses/returns of contact, yield/unyield | N |
| ``<site>/indentation`` | indentation δ (negative: out of contact) | m |
| ``<site>/motion/y_c``, ``<site>/motion/y_ck`` | wheel centre y_C, rigid constraint y_C^k | m |
| ``<site>/wheel`` | a text document naming the wheel (id, train, axle, side, speed, load, result) | |
| ``<site>/passages`` | one text line per passage (peak force, losses, dent) | |
| ``<site>/rail/profile`` | the site's rail as the service started | m |
| ``<site>/rail/dent`` | accumulated dent depth after each passage that dented | m |
| ``<site>/diagnosis/measured``, ``.../fit`` | measured and best-fit force of each diagnosis | N |
| ``<site>/diagnosis/impacts`` | markers: the fitted flat under the wheel | N |
| ``<site>/channels/<crib>`` | a detector's crib channel Q(x_a) − Q(x_b) of every wheel | N |

Everything is in SI units (N, m, s), as in the messages, and every series and view
names its unit (``F [N]``, ``δ [m]``); the text lines too.
| ``<site>/diagnosis/verdict`` | one text line per diagnosis (verdict, flat, peak forces) | |

At a site with a detector, each crib's channel (``PassageResult.channels``) goes to
``<site>/channels/<crib>`` along the same time lines as the force; the default blueprint
then has a second tab, ``Crib channels``: one plot per crib, its channel with the wheel's
contact force F beside it (both in N: ≈ F while the wheel is between the crib's gauges,
≈ 0 otherwise). The cribs are a site's fixed set, so the entities still do not grow.

Time lines:

- ``time`` (a timestamp, the wall clock): when each sample happened, the passage's own
  time (``WheelPassage.timestamp``, the wheel at x = 0) plus x/speed. Text lines (the
  wheel, the passage log, a diagnosis's verdict) are at the passage's time. It goes on
  across runs and parts: recordings of several runs opened together lie in time order.
- ``passage_time`` (a timestamp): the passage's own time, on every sample of the
  passage, so that, like ``passage`` below but across runs, the series views draw each
  wheel as one vertical stroke (a trend over days or months).
- ``passage``: the passage's index in the run, 0, 1, 2, ... Every sample of a
  passage carries it; on this time line the series views draw each wheel as
  one vertical stroke from its lowest to its highest value (a trend of the run)
  and the ``wheel`` document names the wheel at the cursor.
- ``x_mm``: ``passage·10⁶ + position along the site in mm``. Each passage has
  its own kilometre of this time line, so the wheels lie end to end and never
  overlap (one entity drawing wheels that share positions would zig-zag between
  them). Passage 3 at 450 mm along the site is ``x_mm`` = 3 000 450. The
  default blueprint's plots show the ±500 m around the time cursor on it, i.e.
  exactly one wheel: click a line of the ``Passages`` log (or step the cursor)
  to see that wheel, named beside the force plot.
- diagnoses are on ``time`` and ``passage_time`` too, at their passage's time (as
  recorded in this run, else ``Diagnosis.timestamp``);
- ``diagnosis`` and ``diagnosis_mm``: the same for diagnoses (index ``d``,
  ``d·10⁶ + mm``). A diagnosis whose passage was recorded in this run (among
  the last ``KEPT_PASSAGE_INDEXES``) is drawn in that passage's slot of
  ``x_mm`` as well, beside the simulated wheel.

All series go in with ``send_columns`` (one call per entity and passage, ~0.5 ms
for 1 350 samples). Sites must be shorter than 500 m (half a slot).

Parts: the SDK keeps each file's footer (an entry per chunk) in memory until the
file is closed, ~7 MB per 1 000 passages, so after ``PART_PASSAGES`` passages and
diagnoses the recording goes on in ``<stem>-002.rrd``, ``-003`` ... with the same
recording id (the viewer opened on all parts shows one recording; each part has
the blueprint, the styles and the rail profile again). Passage indexes go on
across parts.
"""

from __future__ import annotations

import uuid
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import NDArray

from schemas.diagnosis import Diagnosis
from schemas.messages import PassageResult, RailState

X_TIMELINE = "x_mm"
PASSAGE_TIMELINE = "passage"
TIME_TIMELINE = "time"
PASSAGE_TIME_TIMELINE = "passage_time"
DIAGNOSIS_TIMELINE = "diagnosis"
DIAGNOSIS_X_TIMELINE = "diagnosis_mm"
SLOT_MM = 1_000_000
"""Length of one passage's slot on ``x_mm`` (1 km): passage p starts at p·SLOT_MM."""
MAX_SITE_MM = SLOT_MM // 2
PART_PASSAGES = 5000
"""Passages (and diagnoses) per ``.rrd`` part: the SDK holds a part's footer in memory."""
KEPT_PASSAGE_INDEXES = 4096
"""Passage ids remembered (newest) to draw a diagnosis beside its wheel; bounded."""
VERDICT_LEVELS = {"ok": "INFO", "watch": "WARN", "inspect": "WARN", "remove": "ERROR"}
TRANSITION_COLORS = {
    "loss": (230, 60, 60),
    "contact": (60, 160, 60),
    "yield": (240, 160, 0),
    "unyield": (120, 120, 240),
}


def entities(site_id: str) -> dict[str, str]:
    """{role: entity path} of a site's recording (the whole, fixed set)."""
    root = f"/{rr.escape_entity_path_part(site_id)}"
    return {
        "root": root,
        "force": f"{root}/force",
        "transitions": f"{root}/force/transitions",
        "indentation": f"{root}/indentation",
        "y_c": f"{root}/motion/y_c",
        "y_ck": f"{root}/motion/y_ck",
        "motion": f"{root}/motion",
        "wheel": f"{root}/wheel",
        "passages": f"{root}/passages",
        "rail": f"{root}/rail",
        "profile": f"{root}/rail/profile",
        "dent": f"{root}/rail/dent",
        "diagnosis": f"{root}/diagnosis",
        "measured": f"{root}/diagnosis/measured",
        "fit": f"{root}/diagnosis/fit",
        "impacts": f"{root}/diagnosis/impacts",
        "verdict": f"{root}/diagnosis/verdict",
        "channels": f"{root}/channels",
    }


def channel_entity(site_id: str, crib_id: str) -> str:
    """The entity of crib ``crib_id``'s channel: ``/<site>/channels/<crib>``.

    >>> channel_entity("demo", "ch1")
    '/demo/channels/ch1'
    """
    return f"{entities(site_id)['channels']}/{rr.escape_entity_path_part(crib_id)}"


def one_wheel_window() -> list[rrb.VisibleTimeRange]:
    """±half a slot around the cursor on ``x_mm`` and ``diagnosis_mm``: exactly one wheel.

    The cursor at 3 000 450 (passage 3, 450 mm) shows 2 500 450 … 3 500 450: all of
    passage 3 (3 000 000 … 3 000 000 + site length), nothing of passages 2 or 4.
    """
    half = SLOT_MM // 2
    return [
        rrb.VisibleTimeRange(
            timeline,
            start=rrb.TimeRangeBoundary.cursor_relative(seq=-half),
            end=rrb.TimeRangeBoundary.cursor_relative(seq=half),
        )
        for timeline in (X_TIMELINE, DIAGNOSIS_X_TIMELINE)
    ]


def channel_views(site_id: str, cribs: Sequence[str]) -> rrb.Grid:
    """One plot per crib: its channel, with the wheel's contact force F beside it (N)."""
    e = entities(site_id)
    window = one_wheel_window()
    return rrb.Grid(
        *(
            rrb.TimeSeriesView(
                name=f"Crib {crib}: channel Q(x_a) − Q(x_b) and contact force F [N]",
                origin=e["root"],
                contents=[channel_entity(site_id, crib), e["force"]],
                time_ranges=window,
            )
            for crib in cribs
        ),
        grid_columns=min(len(cribs), 4),
        name="Crib channels",
    )


def default_blueprint(site_id: str, cribs: Sequence[str] = ()) -> rrb.Blueprint:
    """The wheel at the time cursor: its force (with its name beside it) on top, then
    indentation, motion, the rail, the passages and the diagnoses; with ``cribs`` (a site's
    detector) a second tab with a plot per crib channel."""
    e = entities(site_id)
    window = one_wheel_window()
    wheel = rrb.Vertical(
        rrb.Horizontal(
            rrb.TimeSeriesView(
                name="Contact force F [N] of the wheel at the cursor (x_mm: passage·10⁶ + mm)",
                origin=e["force"],
                time_ranges=window,
            ),
            rrb.TextDocumentView(name="Wheel at the cursor", origin=e["wheel"]),
            column_shares=[3, 1],
        ),
        rrb.TimeSeriesView(name="Indentation δ [m]", origin=e["indentation"], time_ranges=window),
        rrb.Horizontal(
            rrb.TimeSeriesView(
                name="Wheel centre y_C and constraint y_C^k [m]",
                origin=e["motion"],
                time_ranges=window,
            ),
            rrb.TimeSeriesView(
                name="Rail: profile (slot 0), then the dent after each denting passage [m]",
                origin=e["rail"],
            ),
            rrb.TextLogView(name="Passages (click one to show its wheel)", origin=e["passages"]),
        ),
        rrb.Horizontal(
            rrb.TimeSeriesView(
                name="Diagnosis: measured and fitted force [N]",
                origin=e["diagnosis"],
                time_ranges=window,
            ),
            rrb.TextLogView(name="Verdicts", origin=e["verdict"]),
            column_shares=[3, 1],
        ),
        row_shares=[3, 2, 2, 2],
        name="Wheel" if cribs else None,
    )
    return rrb.Blueprint(
        rrb.Tabs(wheel, channel_views(site_id, cribs), active_tab=0) if cribs else wheel,
        rrb.TimePanel(timeline=X_TIMELINE, state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
    )


def x_index(x_m: NDArray[np.float64], slot: int = 0) -> NDArray[np.int64]:
    """Positions in m of the passage in ``slot`` → the ``x_mm`` sequence.

    >>> x_index(np.array([0.0, 0.45]), slot=3).tolist()
    [3000000, 3000450]
    """
    mm = np.rint(np.asarray(x_m) * 1000.0).astype(np.int64)
    if len(mm) and (mm.min() < -MAX_SITE_MM or mm.max() >= MAX_SITE_MM):
        raise ValueError(
            f"positions {mm.min()} … {mm.max()} mm do not fit in half a slot of the x_mm "
            f"time line (±{MAX_SITE_MM} mm): the recording draws sites shorter than 500 m"
        )
    return mm + np.int64(slot) * SLOT_MM


def si(value: float, unit: str) -> str:
    """A value in its SI unit, 4 significant digits (no kN, no µm).

    >>> si(182_345.0, "N"), si(2.5e-6, "m"), si(0.0, "m")
    ('1.823e+05 N', '2.5e-06 m', '0 m')
    """
    return f"{value:.4g} {unit}"


def wheel_document(index: int, r: PassageResult) -> str:
    """The markdown that names the wheel of passage ``index`` (the ``wheel`` entity)."""
    s = r.summary
    kinds = ", ".join(
        f"{tr.kind} at {si(tr.x if tr.x is not None else r.speed * tr.t, 'm')}"
        for tr in r.transitions[:12]
    )
    more = f" (+{len(r.transitions) - 12} more)" if len(r.transitions) > 12 else ""
    return (
        f"### {r.passage_id}\n\n"
        f"passage {index} of the run (x_mm {index * SLOT_MM:_} …)\n\n"
        f"- train **{r.train_id}**, axle {r.axle_index}, {r.side} wheel\n"
        f"- speed {r.speed:.1f} m/s, site {r.site_length:g} m, rail revision {r.rail_revision}\n"
        f"- at {r.timestamp:.3f} s (UNIX)\n"
        f"- peak F **{si(s.peak_force, 'N')}**, min F {si(s.min_force, 'N')}\n"
        f"- contact losses {s.contact_losses}, out of contact {si(s.time_out_of_contact, 's')}\n"
        f"- max δ {si(s.max_indentation, 'm')}, dent {si(s.max_dent, 'm')}\n"
        f"- transitions: {kinds or 'none'}{more}\n"
        + (
            "- crib channels, peak: "
            + ", ".join(f"{c} {si(max(v, default=0.0), 'N')}" for c, v in r.channels.items())
            + "\n"
            if r.channels
            else ""
        )
    )


class RerunRecording:
    """Writes one ``.rrd``; not thread-safe (the recorder's thread or process owns it)."""

    def __init__(
        self,
        path: Path,
        site_id: str,
        *,
        recording_id: str | None = None,
        part_passages: int = PART_PASSAGES,
        cribs: Sequence[str] = (),
    ) -> None:
        """``cribs``: the ids of the site's detector's cribs (the blueprint's channel plots);
        a result's channel of another crib is drawn all the same, without a plot of its own."""
        path.parent.mkdir(parents=True, exist_ok=True)
        self.site_id = site_id
        self.entities = entities(site_id)
        self.cribs = tuple(cribs)
        self._channel_entities: dict[str, str] = {}
        """crib id -> its entity, for the cribs styled in the part being written."""
        self.recording_id = recording_id or str(uuid.uuid4())
        self.part_passages = part_passages
        self.files: list[Path] = []
        self._first = path
        self._passages = 0
        self._diagnoses = 0
        self._in_part = 0
        self._rail: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._index_of: OrderedDict[str, tuple[int, float]] = OrderedDict()
        """Recent passages: id -> (index, the passage's own time)."""
        self._closed = False
        self._open(path)

    @property
    def path(self) -> Path:
        """The part being written."""
        return self.files[-1]

    def _open(self, path: Path) -> None:
        self.rec = rr.RecordingStream(f"railtwin-{self.site_id}", recording_id=self.recording_id)
        self.rec.save(str(path), default_blueprint=default_blueprint(self.site_id, self.cribs))
        self.files.append(path)
        self._in_part = 0
        self._channel_entities = {}
        self._style()
        if self._rail is not None:
            self.log_rail(*self._rail)

    def _next_part(self) -> None:
        """Close the part after ``part_passages`` drawings and open ``<stem>-NNN.rrd``.

        The SDK keeps every chunk's entry of the file's footer in memory until the file
        is closed (~7 MB per 1 000 passages), so one endless file would grow the recorder
        without bound; the parts share the recording id, and the viewer opened on all of
        them (``rerun run*.rrd``) shows one recording.
        """
        if self._in_part < self.part_passages:
            return
        self.rec.flush()
        rr.disconnect(self.rec)
        self._open(self._first.with_name(f"{self._first.stem}-{len(self.files) + 1:03d}.rrd"))

    def _style(self) -> None:
        """Names and colours of the series, once (static)."""
        e, log = self.entities, self.rec.log
        log(e["force"], rr.SeriesLines(names="F [N]", aggregation_policy="MinMax"), static=True)
        log(
            e["transitions"],
            rr.SeriesPoints(markers="circle", marker_sizes=4.0, names="transitions F [N]"),
            static=True,
        )
        log(
            e["indentation"],
            rr.SeriesLines(names="δ [m]", aggregation_policy="MinMax"),
            static=True,
        )
        log(e["y_c"], rr.SeriesLines(names="y_C [m]"), static=True)
        log(e["y_ck"], rr.SeriesLines(names="y_C^k [m]"), static=True)
        log(e["profile"], rr.SeriesLines(names="rail y_r at start [m]"), static=True)
        log(e["dent"], rr.SeriesLines(names="accumulated dent [m]"), static=True)
        log(
            e["measured"],
            rr.SeriesLines(names="measured F [N]", colors=(120, 120, 120)),
            static=True,
        )
        log(e["fit"], rr.SeriesLines(names="fit F [N]", colors=(230, 60, 60)), static=True)
        log(
            e["impacts"],
            rr.SeriesPoints(markers="cross", marker_sizes=6.0, names="impacts F [N]"),
            static=True,
        )
        for crib in self.cribs:
            self._channel_entity(crib)

    def _channel_entity(self, crib: str) -> str:
        """Crib ``crib``'s entity, named (static) the first time in this part."""
        entity = self._channel_entities.get(crib)
        if entity is None:
            entity = self._channel_entities[crib] = channel_entity(self.site_id, crib)
            self.rec.log(
                entity,
                rr.SeriesLines(names=f"{crib} Q(x_a) − Q(x_b) [N]", aggregation_policy="MinMax"),
                static=True,
            )
        return entity

    def passage_index(self, passage_id: str) -> int | None:
        """The index (``passage`` time line) of a recent passage, None if not recorded."""
        found = self._index_of.get(passage_id)
        return None if found is None else found[0]

    def _slot(
        self,
        index: int,
        n: int,
        stamp: float | None = None,
        times: NDArray[np.float64] | None = None,
    ) -> list[rr.TimeColumn]:
        """The ``passage`` index of ``n`` rows; with the passage's time ``stamp`` also
        ``passage_time``, and ``time`` = ``stamp + times`` (s)."""
        cols = [rr.TimeColumn(PASSAGE_TIMELINE, sequence=np.full(n, index, dtype=np.int64))]
        if stamp is not None:
            cols.append(rr.TimeColumn(PASSAGE_TIME_TIMELINE, timestamp=np.full(n, stamp)))
            at = np.full(n, stamp) if times is None else stamp + np.asarray(times, np.float64)
            cols.append(rr.TimeColumn(TIME_TIMELINE, timestamp=at))
        return cols

    def _set_times(self, index: int, stamp: float | None) -> None:
        self.rec.set_time(X_TIMELINE, sequence=index * SLOT_MM)
        self.rec.set_time(PASSAGE_TIMELINE, sequence=index)
        if stamp is not None:
            self.rec.set_time(PASSAGE_TIME_TIMELINE, timestamp=stamp)
            self.rec.set_time(TIME_TIMELINE, timestamp=stamp)

    def log_rail(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> None:
        """The site's rail profile (m) as the service started, in slot 0 of ``x_mm`` (of
        every part)."""
        self._rail = (np.asarray(x), np.asarray(y))
        self.rec.send_columns(
            self.entities["profile"],
            indexes=[rr.TimeColumn(X_TIMELINE, sequence=x_index(x))],
            columns=rr.Scalars.columns(scalars=np.asarray(y, dtype=np.float64)),
        )

    def log_dent(self, passage_id: str, state: RailState) -> None:
        """The accumulated dent depth (m, positive down) after ``passage_id``, in its slot."""
        found = self._index_of.get(passage_id)
        index, stamp = found if found is not None else (max(self._passages - 1, 0), None)
        x = np.asarray(state.x)
        self.rec.send_columns(
            self.entities["dent"],
            indexes=[
                rr.TimeColumn(X_TIMELINE, sequence=x_index(x, index)),
                *self._slot(index, len(x), stamp),
            ],
            columns=rr.Scalars.columns(scalars=np.asarray(state.dent, dtype=np.float64)),
        )

    def log_passage(self, result: PassageResult) -> None:
        """Force, indentation, y_C, y_C^k, the crib channels (a site with a detector),
        transitions, the wheel's name and a text line, all in the next slot (``passage`` =
        index, ``x_mm`` = index·10⁶ + mm)."""
        self._next_part()
        e = self.entities
        index = self._passages
        x = np.asarray(result.x)
        stamp = result.timestamp
        index_cols = [
            rr.TimeColumn(X_TIMELINE, sequence=x_index(x, index)),
            *self._slot(index, len(x), stamp, x / result.speed),
        ]
        force = np.asarray(result.force, dtype=np.float64)
        series = (
            (e["force"], force),
            (e["indentation"], np.asarray(result.indentation, dtype=np.float64)),
            (e["y_c"], np.asarray(result.y_c, dtype=np.float64)),
            (e["y_ck"], np.asarray(result.y_ck, dtype=np.float64)),
        )
        channels = (
            (self._channel_entity(crib), np.asarray(values, dtype=np.float64))
            for crib, values in (result.channels or {}).items()
        )
        for entity, values in (*series, *channels):
            self.rec.send_columns(
                entity, indexes=index_cols, columns=rr.Scalars.columns(scalars=values)
            )
        if result.transitions:
            tx = np.array(
                [tr.x if tr.x is not None else result.speed * tr.t for tr in result.transitions]
            )
            tf = np.interp(tx, x, force) if len(x) else np.zeros(len(tx))
            self.rec.send_columns(
                e["transitions"],
                indexes=[
                    rr.TimeColumn(X_TIMELINE, sequence=x_index(tx, index)),
                    *self._slot(index, len(tx), stamp, tx / result.speed),
                ],
                columns=[
                    *rr.Scalars.columns(scalars=tf),
                    *rr.SeriesPoints.columns(
                        colors=[TRANSITION_COLORS[tr.kind] for tr in result.transitions]
                    ),
                ],
            )
        s = result.summary
        self._set_times(index, stamp)
        self.rec.log(
            e["wheel"],
            rr.TextDocument(wheel_document(index, result), media_type=rr.MediaType.MARKDOWN),
        )
        self.rec.log(
            e["passages"],
            rr.TextLog(
                f"#{index} {result.passage_id} (train {result.train_id} axle {result.axle_index} "
                f"{result.side}): peak {si(s.peak_force, 'N')}, {s.contact_losses} contact "
                f"losses, max δ {si(s.max_indentation, 'm')}, dent {si(s.max_dent, 'm')}",
                level="WARN" if s.contact_losses or s.max_dent > 0 else "INFO",
            ),
        )
        self.rec.reset_time()
        self._index_of[result.passage_id] = (index, stamp)
        self._index_of.move_to_end(result.passage_id)
        while len(self._index_of) > KEPT_PASSAGE_INDEXES:
            self._index_of.popitem(last=False)
        self._passages += 1
        self._in_part += 1

    def log_not_drawn(self, passage_id: str, behind_bytes: int) -> None:
        """A passage the recorder was too far behind to draw: its slot stays empty but for
        a line in the passage log (the MCAP log has the passage)."""
        self._next_part()
        index = self._passages
        self.rec.set_time(X_TIMELINE, sequence=index * SLOT_MM)
        self.rec.set_time(PASSAGE_TIMELINE, sequence=index)
        self.rec.log(
            self.entities["passages"],
            rr.TextLog(
                f"#{index} {passage_id}: not drawn, the recorder was {behind_bytes / 2**20:.0f} MB "
                "behind (the MCAP log has it)",
                level="WARN",
            ),
        )
        self.rec.reset_time()
        self._passages += 1
        self._in_part += 1

    def log_diagnosis(
        self,
        diag: Diagnosis,
        t: NDArray[np.float64],
        measured: NDArray[np.float64],
        fitted: NDArray[np.float64],
        x: NDArray[np.float64],
        impacts_x: NDArray[np.float64],
    ) -> None:
        """Measured vs fitted force (N) along the site, the impacts and the verdict.

        ``t`` (s) are the measured times, ``x`` (m) the wheel centre's positions then;
        ``impacts_x`` (m) where the fitted flat meets the rail. Drawn in the diagnosis's
        slot of ``diagnosis_mm`` and, if its passage was recorded, in that passage's slot
        of ``x_mm``.
        """
        # the series go along the site, like the passages; their time from the positions
        span = float(np.ptp(x)) if len(x) > 1 else 0.0
        duration = float(np.ptp(t)) if len(t) > 1 else 0.0
        speed = span / duration if span > 0 and duration > 0 else 1.0
        self._next_part()
        e = self.entities
        d = self._diagnoses
        found = self._index_of.get(diag.passage_id)
        index = None if found is None else found[0]
        # the passage's own time: as recorded in this run, else as the diagnosis echoes it
        stamp = found[1] if found is not None else diag.timestamp

        def indexes(positions: NDArray[np.float64]) -> list[rr.TimeColumn]:
            n = len(positions)
            cols = [
                rr.TimeColumn(DIAGNOSIS_X_TIMELINE, sequence=x_index(positions, d)),
                rr.TimeColumn(DIAGNOSIS_TIMELINE, sequence=np.full(n, d, dtype=np.int64)),
            ]
            if index is not None:
                cols += [
                    rr.TimeColumn(X_TIMELINE, sequence=x_index(positions, index)),
                    rr.TimeColumn(PASSAGE_TIMELINE, sequence=np.full(n, index, dtype=np.int64)),
                ]
            if stamp is not None:
                cols += [
                    rr.TimeColumn(PASSAGE_TIME_TIMELINE, timestamp=np.full(n, stamp)),
                    rr.TimeColumn(TIME_TIMELINE, timestamp=stamp + positions / speed),
                ]
            return cols

        at = indexes(x)
        self.rec.send_columns(
            e["measured"], indexes=at, columns=rr.Scalars.columns(scalars=measured)
        )
        self.rec.send_columns(e["fit"], indexes=at, columns=rr.Scalars.columns(scalars=fitted))
        if len(impacts_x) and len(x):
            order = np.argsort(x)
            f = np.interp(impacts_x, x[order], fitted[order])
            self.rec.send_columns(
                e["impacts"], indexes=indexes(impacts_x), columns=rr.Scalars.columns(scalars=f)
            )
        flat = diag.flat
        what = (
            f"{flat.kind} {si(flat.length, 'm')} "
            f"[{si(flat.length_low, 'm')}, {si(flat.length_high, 'm')}]"
            if flat is not None
            else "no flat"
        )
        self.rec.set_time(DIAGNOSIS_X_TIMELINE, sequence=d * SLOT_MM)
        self.rec.set_time(DIAGNOSIS_TIMELINE, sequence=d)
        if index is not None:
            self.rec.set_time(X_TIMELINE, sequence=index * SLOT_MM)
            self.rec.set_time(PASSAGE_TIMELINE, sequence=index)
        if stamp is not None:
            self.rec.set_time(PASSAGE_TIME_TIMELINE, timestamp=stamp)
            self.rec.set_time(TIME_TIMELINE, timestamp=stamp)
        self.rec.log(
            e["verdict"],
            rr.TextLog(
                f"{diag.passage_id}: {diag.verdict.upper()}, {what}, measured peak "
                f"{si(diag.peak_force_measured, 'N')}, fit peak {si(diag.peak_force_fit, 'N')}"
                + (f"; {'; '.join(diag.reasons)}" if diag.reasons else ""),
                level=VERDICT_LEVELS[diag.verdict],
            ),
        )
        self.rec.reset_time()
        self._diagnoses += 1
        self._in_part += 1

    def close(self) -> None:
        """Flush and write the footer."""
        if not self._closed:
            self._closed = True
            self.rec.flush()
            rr.disconnect(self.rec)
