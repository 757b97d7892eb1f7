"""
Does the published uncertainty hold the truth? The estimator against rigs drawn from its sigmas.

:func:`play` runs a stage on the simulated rig (its kinetics and sensor
blocks, noise-free) and steps, on the same samples, one "truth" model per
given configuration (rigs "as built", drawn by
:func:`~..model.uncertainty.as_built`), beside the open-loop
:class:`~..estimator.core.Estimator` on the nominal configuration. The result
holds, per truth and quantity, the estimate's error against that truth and
its published 1 sigma over time: the coverage tests, ``benchmarks/
uncertainty_coverage.py`` and the documentation's figure read it. Long
stages run at a coarse model step for everyone (``step_s``): the estimator
and the truths then step on the same grid, so what differs is the rig
alone.
"""

from dataclasses import dataclass
import math
from typing import Dict, List, Sequence

import numpy as np

from .simulated_rig import SimulatedRig
from ..config import Config, with_values
from ..estimator.core import Estimator
from ..model.duty import stage_duty
from ..model.eha import EHAModel, SampleBlock
from ..model.kinetics import ThermalFeedback
from ..units import C_TO_K

#: the quantities the drive's limits read, and the oil volumes
CHECKED = ('winding_hotspot', 'magnet', 'airgap_oil_outlet', 'motor_oil_outlet', 'pump_case',
           'pump_outlet', 'chamber_a', 'chamber_b', 'accumulator', 'oil')
#: the ambient of the runs (degC)
AMBIENT_C = 20.0


def coarse(cfg: Config, step_s: float, period_s: float) -> Config:
    """Return ``cfg`` with the estimator stepping ``step_s`` and its copies every ``period_s``."""
    return with_values(cfg, {'estimator.step_s': step_s,
                             'estimator.block_rate_Hz': 50.0,
                             'estimator.pressure_inputs': 'ports',
                             'estimator.limits.period_s': step_s,
                             'estimator.limits.horizons_s': (10.0 * step_s,),
                             'uncertainty.copy_period_s': period_s})


@dataclass
class Coverage:
    """One stage: time (s), and per truth and quantity the error (K) and the 1 sigma (K)."""

    t_s: np.ndarray
    error_K: List[Dict[str, np.ndarray]]     # estimate minus truth, per truth
    sigma_K: Dict[str, np.ndarray]           # the estimator's, the same for every truth
    truth_C: List[Dict[str, np.ndarray]]
    estimate_C: Dict[str, np.ndarray]

    def inside(self, k_sigma: float = 2.0) -> List[Dict[str, float]]:
        """Return, per truth and quantity, the share of the time the truth is inside the band."""
        return [{q: float(np.mean(np.abs(e[q]) <= k_sigma * self.sigma_K[q])) for q in e}
                for e in self.error_K]

    def inside_pooled(self, k_sigma: float = 2.0) -> Dict[str, float]:
        """
        Return per quantity the share of the time the truth is inside the band, over all truths.

        Pooled: one truth's errors are one draw scaled over the run, so its
        own share is nearly all or nothing (a 2.5 sigma rig is outside most
        of the time); the share over the rigs is what the band promises.
        """
        return {q: float(np.mean([v[q] for v in self.inside(k_sigma)])) for q in CHECKED}

    def sigma_over_rms(self) -> Dict[str, float]:
        """Return per quantity the mean sigma over the RMS error of all truths."""
        return {q: float(np.mean(self.sigma_K[q]) / max(math.sqrt(np.mean(
            [np.mean(e[q] ** 2) for e in self.error_K])), 1e-9)) for q in CHECKED}

    def sigma_at(self, t_s: float) -> Dict[str, float]:
        """Return the largest published sigma (K) up to ``t_s`` of each quantity."""
        keep = self.t_s <= t_s
        return {q: float(np.max(s[keep])) for q, s in self.sigma_K.items()}


def play(cfg: Config, truths: Sequence[Config], stage: int, seconds: float,
         rate_Hz: float = 50.0) -> Coverage:
    """
    Play ``seconds`` of ``stage`` from ambient; return the estimator against each truth.

    ``cfg`` the estimator's configuration (its ``estimator.step_s`` is the
    rig's block and every truth's step); the rig's kinetics run on the
    first truth. Open loop, no sensor noise.
    """
    step = cfg.estimator.step_s
    rig = SimulatedRig(truths[0], stage_duty(truths[0], stage), rate_Hz=rate_Hz,
                       noise=False, ambient_C=AMBIENT_C, block_s=step)
    amb = AMBIENT_C + C_TO_K
    first = rig.kin.sample(rig.duty, np.array([0.0]), ThermalFeedback.uniform(amb))
    models = [rig.truth]
    for t in truths[1:]:
        m = EHAModel(t)
        m.initialise(amb, first)
        models.append(m)
    est = Estimator(cfg)
    est.ambient_K = amb
    times, est_C, sig, true = [], {q: [] for q in CHECKED}, {q: [] for q in CHECKED}, \
        [{q: [] for q in CHECKED} for _ in truths]
    est.add_many('current_A', np.array([0.0]), first.current_A)
    for name in ('speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m'):
        est.add_many(name, np.array([0.0]), getattr(first, name))
    for _ in range(int(round(seconds / step))):
        block = rig.next_block()
        samples = SampleBlock(block['t_s'], *(block[n] for n in (
            'current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m')))
        for m in models[1:]:
            m.step(samples, amb)
        for name in est.inputs:
            est.add_many(name, block['t_s'], block[name])
        done = est.advance_all()
        if not done:
            continue
        e = done[-1]
        times.append(e.stamp_s)
        for q in CHECKED:
            est_C[q].append(e.temperatures_C[q])
            sig[q].append(e.uncertainty_K[q])
        for k, m in enumerate(models):
            out = m.outputs()
            for q in CHECKED:
                true[k][q].append(out[q] - C_TO_K)
    est_a = {q: np.array(v) for q, v in est_C.items()}
    true_a = [{q: np.array(v) for q, v in t.items()} for t in true]
    return Coverage(t_s=np.array(times), error_K=[{q: est_a[q] - t[q] for q in CHECKED}
                                                  for t in true_a],
                    sigma_K={q: np.array(v) for q, v in sig.items()}, truth_C=true_a,
                    estimate_C=est_a)
