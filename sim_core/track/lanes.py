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


def aligned_zeros(shape: int | tuple[int, ...], dtype: DTypeLike) -> NDArray[Any]:
    """Zeros of ``shape`` whose first element lies on an ``ALIGN``-byte boundary."""
    dt = np.dtype(dtype)
    n = int(np.prod(shape))
    buf = np.zeros(n * dt.itemsize + ALIGN, dtype=np.uint8)
    off = (-buf.ctypes.data) % ALIGN
    return buf[off : off + n * dt.itemsize].view(dt).reshape(shape)


def padded_modes(a: NDArray[Any], dtype: DTypeLike, fill: float = 0.0) -> NDArray[Any]:
    """``a`` (modes along its last axis) in ``dtype``, its last axis padded with ``fill`` to
    ``padded_size`` and every row starting on an ``ALIGN``-byte boundary."""
    m = a.shape[-1]
    out = aligned_zeros((*a.shape[:-1], padded_size(m)), dtype)
    out[..., :m] = a
    if fill != 0.0:
        out[..., m:] = fill
    return out
