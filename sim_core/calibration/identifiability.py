"""Which track parameters, and which combinations of them, the round wheels cannot tell apart.

The data's Fisher information F = JᵀJ (J the noise-weighted Jacobian of the channels in the
log-factors z) says how well each direction of z is determined: along an eigenvector v of F
with eigenvalue λ, the data alone fix vᵀz to a standard deviation 1/√λ. A direction the data
fix no better than the prior does (1/√λ ≥ ``prior_sd``/2) is one they cannot tell apart; the
estimate along it stays where the prior holds it (at the nominal), and its interval is the
prior's. Per parameter the same test is made on the marginal: a parameter is

- ``yes`` (identified) when the data shrink its prior standard deviation to less than
  ``IDENTIFIED`` (0.5) of it;
- ``partly`` when less than ``PARTLY`` (0.9) of it: the data move it, the prior still matters;
- ``no`` otherwise: its estimate is the nominal's, whatever the data.

    >>> import numpy as np
    >>> f = np.array([[400.0, 0.0], [0.0, 0.01]])  # the data fix z0 to 5 %, z1 not at all
    >>> a = analyse(f, 0.2, ("k", "c"))
    >>> a.identifiable, [round(s, 3) for s in a.data_sd], [round(s, 3) for s in a.posterior_sd]
    (('yes', 'no'), [0.05, 10.0], [0.049, 0.2])
    >>> a.weak[0].label(("k", "c"))
    'c'
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "IDENTIFIED",
    "PARTLY",
    "Combination",
    "Identifiability",
    "Verdict",
    "analyse",
    "judge",
]

Verdict = Literal["yes", "partly", "no"]

IDENTIFIED = 0.5
"""Posterior/prior standard deviation below which a parameter counts as identified."""

PARTLY = 0.9
"""Below this (and not identified), the data move the parameter but the prior still matters."""

SHOWN = 0.2
"""A component of a combination is named when its weight is at least this (largest = 1)."""


@dataclass(frozen=True)
class Combination:
    """A direction of the log-factors: sum_i weights[i]·ln(θ_i/θ_i,nominal), and how well the
    data alone determine it (standard deviation of that sum; inf: not at all)."""

    weights: tuple[float, ...]
    """Largest weight 1."""
    data_sd: float

    def label(self, names: tuple[str, ...]) -> str:
        """The combination as a product of powers, e.g. ``ballast.stiffness·sleeper_mass^-0.6``."""
        parts = []
        for n, w in zip(names, self.weights, strict=True):
            if abs(w) < SHOWN:
                continue
            parts.append(n if abs(w - 1.0) < 0.05 else f"{n}^{w:.2g}")
        return "·".join(parts)


@dataclass(frozen=True)
class Identifiability:
    """The analysis of a Fisher matrix against the prior (module docstring)."""

    identifiable: tuple[Verdict, ...]
    data_sd: tuple[float, ...]
    """Per parameter: the data's marginal standard deviation of ln θ_i (inf: not determined)."""
    posterior_sd: tuple[float, ...]
    """Per parameter: data and prior together."""
    weak: tuple[Combination, ...]
    """Directions the data cannot tell apart (data sd ≥ prior sd / 2), weakest first."""
    strong: tuple[Combination, ...]
    """The others, best determined first."""


def judge(sd: tuple[float, ...], prior_sd: float) -> tuple[Verdict, ...]:
    """Each parameter's verdict from its standard deviation (of ln θ) against the prior's.

    >>> judge((0.05, 0.15, 0.3), 0.2)
    ('yes', 'partly', 'no')
    """
    out: list[Verdict] = []
    for s in sd:
        ratio = s / prior_sd
        out.append("yes" if ratio < IDENTIFIED else "partly" if ratio < PARTLY else "no")
    return tuple(out)


def _normalised(v: NDArray[np.float64]) -> tuple[float, ...]:
    v = v / v[np.argmax(np.abs(v))]
    return tuple(float(x) for x in v)


def analyse(
    fisher: NDArray[np.float64], prior_sd: float, names: tuple[str, ...]
) -> Identifiability:
    """Identifiability of the parameters ``names`` from the data's Fisher matrix (in the
    log-factors) against an independent prior of ``prior_sd`` on each log-factor."""
    f = 0.5 * (fisher + fisher.T)
    n = f.shape[0]
    lam, vec = np.linalg.eigh(f)
    scale = max(float(lam.max()), 1e-300)
    good = lam > 1e-10 * scale
    # marginal data sd: the pseudo-inverse over the determined directions, inf if a
    # parameter has weight in an undetermined one
    data_sd = []
    for i in range(n):
        if np.any(np.abs(vec[i, ~good]) > 1e-6):
            data_sd.append(float("inf"))
        else:
            data_sd.append(float(np.sqrt(np.sum(vec[i, good] ** 2 / lam[good]))))
    post = np.linalg.inv(f + np.eye(n) / prior_sd**2)
    post_sd = tuple(float(np.sqrt(post[i, i])) for i in range(n))
    verdicts = judge(post_sd, prior_sd)
    weak: list[tuple[float, Combination]] = []
    strong: list[tuple[float, Combination]] = []
    for j in range(n):
        unit_sd = float(1.0 / np.sqrt(lam[j])) if good[j] else float("inf")
        vmax = float(np.max(np.abs(vec[:, j])))
        combo = Combination(_normalised(vec[:, j]), unit_sd / vmax)
        # the prior's sd along the unit direction is prior_sd whatever the direction
        (weak if unit_sd >= 0.5 * prior_sd else strong).append((unit_sd, combo))
    weak.sort(key=lambda p: -p[0])
    strong.sort(key=lambda p: p[0])
    return Identifiability(
        verdicts,
        tuple(data_sd),
        post_sd,
        tuple(c for _, c in weak),
        tuple(c for _, c in strong),
    )
