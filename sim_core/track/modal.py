"""The finite track reduced to its modes: a diagonal first-order system the stepper advances exactly.

From M, C, K (``sim_core.track.assembly``):

1. the undamped modes up to ``cutoff`` Hz, mass-normalised (Φ, ω²);
2. the non-proportional damping projected on them, Φᵀ C Φ, and the first-order
   system of (q, q̇) diagonalised: complex modes ζ with ζ̇ = λ·ζ + R(x)·F, where
   the contact force F pushes the rail down at x through the element's shape
   functions. Conjugate pairs are kept once, with weight 2. The system is symmetric
   (M, C, K are), so a mode's left eigenvector is its right one transposed: the load a
   force puts on a mode is its deflection shape times one constant, and scaling each
   mode by that constant's square root makes the two the same row R (with the weight
   folded in, the rail's deflection is Σ Re(R_j(x)·ζ_j));
3. what the truncation leaves out, kept statically: the residual flexibility of
   the modes above the cutoff (Kᵀ⁻¹ less the modal sum) on every element, and
   the element's own "bubble", the local deflection under a point load between
   its nodes (``beam.bubble_compliance``). Both act in series with the contact.
   Kᵀ⁻¹ is needed only on the kept elements' dofs: their columns are solved from a sparse
   LU factorisation of K (``_compliance_columns``; K is banded but for the sleepers' dofs),
   not read from a dense inverse: the same to rounding, in a quarter to a tenth of the time.

The undamped modes depend on K and M only: a track that differs in its damping alone
(the calibration's damping sensitivities) reuses them (``_undamped``, keyed by the track
without its damping and the stretch: the same K and M to the bit) and solves only the
small complex eigenproblem.

The rail under the wheel is then w(x) = Σ Re(R_j(x)·ζ_j) − r(x)·F, with R
interpolated from the nodal rows by the element's shape functions, and a crib's
channel is F inside the crib plus the rail's inertia between its gauges,
Σ Re(A_ij·ζ̇_j) (MODEL.md §8). Only the elements the wheel rolls over keep their rows
(the rest of the model, margins and absorbers, acts through the modes).

Worked example (the static point compliance of the reduced model equals the
finite element one, whatever the cutoff):

    >>> from sim_core.track.spec import Support, TrackSpec
    >>> t = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))
    >>> mt = reduce_track(t, 0.0, 1.2, cutoff=1500.0)
    >>> abs(mt.static_compliance(0.3) / mt.fe_static_compliance(0.3) - 1) < 1e-9
    True
"""

from __future__ import annotations

import dataclasses
import functools
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from sim_core.track import store
from sim_core.track.assembly import ABSORBER_RATE, TrackMatrices, assemble
from sim_core.track.beam import (
    bubble_compliance,
    deflection_integral,
    deflection_shapes_at,
    shear_ratio,
)
from sim_core.track.lanes import PAD_LAMBDA, padded_parts
from sim_core.track.layout import ABSORBER_BAYS, ELEMENTS_PER_BAY, MARGIN_BAYS, TrackLayout, layout
from sim_core.track.spec import Crib, Support, TrackError, TrackSpec
from sim_core.track.stepper import CRIB_GROUP, MODE_DTYPE, Modes

CUTOFF = 12000.0
"""Highest undamped track frequency kept as a mode, Hz (convergence: docs/MODEL.md §8).

12 kHz, three times the 4 kHz band the channels are compared in: against 16 kHz (a quarter
more modes, a quarter more work a step) the reference cases' peaks move by ≤ 0.15 % and
their filtered channels by ≤ 0.15 % of P; against 24 kHz the site case's filtered channels
stay within 0.43 % of P (16 kHz: 0.21 %). At 10 and 9 kHz the flat's case T04 moves by
0.6 and 0.8 % of P."""

MAX_MODES = 1500
"""At most this many modes: the work per step, and the reduction's dense eigen-solves, grow
with them (a documented limit: docs/CONTRACT.md; a 30 m stretch of 0.6 m bays needs ~800)."""

MAX_DOFS = 4000
"""At most this many finite-element degrees of freedom before the reduction (its dense
eigen-solves grow as their cube: ~2 400 for 30 m of 0.6 m bays)."""

BUBBLE_POINTS = 33
"""Samples of an element's bubble compliance over ξ in [0, 1] (interpolated linearly)."""

UNDAMPED_KEPT = 4
"""Undamped mode sets kept in memory for reuse (``_undamped``): a calibration's sensitivities
to the damping values share the modes of the track they start from."""

UNDAMPED_MAX_DOFS = 1500
"""Only models up to this many dofs keep their modes for reuse (the calibration's ~450, a
few MB at most each; the twin's 30 m stretches, ~2 400 dofs, are reduced once and would
hold ~20 MB each)."""


_BUBBLE_GRID = np.linspace(0.0, 1.0, BUBBLE_POINTS)
"""ξ of the bubble's samples."""


class TrackTooLargeError(TrackError):
    """The finite track would need more modes than ``MAX_MODES`` (field ``foundation``)."""


@dataclass(frozen=True, eq=False)
class ModalTrack:
    """The reduced track: what the compiled stepper reads (see the module's docstring)."""

    track: TrackSpec
    layout: TrackLayout
    cutoff: float
    lam: NDArray[np.complex128]
    weight: NDArray[np.float64]
    rows: NDArray[np.complex128]
    """(rail dofs of the kept elements, modes): R, the deflection per unit ζ and the load per
    unit downward force at once (the modes scaled so that the two are the same)."""
    first_element: int
    """The finite model's index of the first kept element (the wheel's stretch)."""
    elem_x: NDArray[np.float64]
    elem_len: NDArray[np.float64]
    elem_phi: NDArray[np.float64]
    resid: NDArray[np.float64]
    bubble: NDArray[np.float64]
    crib_ids: tuple[str, ...]
    crib_lo: NDArray[np.float64]
    crib_hi: NDArray[np.float64]
    crib_rows: NDArray[np.complex128]
    """(cribs, modes): A, the rail's inertia between the gauges per ζ̇ (weights folded in)."""
    fe_compliance_blocks: NDArray[np.float64]

    @property
    def n_modes(self) -> int:
        return int(self.lam.size)

    @functools.cached_property
    def arrays(self) -> Modes:
        """The compiled stepper's view: real and imaginary parts apart, the modes' arrays in
        ``MODE_DTYPE`` (single precision), padded with inert modes to a multiple of
        ``lanes.LANES`` and aligned to cache lines (``sim_core.track.lanes``)."""

        def c(a: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.ascontiguousarray(a, dtype=np.float64)

        lam_r, lam_i = padded_parts(self.lam, MODE_DTYPE, PAD_LAMBDA)
        row_r, row_i = padded_parts(self.rows, MODE_DTYPE)
        nc = len(self.crib_ids)
        crib_r, crib_i = padded_parts(
            _crib_groups(self.crib_rows.reshape(nc, self.n_modes)), MODE_DTYPE
        )
        return Modes(
            lam_r,
            lam_i,
            row_r,
            row_i,
            c(self.elem_x),
            c(self.elem_len),
            c(self.elem_phi),
            c(self.resid),
            c(self.bubble),
            c(self.crib_lo),
            c(self.crib_hi),
            crib_r,
            crib_i,
        )

    def element_of(self, x: float) -> int:
        """The kept element holding x (the first or last one beyond them)."""
        i = int(np.searchsorted(self.elem_x, x, side="right")) - 1
        return min(max(i, 0), self.elem_x.size - 1)

    def shapes_at(self, x: float) -> tuple[int, NDArray[np.float64]]:
        """(the element holding x, its four deflection shape functions at x)."""
        e = self.element_of(x)
        length = float(self.elem_len[e])
        xi = (x - float(self.elem_x[e])) / length
        return e, deflection_shapes_at(xi, length, float(self.elem_phi[e]))

    def rows_at(self, x: float) -> NDArray[np.complex128]:
        """R at x: every mode's deflection per unit ζ, and its load per unit downward force."""
        e, n = self.shapes_at(x)
        return n @ self.rows[2 * e : 2 * e + 4]

    def bubble_compliance(self, x: float) -> float:
        """The element's own local static compliance at x (0 on a node), m/N."""
        e = self.element_of(x)
        xi = (x - self.elem_x[e]) / self.elem_len[e]
        return float(np.interp(xi, _BUBBLE_GRID, self.bubble[e]))

    def residual_compliance(self, x: float) -> float:
        """r(x), m/N: the static compliance the kept modes leave out (truncation and bubble)."""
        e, n = self.shapes_at(x)
        return float(n @ self.resid[e] @ n) + self.bubble_compliance(x)

    def static_compliance(self, x: float) -> float:
        """The reduced model's static point compliance at x, m/N (modes plus residual)."""
        r = self.rows_at(x)
        # a unit downward force holds ζ = -R/λ; the rail moves by Σ Re(R·ζ) (down)
        modal = float(np.sum((r * r / self.lam).real))
        return modal + self.residual_compliance(x)

    def fe_static_compliance(self, x: float) -> float:
        """The finite-element model's static point compliance at x (with the bubble), m/N."""
        e, n = self.shapes_at(x)
        return float(n @ self.fe_compliance_blocks[e] @ n) + self.bubble_compliance(x)


def reduce_track(
    track: TrackSpec,
    x0: float,
    x1: float,
    cribs: tuple[Crib, ...] = (),
    *,
    cutoff: float = CUTOFF,
    margin_bays: int = MARGIN_BAYS,
    absorber_bays: int = ABSORBER_BAYS,
    elements_per_bay: int = ELEMENTS_PER_BAY,
) -> ModalTrack:
    """The modal track for a wheel from ``x0`` to ``x1`` (cached: the same arguments, the same object).

    An object served from memory still marks its disk entry used (``store.touch``, at most
    every ``store.TOUCH_INTERVAL``), so that the disk cache's bound evicts other entries
    first."""
    args = (track, round(x0, 9), round(x1, 9), cribs, cutoff, margin_bays, absorber_bays)
    mt = _reduce(*args, elements_per_bay)
    store.touch(_store_inputs(*args, elements_per_bay))
    return mt


def _crib_groups(a: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """The cribs' rows ``a`` with zero rows appended to a multiple of ``stepper.CRIB_GROUP``
    (the stepper adds the cribs' inertia four at a time)."""
    pad = -a.shape[0] % CRIB_GROUP
    return np.concatenate([a, np.zeros((pad, a.shape[1]))]) if pad else a


def _store_inputs(
    track: TrackSpec,
    x0: float,
    x1: float,
    cribs: tuple[Crib, ...],
    cutoff: float,
    margin_bays: int,
    absorber_bays: int,
    elements_per_bay: int,
) -> tuple[Any, ...]:
    """Everything a reduction depends on: its disk cache entry is ``store.key`` of it."""
    return (
        track,
        x0,
        x1,
        cribs,
        cutoff,
        margin_bays,
        absorber_bays,
        elements_per_bay,
        ABSORBER_RATE,
    )


@functools.lru_cache(maxsize=8)
def _reduce(
    track: TrackSpec,
    x0: float,
    x1: float,
    cribs: tuple[Crib, ...],
    cutoff: float,
    margin_bays: int,
    absorber_bays: int,
    elements_per_bay: int,
) -> ModalTrack:
    gauges = tuple(g for c in cribs for g in (c.x_a, c.x_b))
    name = store.key(
        _store_inputs(track, x0, x1, cribs, cutoff, margin_bays, absorber_bays, elements_per_bay)
    )
    kept = store.load(name, (*_ARRAYS, *_LAYOUT))
    restored = _restored_layout(kept) if kept is not None else None
    if kept is not None and restored is not None:
        # the entry keeps its layout (its key names every input of it): not made again
        _check_dofs(track, restored)
        return _from_arrays(track, restored, cutoff, cribs, kept)
    lay = layout(
        track,
        x0,
        x1,
        gauges=gauges,
        margin_bays=margin_bays,
        absorber_bays=absorber_bays,
        elements_per_bay=elements_per_bay,
    )
    _check_dofs(track, lay)
    same_km = (_stiffness_key(track), x0, x1, gauges, margin_bays, absorber_bays, elements_per_bay)
    mt = _modal(assemble(track, lay), cutoff, cribs, x0, x1, modes_key=same_km)
    store.save(
        name,
        {f: getattr(mt, f) for f in _ARRAYS}
        | {
            "x": lay.x,
            "sleepers": np.asarray(lay.sleepers, dtype=np.float64),
            "sleeper_nodes": lay.sleeper_nodes,
            "absorb": lay.absorb,
        },
    )
    return mt


_ARRAYS = (
    "lam",
    "weight",
    "rows",
    "first_element",
    "elem_x",
    "elem_len",
    "elem_phi",
    "resid",
    "bubble",
    "crib_lo",
    "crib_hi",
    "crib_rows",
    "fe_compliance_blocks",
)
"""The fields of a ``ModalTrack`` that are arrays (what the disk cache keeps)."""


_LAYOUT = ("x", "sleepers", "sleeper_nodes", "absorb")
"""The ``TrackLayout`` arrays an entry keeps beside the reduction."""


def _restored_layout(kept: dict[str, NDArray[Any]]) -> TrackLayout | None:
    """The entry's ``TrackLayout``, or None if its arrays do not fit together (a damaged entry
    whose CRC held: the reduction is then made again)."""
    x, sleepers, nodes, absorb = (kept[f] for f in _LAYOUT)
    n = x.size
    if (
        x.ndim != 1
        or n < 2
        or absorb.shape != (n - 1,)
        or nodes.shape != sleepers.shape
        or nodes.dtype.kind != "i"
        or not np.all((nodes >= 0) & (nodes < n))
    ):
        return None
    return TrackLayout(x, tuple(sleepers.tolist()), nodes, absorb)


def _check_dofs(track: TrackSpec, lay: TrackLayout) -> None:
    """Refuse a finite model of more than ``MAX_DOFS`` degrees of freedom (field ``foundation``)."""
    dofs = 2 * lay.n_nodes + (len(lay.sleepers) if track.kind == "discrete" else 0)
    if dofs > MAX_DOFS:
        raise TrackTooLargeError(
            "foundation",
            f"the track model would have {dofs} degrees of freedom, more than MAX_DOFS = "
            f"{MAX_DOFS}: shorten the simulated stretch or lengthen the sleeper spacing",
        )


def _from_arrays(
    track: TrackSpec,
    lay: TrackLayout,
    cutoff: float,
    cribs: tuple[Crib, ...],
    a: dict[str, NDArray[Any]],
) -> ModalTrack:
    fields: dict[str, Any] = {f: a[f] for f in _ARRAYS}
    fields["first_element"] = int(fields["first_element"])
    return ModalTrack(
        track=track, layout=lay, cutoff=cutoff, crib_ids=tuple(c.id for c in cribs), **fields
    )


_UNDAMPED: OrderedDict[Any, tuple[NDArray[np.float64], NDArray[np.float64]]] = OrderedDict()
_UNDAMPED_LOCK = threading.Lock()


def _undamped(
    k: NDArray[np.float64], m: NDArray[np.float64], w2max: float, key: Any = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(ω², Φ): the mass-normalised undamped modes of K, M with ω² ≤ ``w2max``. With a
    ``key`` (what K and M are made from: ``_stiffness_key``), the last ``UNDAMPED_KEPT``
    sets are reused (module docstring)."""
    if key is None or k.shape[0] > UNDAMPED_MAX_DOFS:
        w2, phi = sla.eigh(k, m, subset_by_value=(-np.inf, w2max), driver="gvx")
        return w2, phi
    full = (key, float(w2max))
    with _UNDAMPED_LOCK:
        got = _UNDAMPED.get(full)
        if got is not None:
            _UNDAMPED.move_to_end(full)
            return got
    w2, phi = sla.eigh(k, m, subset_by_value=(-np.inf, w2max), driver="gvx")
    w2.flags.writeable = False
    phi.flags.writeable = False
    with _UNDAMPED_LOCK:
        _UNDAMPED[full] = (w2, phi)
        while len(_UNDAMPED) > UNDAMPED_KEPT:
            _UNDAMPED.popitem(last=False)
    return w2, phi


def _stiffness_key(track: TrackSpec) -> TrackSpec:
    """``track`` without its damping: what K and M depend on (``assembly.assemble`` puts the
    pads' and the ballast's damping in C alone)."""
    ballast = None if track.ballast is None else Support(track.ballast.stiffness)
    return dataclasses.replace(track, pad=Support(track.pad.stiffness), ballast=ballast)


def _compliance_columns(k: NDArray[np.float64], lo: int, hi: int) -> NDArray[np.float64]:
    """K⁻¹[lo:hi, lo:hi]: the static compliance among dofs lo..hi-1, from a sparse LU of K
    solved for those columns only (the same as a dense inverse's to rounding)."""
    n = k.shape[0]
    cols = np.arange(lo, hi)
    rhs = np.zeros((n, cols.size))
    rhs[cols, np.arange(cols.size)] = 1.0
    x = spla.splu(sps.csc_matrix(k)).solve(rhs)
    return np.asarray(x[lo:hi], dtype=np.float64)


def _modal(
    mats: TrackMatrices,
    cutoff: float,
    cribs: tuple[Crib, ...],
    x0: float,
    x1: float,
    *,
    modes_key: Any = None,
) -> ModalTrack:
    lay = mats.layout
    nr = mats.n_rail_dofs
    w2max = (2.0 * np.pi * cutoff) ** 2
    w2, phi = _undamped(mats.k, mats.m, w2max, modes_key)
    n = w2.size
    cr = phi.T @ mats.c @ phi
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -np.diag(w2)
    a[n:, n:] = -cr
    lam, v = sla.eig(a)
    keep = lam.imag > 1e-9 * np.abs(lam)
    real = np.abs(lam.imag) <= 1e-9 * np.abs(lam)
    sel = keep | real
    if int(sel.sum()) > MAX_MODES:
        raise TrackTooLargeError(
            "foundation",
            f"the track model needs {int(sel.sum())} modes below {cutoff:g} Hz, more than "
            f"MAX_MODES = {MAX_MODES}: shorten the simulated stretch or lengthen the sleeper spacing",
        )
    weight = np.where(keep[sel], 2.0, 1.0)
    lam_k = lam[sel]
    # a mode ψ = (a, λa) of the symmetric pencil B·ẋ + C·x = (Φᵀf, 0), B = [[Cr, I], [I, 0]],
    # C = diag(Ω², −I): ψᵀBψ = aᵀCr·a + 2λ·aᵀa =: b, and the mode's equation is
    # ζ̇ = λζ + aᵀΦᵀf/b. A downward force F at x loads it by −h(x)·F/b with h = N(x)·Φ·a
    # its deflection: scaled by s = √(−weight/b), deflection and load are one row R = s·h.
    a_k = v[:n, sel]
    b = np.einsum("ij,ij->j", a_k, cr @ a_k) + 2.0 * lam_k * np.einsum("ij,ij->j", a_k, a_k)
    scale = np.sqrt(-weight / b)
    phi_r = phi[:nr]
    n_el = lay.n_nodes - 1
    first = max(int(np.searchsorted(lay.x, x0 - 1e-9, side="right")) - 2, 0)
    last = min(int(np.searchsorted(lay.x, x1 + 1e-9, side="left")) + 1, n_el)
    rows = (phi_r[2 * first : 2 * last + 2] @ a_k) * scale
    acc = (phi_r @ a_k) * (lam_k * scale)
    # static: FE compliance blocks and the truncation's residual, per element
    kinv = _compliance_columns(mats.k, 2 * first, 2 * last + 2)
    kept = range(first, last)
    blocks = np.empty((len(kept), 4, 4))
    resid = np.empty((len(kept), 4, 4))
    for k, e in enumerate(kept):
        d = slice(2 * e, 2 * e + 4)
        blocks[k] = kinv[2 * k : 2 * k + 4, 2 * k : 2 * k + 4]
        resid[k] = blocks[k] - (phi_r[d] / w2) @ phi_r[d].T
    lengths = lay.lengths[first:last]
    phis = np.array([shear_ratio(mats.track.rail, float(L)) for L in lengths])
    grid = np.linspace(0.0, 1.0, BUBBLE_POINTS)
    bub_cache: dict[float, NDArray[np.float64]] = {}
    bubble = np.empty((len(kept), BUBBLE_POINTS))
    for e, L in enumerate(lengths):
        key = round(float(L), 12)
        if key not in bub_cache:
            bub_cache[key] = bubble_compliance(mats.track.rail, key, grid)
        bubble[e] = bub_cache[key]
    crib_rows = np.zeros((len(cribs), lam_k.size), dtype=np.complex128)
    all_lengths = lay.lengths
    for i, c in enumerate(cribs):
        ai = np.zeros(nr)
        for e in range(n_el):
            if lay.x[e] >= c.x_a - 1e-9 and lay.x[e + 1] <= c.x_b + 1e-9:
                ai[2 * e : 2 * e + 4] += deflection_integral(mats.track.rail, float(all_lengths[e]))
        crib_rows[i] = ai @ acc
    return ModalTrack(
        track=mats.track,
        layout=lay,
        cutoff=cutoff,
        lam=np.ascontiguousarray(lam_k),
        weight=weight,
        rows=np.ascontiguousarray(rows),
        first_element=first,
        elem_x=np.ascontiguousarray(lay.x[first:last]),
        elem_len=np.ascontiguousarray(lengths),
        elem_phi=phis,
        resid=resid,
        bubble=bubble,
        crib_ids=tuple(c.id for c in cribs),
        crib_lo=np.array([c.x_a for c in cribs], dtype=np.float64),
        crib_hi=np.array([c.x_b for c in cribs], dtype=np.float64),
        crib_rows=crib_rows,
        fe_compliance_blocks=blocks,
    )
