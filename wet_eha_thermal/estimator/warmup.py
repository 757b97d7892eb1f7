"""
Compile every numba kernel the live estimator calls, before it listens to a rig.

After an install or a change of the model's code, numba compiles each kernel
at its first call and keeps it in its on-disk cache. Compiling the lot takes
about a minute on a quiet two-core machine, and several when two processes
compile at once beside other work; a node that compiled at its first sample
would let samples wait (and inputs go stale) that long. :func:`compile_estimator`
makes those first calls on synthetic data: once per install it pays the
compile, afterwards it loads the cache in about a second.
"""

import time
from typing import List

import numpy as np

from .intake import sensor_signal, split_differential
from .session import EstimatorSession
from ..config import Config
from ..model.duty import stage_duty
from ..model.kinetics import KineticModel, ThermalFeedback
from ..model.oil import get_oil
from ..model.warmup import compile_model

#: Length of the synthetic stage-6 record fed to the estimator (s) and its rate (Hz):
#: past the first tick of the current limits (0.5 s), which then are worked out
WARM_SECONDS, WARM_RATE_HZ = 0.6, 1000.0
#: Silence after it (s): the inputs go stale, then held blocks cross the rest.
WARM_SILENCE_S = 10.0

#: The configurations this process has warmed up for: kernels, once loaded, stay loaded, and
#: an equal configuration calls them with the same types (a process that starts several
#: nodes, as the tests do, would otherwise build and run a throw-away estimator for each)
_warmed: List[Config] = []


def compile_estimator(cfg: Config) -> float:
    """
    Compile (or load from numba's cache) the model's and the estimator core's kernels; return s.

    Runs :func:`~wet_eha_thermal.model.warmup.compile_model`, then a throw-away
    :class:`~.session.EstimatorSession` through the live node's calls
    (:meth:`~.session.EstimatorSession.take`, ``add_measured``) on
    ``WARM_SECONDS`` of stage-6 signals, then ``WARM_SILENCE_S`` of silence
    (stale inputs, held blocks), the uncertainty's copies over that record and
    the live correction's filter once; and the split of a differential
    pressure, whichever pressure inputs ``cfg`` has. Returns at once in a
    process that has done it for an equal configuration.
    """
    start = time.perf_counter()
    if any(cfg == done for done in _warmed):
        return time.perf_counter() - start
    compile_model(cfg)
    session = EstimatorSession(cfg, outlook='background')
    if session._est.propagation is not None:
        # the first tick takes the cold start's heated figures at once: its limits are
        # computed within these few samples
        session._est.propagation.heating_wait_per_step_s = 0.0
    kin = KineticModel(cfg, get_oil(cfg.fluid.grade))
    t = np.arange(1, int(WARM_SECONDS * WARM_RATE_HZ) + 1) / WARM_RATE_HZ
    samples = kin.sample(stage_duty(cfg, 6), t, ThermalFeedback.uniform())
    signals = {name: sensor_signal(samples, name) for name in session.inputs}
    tcs = session.thermocouples
    for k, tk in enumerate(t):
        if k % 100 == 50:       # thermocouple readings: the correction's filter step
            for tc in tcs:
                session.add_measured(tc, float(tk), cfg.estimator.ambient_C)
        for name in session.inputs:
            session.take(name, float(tk), float(signals[name][k]), now_s=float(tk))
    # the first tick's limits and margin, to their end; not the forecast, whose model steps
    # are the estimator's (a second of start-up saved)
    est = session._est          # the estimator's parts: this module warms them up
    est._outlook.forecast = None
    while session.work(0.05):
        pass
    # a silence: inputs go stale, the model steps on held values and in held blocks
    session.step(float(t[-1]) + WARM_SILENCE_S, all_steps=True)
    if est.propagation is not None:
        # the uncertainty's copies step at a period's end (seconds of samples away)
        est.propagation.warm_up(est.ambient_K)
    if est._correction is not None:
        # the filter starts at the first usable reading, which so short a record never
        # gives (a thermocouple is first watched for its noise and for being stuck)
        est._correction.warm_up(est.model, cfg.estimator.step_s)
    # scripts/dev warms the shipped configuration (port pressures) for the processes that
    # follow, and those that run one differential pressure (recorded logs) call this one too
    split_differential(np.zeros(1), cfg.hydraulics.accumulator.pressure_Pa)
    _warmed.append(cfg)
    return time.perf_counter() - start


if __name__ == '__main__':      # `scripts/dev` compiles once, before the test workers start
    from ..config import load_config
    print(f'model and estimator kernels ready in {compile_estimator(load_config()):.1f} s',
          flush=True)
