"""
Compile the model's numba kernels before a node listens or publishes.

A process's first model step compiles the kernels it calls: about half a
minute after an install or a change of the model's code, a fraction of a
second from numba's on-disk cache. :func:`compile_model` makes those first
calls on a tenth of a second of stage 6, with the argument types that the
estimator and the simulated rig use.
"""

import time

import numpy as np

from .duty import stage_duty
from .eha import EHAModel
from .kinetics import KineticModel, ThermalFeedback
from ..config import Config
from ..units import C_TO_K

#: The warm-up run: its length (s), model step (s) and sample rate (Hz).
WARM_SECONDS, WARM_STEP_S, WARM_RATE_HZ = 0.1, 0.02, 1000.0


def compile_model(cfg: Config) -> float:
    """
    Compile the model's and the kinetic model's kernels now (or load them); return seconds.

    The kinetic model plays stage 6 into a coupled model from 20 degC, one
    block of samples per model step, as an offline simulation does.
    """
    start = time.perf_counter()
    T_K = 20.0 + C_TO_K
    model = EHAModel(cfg)
    kin = KineticModel(cfg, model.oil, model.log)
    duty = stage_duty(cfg, 6)
    model.initialise(T_K, kin.sample(duty, np.array([0.0]), ThermalFeedback.uniform(T_K)))
    per_step = int(round(WARM_STEP_S * WARM_RATE_HZ))
    frac = np.arange(1, per_step + 1) / per_step
    for k in range(int(round(WARM_SECONDS / WARM_STEP_S))):
        samples = kin.sample(duty, (k + frac) * WARM_STEP_S, ThermalFeedback(
            pump_oil_K=T_K, line_oil_K=T_K, winding_K=model.outputs()['winding_mean'],
            drag_W=model.motor.shaft_drag_W,
            electromagnetic_loss_W=model.motor.electromagnetic_loss_W))
        model.step(samples, T_K)
        model.outputs()
    return time.perf_counter() - start
