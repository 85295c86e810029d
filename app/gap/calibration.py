"""The nuisances every real drive carries (a gyro's bias and scale, the steering's offset and
ratio, nominal C1n and C2n) calibrated on every usable sample, with 95 % intervals that count
residuals hanging together over a block."""

from dataclasses import dataclass

import numpy as np

from app.gap.candidates import RIVAL_NUISANCE, Param, mods_of
from app.gap.nominal_model import Mods
from app.gap.problem import Fit, Problem, fit, with_scales
from app.sim.effects import EffectName
from app.units import Z95


@dataclass(frozen=True)
class NuisanceFit:
    """The drive's nuisances (a gyro's bias and scale, the steering's offset …) calibrated on it."""

    params: tuple[Param, ...]  # as calibrated: an optional nuisance the drive does not show, held
    fit: Fit
    ci95: tuple[tuple[float, float], ...]
    declared: tuple[Param, ...]  # as the candidates module declares them

    @property
    def values(self) -> tuple[float, ...]:
        return self.fit.values

    def mods(self, *effect: dict[str, float]) -> Mods:
        return mods_of(self.fit.fields(), *effect)

    def params_for(self, effect: EffectName, rival_free: bool = False) -> tuple[Param, ...]:
        """The nuisances fitted beside ``effect``; its rival (a nuisance that imitates it) held at
        its nominal value, or with ``rival_free`` fitted beside it even where the calibration
        alone did not show it (the effect may have hidden it)."""
        rival = RIVAL_NUISANCE.get(effect)
        if rival_free:
            return tuple(d if d.name == rival else p for p, d in zip(self.params, self.declared, strict=True))
        return tuple(p.fixed() if p.name == rival else p for p in self.params)

    def start_for(self, effect: EffectName) -> tuple[float, ...]:
        return tuple(
            v if p.free else p.nominal for p, v in zip(self.params_for(effect), self.values, strict=True)
        )


def calibrate(pb: Problem, params: tuple[Param, ...]) -> tuple[Problem, NuisanceFit]:
    """The nuisances fitted on every usable sample, twice: the channels' scales are set from the
    first fit's residuals, then the fit is repeated with them."""
    declared = params
    first = fit(pb, params, pb.rows)
    pb = with_scales(pb, pb.simulate(mods_of(first.fields())))
    final = fit(pb, params, pb.rows, start=first.values)
    ci95 = ci95_of(pb, final)
    unseen = [
        k
        for k, (p, (low, high)) in enumerate(zip(params, ci95, strict=True))
        if p.optional and low <= p.nominal <= high
    ]
    if unseen:  # held at nominal; their intervals (which cover it) are what the drive says of them
        params = tuple(p.fixed() if k in unseen else p for k, p in enumerate(params))
        final = fit(pb, params, pb.rows, start=final.values)
        held = dict(zip(unseen, (ci95[k] for k in unseen), strict=True))
        ci95 = tuple(held.get(k, ci) for k, ci in enumerate(ci95_of(pb, final)))
    return pb, NuisanceFit(params, final, ci95, declared)


def ci95_of(pb: Problem, result: Fit) -> tuple[tuple[float, float], ...]:
    """95 % intervals from the fit's Jacobian (a fit over every usable sample), each channel's
    residual variance its own, inflated for residuals that hang together over about a block
    (GAP_BLOCK_S): the effective sample size is the blocks'. Per channel, so that a misfit in a
    channel a parameter does not act on (a vehicle speed signal off by its scale) does not widen
    that parameter's interval: cov = A⁻¹·(Σ s_c²·J_cᵀJ_c)·A⁻¹, A = JᵀJ."""
    jac, res = result.jac, result.fun
    if jac is None or res is None:
        raise ValueError("a fit without its Jacobian has no intervals")
    n = int(pb.rows.sum())
    k = jac.shape[1]
    inflate = max(n / pb.blocks(pb.rows), 1.0)
    channels = 3 if pb.has_speed else 2
    middle = np.zeros((k, k))
    for c in range(channels):
        block, r = jac[c * n : (c + 1) * n], res[c * n : (c + 1) * n]
        middle += float(np.sum(r**2)) / max(n - k, 1) * inflate * (block.T @ block)
    priors = jac[channels * n :]  # already in units of their spread
    middle += priors.T @ priors
    outer = np.linalg.pinv(jac.T @ jac)
    cov = outer @ middle @ outer
    free = np.array([p.free for p in result.params])
    scales = np.array([p.scale for p in result.params])
    half = np.zeros(len(free))  # a parameter held at its value has no interval of its own
    half[free] = Z95 * np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scales[free]
    return tuple((v - w, v + w) for v, w in zip(result.values, half.tolist(), strict=True))
