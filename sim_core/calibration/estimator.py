"""The track's parameters from round wheels: Gauss–Newton on the noise-weighted channel residuals.

With z the log-factors on the nominal values (``parameters``), r_k(z) the weighted residual of
wheel k (``residuals``) and J_k its Jacobian (``sensitivities``), the estimate minimises

    Σ_k |r_k(z)|² + |z|² / prior_sd²

a maximum a-posteriori estimate under an independent normal prior of ``PRIOR_SD`` on each
log-factor: the ±30 % a nominal track value is ordinarily off (issue 26); along the
directions the data do not determine, the estimate stays at the nominal instead of wandering.
The steps (JᵀJ + I/prior_sd²)·Δ = Jᵀr − z/prior_sd² are held within a trust region (no
log-factor moves by more than the radius a step; it grows where the linear model predicted
the step's gain well and shrinks where it did not: the channels are far from linear in the
pad's stiffness over ±30 %, and one long Gauss–Newton step from the nominal trades a
stiffness for a damping). Each step is checked on the full model and taken only if it lowers
the cost; after it, every wheel's Jacobian is updated by Broyden's rank-one formula, and where the
linear model predicted the step's gain poorly (less than 3/4 of it came) the informative
wheels' (``INFORMATIVE``: the fast ones) are computed anew.

Uncertainty: the posterior covariance (F + I/prior_sd²)⁻¹ with F = ΣJ_kᵀJ_k the Fisher
information, scaled by the reduced χ² when it exceeds 1; and a jackknife over the wheels
(the estimate with each wheel left out, linearised), which sees what the white-noise model
does not: the rail's roughness, unknown and the same for every wheel, drives a dynamic load
that differs from wheel to wheel with its speed. Each parameter's standard deviation is the
larger of the two; its interval is the estimate × exp(±1.96 sd).

A parameter the wheels do not determine (``identifiability``: verdict ``no`` on that standard
deviation) is not left where the data's unmodelled part (the rail's roughness, above all)
pushed it: it is put back to its nominal and held there (prior precision ``FROZEN``), the
others are fitted again, and its interval is the prior's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.calibration.identifiability import Identifiability, analyse, judge
from sim_core.calibration.parameters import names, scaled, values
from sim_core.calibration.residuals import Passage, Site, noise_sigma, residual
from sim_core.calibration.sensitivities import Progress, _quiet, jacobian, residuals
from sim_core.track.spec import TrackSpec

__all__ = ["MAX_STEPS", "PRIOR_SD", "Z95", "Estimate", "calibrate"]

PRIOR_SD = 0.2
"""Prior standard deviation of each ln(value/nominal): a nominal value within ±30 % of the
truth is ordinary (issue 26), a uniform factor in [0.7, 1.3] has a spread of 0.17."""

MAX_STEPS = 6
"""Gauss–Newton steps at most (each costs one reduction and one passage per wheel)."""

Z95 = 1.959964
"""The two-sided 95 % point of the normal distribution."""

TRUST = 0.15
"""The first step's trust radius: the largest change of any log-factor."""

MAX_TRUST = 0.6
"""The trust radius grows (doubles after a step the linear model predicted well) up to this."""

INFORMATIVE = 0.95
"""The wheels whose Jacobians are computed anew after each step: the fewest holding this
share of the Fisher information (the fast ones); the others' are updated by Broyden."""

SIGMA_TOL = 0.10
"""The noise is estimated again from the calibrated residuals; if some wheel's moved by more
than this (relative), the search is run once more with the new weights (``PASSES``). A
record whose nominal fit is far off (1.7 x its noise) overstates its noise by 15 %, and its
weights then matter; a few % do not pay for three more steps (a reduction of the track per
value each): on the handed-over S01 (6 % on its fastest wheel) a second search sent the
pad's damping to 1.82 x the truth outside its interval, where without it the damping is
judged not determined and held at the nominal (1.22 x, inside the prior's interval)."""

PASSES = 2
"""Searches at most."""

FROZEN = 1.0e12
"""The prior precision that holds a parameter the wheels do not determine at its nominal."""

TOL = 0.005
"""Stop when no log-factor moves by more than this."""


@dataclass(frozen=True)
class Estimate:
    """A calibration's result (module docstring); per parameter in the order of ``names``."""

    names: tuple[str, ...]
    nominal: tuple[float, ...]
    z: tuple[float, ...]
    """ln(estimate / nominal)."""
    sd: tuple[float, ...]
    """Standard deviation of each ln(estimate): the larger of Fisher and jackknife."""
    fisher_sd: tuple[float, ...]
    jackknife_sd: tuple[float, ...]
    covariance: NDArray[np.float64]
    """Posterior covariance of z (Fisher and prior, χ²-scaled)."""
    fisher: NDArray[np.float64]
    """The data's Fisher information in z (ΣJᵀJ)."""
    identifiability: Identifiability
    wheels: tuple[str, ...]
    sigma: tuple[float, ...]
    """Each wheel's noise σ, N, estimated from its record."""
    rms_nominal: tuple[float, ...]
    """Each wheel's residual rms / σ on the nominal track."""
    rms_calibrated: tuple[float, ...]
    """... and on the calibrated one."""
    chi2_reduced: float
    steps: int
    track: TrackSpec
    """The calibrated track."""

    @property
    def estimate(self) -> tuple[float, ...]:
        return tuple(v * math.exp(z) for v, z in zip(self.nominal, self.z, strict=True))

    def interval(self, i: int, z: float = Z95) -> tuple[float, float]:
        """The two-sided interval of parameter i (95 % by default)."""
        v = self.estimate[i]
        return v * math.exp(-z * self.sd[i]), v * math.exp(z * self.sd[i])


def _sum_jtj(jac: Sequence[NDArray[np.float64]]) -> NDArray[np.float64]:
    out = np.zeros((jac[0].shape[1], jac[0].shape[1]))
    for j in jac:
        out += j.T @ j
    return out


def _informative(jac: Sequence[NDArray[np.float64]]) -> list[int]:
    """The fewest wheels holding ``INFORMATIVE`` of the Fisher information (its trace in z,
    each parameter's column scaled to the total's diagonal)."""
    total = _sum_jtj(jac)
    scale = 1.0 / np.sqrt(np.maximum(np.diag(total), 1e-300))
    share = np.array([float(np.sum((j * scale) ** 2)) for j in jac])
    order = np.argsort(-share)
    cum = np.cumsum(share[order]) / max(float(share.sum()), 1e-300)
    count = int(np.searchsorted(cum, INFORMATIVE) + 1)
    return sorted(int(k) for k in order[:count])


def _judged(ident: Identifiability, sd: NDArray[np.float64], prior_sd: float) -> Identifiability:
    """The verdicts on the final standard deviations (a jackknife larger than the Fisher
    information's says the wheels disagree: the parameter is not determined)."""
    final = tuple(max(float(a), float(b)) for a, b in zip(sd, ident.posterior_sd, strict=True))
    return dataclasses.replace(ident, identifiable=judge(final, prior_sd), posterior_sd=final)


def _uncertainty(
    jac: Sequence[NDArray[np.float64]],
    base: Sequence[NDArray[np.float64]],
    z: NDArray[np.float64],
    precision: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """(Fisher sd, jackknife sd, posterior covariance, reduced χ²) at z (module docstring)."""
    n = z.size
    a = _sum_jtj(jac) + np.diag(precision)
    n_data = sum(r.size for r in base)
    chi2 = sum(float(r @ r) for r in base) / max(1, n_data - n)
    cov = np.asarray(np.linalg.inv(a) * max(1.0, chi2), dtype=np.float64)
    fisher_sd = np.sqrt(np.diag(cov))
    # jackknife over the wheels, linearised at the estimate
    g_all = [j.T @ r for j, r in zip(jac, base, strict=True)]
    g_sum = np.sum(g_all, axis=0)
    k = len(g_all)
    if k < 3:
        return fisher_sd, np.zeros(n), cov, chi2
    loo = np.array(
        [
            z + np.linalg.solve(a - j.T @ j, g_sum - gk - precision * z)
            for j, gk in zip(jac, g_all, strict=True)
        ]
    )
    jack_sd = np.sqrt((k - 1) / k * np.sum((loo - loo.mean(axis=0)) ** 2, axis=0))
    return fisher_sd, jack_sd, cov, chi2


def _rms(r: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(r**2)))


def _descend(
    nominal: TrackSpec,
    z: NDArray[np.float64],
    base: list[NDArray[np.float64]],
    jac: list[NDArray[np.float64]],
    passages: Sequence[Passage],
    site: Site,
    sigma: Sequence[float],
    informative: list[int],
    precision: NDArray[np.float64],
    max_steps: int,
    progress: Progress,
) -> tuple[NDArray[np.float64], list[NDArray[np.float64]], int]:
    """Trust-region Gauss–Newton steps from z (module docstring); ``jac`` is updated in place.
    Returns the new z, its residuals and the steps taken."""
    prior = np.diag(precision)

    def cost(rs: Sequence[NDArray[np.float64]], zz: NDArray[np.float64]) -> float:
        return float(sum(float(r @ r) for r in rs) + zz @ (precision * zz))

    current = cost(base, z)
    steps = 0
    radius = TRUST
    for _ in range(max_steps):
        a = _sum_jtj(jac) + prior
        g = sum(j.T @ r for j, r in zip(jac, base, strict=True)) - precision * z
        delta = np.linalg.solve(a, g)
        big = float(np.max(np.abs(delta)))
        if big > radius:
            delta = delta * (radius / big)
        predicted = float(2.0 * g @ delta - delta @ a @ delta)
        trial_z = z + delta
        trial = residuals(nominal, trial_z, passages, site, sigma, progress, f"step {steps + 1}")
        c = cost(trial, trial_z)
        steps += 1
        moved = float(np.max(np.abs(delta)))
        if c >= current:
            radius = 0.5 * moved
            if radius < TOL:
                break
            continue
        ratio = (current - c) / predicted if predicted > 0 else 0.0
        if ratio > 0.75:
            radius = min(2.0 * radius, MAX_TRUST)
        elif ratio < 0.25:
            radius = 0.5 * radius
        # Broyden for every wheel, then the informative wheels' Jacobians anew at the new z
        dd = float(delta @ delta)
        for k, (j, r0, r1) in enumerate(zip(jac, base, trial, strict=True)):
            jac[k] = j + np.outer((r0 - r1) - j @ delta, delta) / dd
        z, base, current = trial_z, trial, c
        if moved < TOL:
            break
        if ratio > 0.75:
            continue  # the linear model held: Broyden's update is enough
        sub = [passages[k] for k in informative]
        fresh = jacobian(
            nominal,
            z,
            sub,
            site,
            [sigma[k] for k in informative],
            [base[k] for k in informative],
            progress,
        )
        for k, j in zip(informative, fresh, strict=True):
            jac[k] = j
    return z, base, steps


def calibrate(
    nominal: TrackSpec,
    passages: Sequence[Passage],
    site: Site,
    *,
    prior_sd: float = PRIOR_SD,
    max_steps: int = MAX_STEPS,
    progress: Progress = _quiet,
) -> Estimate:
    """The track's parameters from round-wheel ``passages`` at ``site`` (module docstring)."""
    if not passages:
        raise ValueError("calibration needs at least one passage")
    keys = names(nominal)
    n = len(keys)
    z = np.zeros(n)
    raw = [residual(nominal, p, site, 1.0) for p in passages]
    sigma = [noise_sigma(r) for r in raw]
    for p, s in zip(passages, sigma, strict=True):
        if not (s > 0.0 and math.isfinite(s)):
            raise ValueError(f"{p.name}: the record has no noise to weigh it by (σ = {s!r})")
    base = [r / s for r, s in zip(raw, sigma, strict=True)]
    raw_nominal = list(base)
    jac = jacobian(nominal, z, passages, site, sigma, base, progress)
    precision = np.full(n, 1.0 / prior_sd**2)
    informative = _informative(jac)
    steps = 0
    for again_pass in range(PASSES):
        z, base, more = _descend(
            nominal,
            z,
            base,
            jac,
            passages,
            site,
            sigma,
            informative,
            precision,
            max_steps if again_pass == 0 else max(1, max_steps // 2),
            progress,
        )
        steps += more
        # the noise again, from the calibrated residuals (the nominal's misfit inflates it)
        again = [noise_sigma(r * s) for r, s in zip(base, sigma, strict=True)]
        change = max(abs(s1 / s0 - 1.0) for s1, s0 in zip(again, sigma, strict=True))
        for k, (s1, s0) in enumerate(zip(again, sigma, strict=True)):
            base[k] = base[k] * (s0 / s1)
            jac[k] = jac[k] * (s0 / s1)
        raw_nominal = [r * s for r, s in zip(raw_nominal, sigma, strict=True)]
        sigma = again
        raw_nominal = [r / s for r, s in zip(raw_nominal, sigma, strict=True)]
        if change < SIGMA_TOL:
            break
    rms_nominal = tuple(_rms(r) for r in raw_nominal)
    fisher = _sum_jtj(jac)
    fisher_sd, jack_sd, cov, chi2 = _uncertainty(jac, base, z, precision)
    sd = np.maximum(fisher_sd, jack_sd)
    ident = _judged(analyse(fisher, prior_sd, keys), sd, prior_sd)
    frozen = np.array([v == "no" for v in ident.identifiable])
    if frozen.any() and not frozen.all():
        # what the wheels do not determine stays at the nominal; the rest is fitted again
        z = np.where(frozen, 0.0, z)
        base = residuals(nominal, z, passages, site, sigma, progress, "refit")
        precision = np.where(frozen, FROZEN, precision)
        z, base, more = _descend(
            nominal,
            z,
            base,
            jac,
            passages,
            site,
            sigma,
            informative,
            precision,
            max(1, max_steps // 2),
            progress,
        )
        steps += more
        fisher = _sum_jtj(jac)
        fisher_sd, jack_sd, cov, chi2 = _uncertainty(jac, base, z, precision)
        fisher_sd = np.where(frozen, prior_sd, fisher_sd)
        jack_sd = np.where(frozen, 0.0, jack_sd)
        sd = np.maximum(fisher_sd, jack_sd)
        again_ident = _judged(analyse(fisher, prior_sd, keys), sd, prior_sd)
        ident = dataclasses.replace(
            again_ident,
            identifiable=tuple(
                "no" if f else v for f, v in zip(frozen, again_ident.identifiable, strict=True)
            ),
        )
    return Estimate(
        names=keys,
        nominal=values(nominal),
        z=tuple(float(v) for v in z),
        sd=tuple(float(v) for v in sd),
        fisher_sd=tuple(float(v) for v in fisher_sd),
        jackknife_sd=tuple(float(v) for v in jack_sd),
        covariance=cov,
        fisher=fisher,
        identifiability=ident,
        wheels=tuple(p.name for p in passages),
        sigma=tuple(sigma),
        rms_nominal=rms_nominal,
        rms_calibrated=tuple(_rms(r) for r in base),
        chi2_reduced=chi2,
        steps=steps,
        track=scaled(nominal, z),
    )
