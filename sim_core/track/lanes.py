"""The modes' arrays as the stepper's vector loops want them: padded and aligned to cache lines.

The stepper's loops over the modes (``sim_core.track.stepper``) read some twenty rows of
single-precision values a step. When a row's length is not a multiple of 16 values (64 bytes),
the rows of a 2-D array start at every offset within a cache line, and most vector loads
straddle two lines. Measured on the site case's 401 modes (one ``predict``, 20 000 calls):
0.44-0.71 µs a call with rows 401 values long, 0.29 µs with rows padded to 416 and starting on
a 64-byte boundary, 0.27 µs at 400.

Padding modes are inert: λ = -1 s⁻¹ (a decay, so that no coefficient divides by zero), no load
and no deflection (zero rows), a zero state. They stay zero whatever the step.

    >>> import numpy as np
    >>> padded_size(401)
    416
    >>> a = aligned_zeros((3, padded_size(401)), np.float32)
    >>> a.ctypes.data % ALIGN, a.strides[0] % ALIGN
    (0, 0)
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numpy.typing import DTypeLike, NDArray

ALIGN = 64
"""Bytes: a cache line, and one 512-bit vector."""
LANES = 16
"""Single-precision values a cache line holds: the modes are padded to a multiple of this."""
PAD_LAMBDA = -1.0
"""λ of a padding mode, s⁻¹: a slow real decay (its state is zero and stays zero)."""


def padded_size(m: int) -> int:
    """The number of modes ``m`` rounded up to a multiple of ``LANES``."""
    if m < 0:
        raise ValueError(f"number of modes: {m} < 0")
    return -(-m // LANES) * LANES


def aligned_empty(shape: int | tuple[int, ...], dtype: DTypeLike) -> NDArray[Any]:
    """An uninitialised array of ``shape`` whose first element lies on an ``ALIGN``-byte
    boundary (what ``aligned_zeros`` zeroes; the track cache reads its files into one)."""
    dt = np.dtype(dtype)
    n = int(np.prod(shape))
    buf = np.empty(n * dt.itemsize + ALIGN, dtype=np.uint8)
    off = (-buf.ctypes.data) % ALIGN
    return buf[off : off + n * dt.itemsize].view(dt).reshape(shape)


def aligned_zeros(shape: int | tuple[int, ...], dtype: DTypeLike) -> NDArray[Any]:
    """Zeros of ``shape`` whose first element lies on an ``ALIGN``-byte boundary."""
    out = aligned_empty(shape, dtype)
    out.fill(0)
    return out


def padded_modes(a: NDArray[Any], dtype: DTypeLike, fill: float = 0.0) -> NDArray[Any]:
    """``a`` (modes along its last axis) in ``dtype``, its last axis padded with ``fill`` to
    ``padded_size`` and every row starting on an ``ALIGN``-byte boundary: the numpy form of one
    real array, which the tests hold ``padded_parts`` (the stepper's arrays) to."""
    m = a.shape[-1]
    out = aligned_zeros((*a.shape[:-1], padded_size(m)), dtype)
    out[..., :m] = a
    if fill != 0.0:
        out[..., m:] = fill
    return out


def padded_parts(
    a: NDArray[np.complexfloating[Any, Any]], dtype: DTypeLike, fill: float = 0.0
) -> tuple[NDArray[Any], NDArray[Any]]:
    """The real and imaginary parts of ``a`` (modes along its last axis) as two arrays of
    ``padded_modes``' form (real padding ``fill``, imaginary 0), in one compiled pass: the site
    case's rows (362 x 401 complex) in a third of the time of two strided numpy copies.

    >>> r, i = padded_parts(np.array([[1 + 2j, 3 - 4j]]), np.float32, fill=-1.0)
    >>> r.shape, r[0, :3].tolist(), i[0, :3].tolist()
    ((1, 16), [1.0, 3.0, -1.0], [2.0, -4.0, 0.0])
    """
    m = a.shape[-1]
    shape = (*a.shape[:-1], padded_size(m))
    out_r = aligned_zeros(shape, dtype)
    out_i = aligned_zeros(shape, dtype)
    flat = np.ascontiguousarray(a).reshape(-1, m)
    _split(flat, out_r.reshape(-1, shape[-1]), out_i.reshape(-1, shape[-1]), fill)
    return out_r, out_i


@numba.njit(cache=True)
def _split(a: NDArray[Any], out_r: NDArray[Any], out_i: NDArray[Any], fill: float) -> None:
    """Rows of ``a`` into ``out_r`` and ``out_i`` (already zero), padding of ``out_r`` ``fill``."""
    m = a.shape[1]
    for k in range(a.shape[0]):
        for j in range(m):
            out_r[k, j] = a[k, j].real
            out_i[k, j] = a[k, j].imag
        if fill != 0.0:
            for j in range(m, out_r.shape[1]):
                out_r[k, j] = fill
