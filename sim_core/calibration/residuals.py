"""A calibration passage and its channel residuals, weighted by the record's noise.

The residual of a passage on a track is (measured − predicted) / σ over every sample of
every crib, σ the white noise on its record. A WheelPassage does not carry σ, so it is
estimated from the record itself (``noise_sigma``): the robust spread (1.4826 × the median
absolute deviation) of the residual against a forward prediction. The model errs only near
the gauge steps and in a fast wheel's dynamic load, a minority of the samples, which the
median ignores.

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> r = rng.normal(0.0, 2.0, 20000); r[:500] += 30.0  # 2.5 % of samples far off
    >>> round(noise_sigma(r), 1)
    2.1
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.calibration.forward import Wheel, predict_channels
from sim_core.diagnosis.sensor import SensorModel
from sim_core.track.spec import Crib, TrackSpec

__all__ = ["MAD_SCALE", "Passage", "Site", "noise_sigma", "predict", "residual"]

MAD_SCALE = 1.4826
"""σ of a normal distribution per median absolute deviation."""


@dataclass(frozen=True)
class Site:
    """What every passage at a site shares: the cribs and the measuring chain."""

    cribs: tuple[Crib, ...]
    chain: SensorModel


@dataclass(frozen=True)
class Passage:
    """A round wheel's record: its name, the wheel, the sample times (s, t = 0 at x_C = 0)
    and the channels (N, samples × cribs, in the site's crib order)."""

    name: str
    wheel: Wheel
    t: NDArray[np.float64]
    channels: NDArray[np.float64]

    def __post_init__(self) -> None:
        if self.channels.ndim != 2 or self.channels.shape[0] != self.t.size:
            raise ValueError(
                f"{self.name}: channels must be samples x cribs, got {self.channels.shape} "
                f"for {self.t.size} samples"
            )


def noise_sigma(r: NDArray[np.float64]) -> float:
    """The robust σ of residuals ``r`` (1.4826 × median |r − median r|)."""
    r = np.ravel(r)
    return float(MAD_SCALE * np.median(np.abs(r - np.median(r))))


def predict(track: TrackSpec, passage: Passage, site: Site) -> NDArray[np.float64]:
    """The channels ``track`` predicts for ``passage`` (samples × cribs)."""
    return predict_channels(track, passage.wheel, site.cribs, site.chain, passage.t)


def residual(track: TrackSpec, passage: Passage, site: Site, sigma: float) -> NDArray[np.float64]:
    """(measured − predicted) / σ, flattened (samples × cribs, row-major)."""
    return np.ravel((passage.channels - predict(track, passage, site)) / sigma)
