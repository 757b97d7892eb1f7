"""The compiled model step gives the numpy results, and the model runs without numba too."""

import json
import os
import subprocess
import sys

import pytest
from wet_eha_thermal.model import compiled

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

# one minute of stage 6 (the most flow and pressure swing) from cold: about 3000 model
# steps through every compiled kernel (flows, airgap friction, circuit matrices)
RUN = """
import json, sys
from wet_eha_thermal.config import load_config
from wet_eha_thermal.model import compiled
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.offline.simulation import simulate
cfg = load_config()
r = simulate(cfg, stage_duty(cfg, 6), 60.0, record_every_s=60.0)
json.dump({'compiled': compiled.COMPILED, 'outputs': r.model.outputs(),
           'energy': r.model.energy()}, sys.stdout)
"""


def run_model(disable_jit: bool) -> dict:
    env = dict(os.environ, NUMBA_DISABLE_JIT='1' if disable_jit else '0')
    out = subprocess.run([sys.executable, '-c', RUN], env=env, capture_output=True, text=True,
                         timeout=600, check=True)
    return json.loads(out.stdout)


@pytest.mark.skipif(not compiled.COMPILED, reason='numba is not installed')
def test_compiled_and_interpreted_runs_agree():
    # the same source, compiled by numba and run as numpy code: they differ only in
    # the rounding of a few transcendental functions (1 ulp, 1e-16 relative), so
    # after 3000 steps the temperatures agree far below a microkelvin; a kernel that
    # broadcast, indexed or branched differently from numpy would miss by kelvins
    plain = run_model(disable_jit=True)
    fast = run_model(disable_jit=False)
    assert (plain['compiled'], fast['compiled']) == (False, True)
    assert plain['outputs'].keys() == fast['outputs'].keys()
    for name, value in fast['outputs'].items():
        assert value == pytest.approx(plain['outputs'][name], abs=1e-6), name
    for name, value in fast['energy'].items():
        assert value == pytest.approx(plain['energy'][name], rel=1e-9, abs=1e-6), name
    # the run did work the EHA (kilojoules of losses), so the states compared moved
    assert fast['energy']['sources'] > 1e3
