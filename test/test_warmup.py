"""The live start's warm-up compiles every kernel that a realistic estimator run calls."""

import json
import subprocess
import sys

import pytest
from wet_eha_thermal.model import compiled

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

# In a process of its own (a test session has compiled more by then): the warm-up, then
# live-like work with the node's calls, noise, thermocouples, the forecast and the margin, a
# silence and data again, and a second of one differential pressure (the warm-up is that of the
# shipped configuration, as scripts/dev runs it: port pressures). Prints the kernel signatures
# that the warm-up missed. 12 s of each
# stage: past the uncertainty's copy period (10 s) and many limits' ticks (0.5 s); without
# the warm-up, runs of 12 s and of 30 s called the same 41 signatures of 33 kernels.
RUN = """
import json, sys
import numba
import numpy as np
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.estimator.intake import sensor_signal
from wet_eha_thermal.estimator.warmup import compile_estimator
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil


def signatures():
    found = {}
    for mod_name, mod in list(sys.modules.items()):
        if not mod_name.startswith('wet_eha_thermal'):
            continue
        for name, obj in vars(mod).items():
            if isinstance(obj, numba.core.dispatcher.Dispatcher):
                found[f'{obj.py_func.__module__}.{name}'] = {str(s) for s in obj.signatures}
    return found


cfg = load_config()
compile_estimator(cfg)
before = signatures()
est = EstimatorSession(cfg, outlook='background', budget_s=0.002)
rng = np.random.default_rng(7)
kin = KineticModel(cfg, get_oil(cfg.fluid.grade))
for stage, (t0, t1) in ((6, (0.0, 12.0)), (3, (400.0, 412.0))):
    t = np.arange(t0 * 1000 + 1, t1 * 1000 + 1) / 1000.0
    s = kin.sample(stage_duty(cfg, stage), t - t0, ThermalFeedback.uniform())
    sig = {n: sensor_signal(s, n) * (1 + 0.01 * rng.standard_normal(t.size))
           for n in est.inputs}
    for k, tk in enumerate(t):
        if k % 1000 == 0:
            for tc in est.thermocouples:
                est.add_measured(tc, tk, 25.0 + rng.standard_normal())
        for n in est.inputs:
            est.take(n, tk, sig[n][k], now_s=tk)
    while est.work(0.05):
        pass
    est.step(t1 + 360.0 if stage == 6 else t1, all_steps=True)
# one differential pressure (as the recorder's logs hold): the intake splits it into the
# three the model takes; the rest of the path is the one above
cfg_dp = load_config(overrides={'estimator.pressure_inputs': 'differential'})
est = EstimatorSession(cfg_dp)
t = np.arange(1, 1001) / 1000.0
s = kin.sample(stage_duty(cfg_dp, 6), t, ThermalFeedback.uniform())
sig = {n: sensor_signal(s, n) for n in est.inputs}
for k, tk in enumerate(t):
    for n in est.inputs:
        est.take(n, tk, sig[n][k], now_s=tk)
est.step(t[-1], all_steps=True)
after = signatures()
json.dump({k: sorted(v - before.get(k, set())) for k, v in after.items()
           if v - before.get(k, set())}, sys.stdout)
"""


@pytest.mark.skipif(not compiled.COMPILED, reason='numba is not installed')
def test_warm_up_leaves_nothing_to_compile_for_a_live_run():
    out = subprocess.run([sys.executable, '-c', RUN], capture_output=True, text=True,
                         timeout=600, check=True)
    missed = json.loads(out.stdout)
    assert missed == {}, missed
