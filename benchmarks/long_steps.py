"""
The model's long steps against the same model stepped finely: the forecast's and the heating's.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/long_steps.py [--horizon 1200]

Several callers step the coupled model in long steps of held or repeated
inputs: the outlook's forecast (steps of ``forecast_step_s``, doubled up to
one pass of the repeated duty while the state moves little) and the cold
start's heating of the uncertainty copies (the longest horizon in a few
equal exact steps). Here, from the reference rig at ambient:

- forecast: 60 s of a stage's duty stepped as the live estimator steps
  (20 ms), then the outlook's forecast of it (its own code) with its steps,
  and with 1 s steps; a light duty (stage 6, no load) and a loaded one
  (stage 1, 16 MPa);
- heating: the held duties of the limits at the continuous rating (1000
  rad/s at 10 MPa, 500 rad/s at 15 MPa) over the longest horizon in 4, 8,
  16 and 64 equal steps (:func:`~wet_eha_thermal.estimator.uncertainty._heated`,
  the heating's own stepping), and in 1 s steps.

Printed for the winding hot spot, the magnet and the oil (the limited
quantities) and the pump case oil: the largest error (K) of the long steps
against the fine ones over the run (forecast) or at the horizon (heating),
and each rise above ambient. The fine reference's own convergence: the
heating in 0.5 s steps against 1 s on the loaded duty.
"""

import argparse
import time

import numpy as np

from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.limits import HeldDuty
from wet_eha_thermal.estimator.outlook import _Forecast, Outlook
from wet_eha_thermal.estimator.uncertainty import _heated
from wet_eha_thermal.model import snapshot
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.eha import EHAModel, SampleBlock
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.model.quantity_table import limits_C
from wet_eha_thermal.units import C_TO_K

NAMES = ('winding_hotspot', 'magnet', 'oil', 'pump_case')
AMBIENT_K = C_TO_K + 20.0
STEP_S = 0.02          # the live estimator's step
PER_STEP = 10          # samples per live step (500 Hz)


def stage_blocks(cfg, stage: int, duration_s: float):
    """Return the sensor samples of ``duration_s`` of a stage, one block per live step."""
    kin = KineticModel(cfg, get_oil(cfg.fluid.grade))
    t = np.arange(1, int(round(duration_s / STEP_S)) * PER_STEP + 1) * (STEP_S / PER_STEP)
    s = kin.sample(stage_duty(cfg, stage), t, ThermalFeedback.uniform(AMBIENT_K))
    cols = [np.asarray(getattr(s, f)) for f in SampleBlock.__dataclass_fields__]
    return [SampleBlock(*(c[k:k + PER_STEP] for c in cols))
            for k in range(0, t.size, PER_STEP)]


def cold_model(cfg, first: SampleBlock) -> EHAModel:
    """Return the estimator's model at ambient, started at ``first``."""
    m = EHAModel(cfg, coefficient_filter_s=cfg.estimator.coefficient_filter_s)
    m.initialise(AMBIENT_K, first)
    return m


def forecast_run(cfg, outlook: Outlook, saved: bytes, horizon_s: float, fine_n: int = 0):
    """Return the forecast's (times s, outputs K): its own steps, or ``fine_n`` live steps each."""
    f = _Forecast(start_s=0.0, ambient_K=AMBIENT_K, now_C={}, saved=saved,
                  blocks=list(outlook.window), crossed=dict.fromkeys(outlook.limits_C),
                  n=max(1, int(round(cfg.estimator.forecast_step_s / STEP_S))))
    outlook.forecast = f
    outlook._forecast_step_unguarded()            # its first slice: the copy and the duty
    times, ys = [0.0], [[f.model.outputs()[q] for q in NAMES]]
    while f.t_s < horizon_s - 1e-9:
        if fine_n:
            f.n = fine_n
        outlook.forecast = f                       # (it lets go of it at its horizon)
        outlook._forecast_step_unguarded()
        out = f.model.outputs()
        times.append(f.t_s)
        ys.append([out[q] for q in NAMES])
    outlook.forecast = None
    return np.array(times), np.array(ys)


def forecasts(cfg, horizon_s: float) -> None:
    """Print the forecast's error against 1 s steps on a light and a loaded stage."""
    for stage in (6, 1):
        blocks = stage_blocks(cfg, stage, cfg.estimator.forecast_window_s)
        model = cold_model(cfg, blocks[0])
        outlook = Outlook(cfg, model, limits_C(cfg))
        for b in blocks[1:]:
            model.step(b, AMBIENT_K)
            outlook.record(b)
        saved = snapshot.save(model)
        t0 = time.process_time()
        t, y = forecast_run(cfg, outlook, saved, horizon_s)
        cpu = time.process_time() - t0
        tf, yf = forecast_run(cfg, outlook, saved, horizon_s,
                              fine_n=int(round(1.0 / STEP_S)))
        ref = np.column_stack([np.interp(t, tf, yf[:, k]) for k in range(len(NAMES))])
        err = np.abs(y - ref).max(axis=0)
        rise = ref[-1] - AMBIENT_K
        print(f'forecast, stage {stage}: {t.size - 1} steps over {t[-1]:.0f} s '
              f'({cpu:.2f} s CPU), largest error against 1 s steps: '
              + ', '.join(f'{q} {e:.2f} K (rise {r:.1f})' for q, e, r in zip(NAMES, err, rise)),
              flush=True)


def heatings(cfg, horizon_s: float) -> None:
    """Print the heating's error at the horizon against 1 s steps on two loaded duties."""
    first = HeldDuty(0.0, 1e6, 1e6, 1e6, 0.0).block(0.0, 0.0)
    saved = snapshot.save(cold_model(cfg, first))
    amps = cfg.motor.max_continuous_current_A
    for label, (speed, p_a) in {'1000 rad/s, 10 MPa': (1000.0, 10e6),
                                '500 rad/s, 15 MPa': (500.0, 15e6)}.items():
        held = HeldDuty(speed, p_a, 1e6, 1e6, 0.0)

        def heat(steps):
            return _heated(saved, steps, list(NAMES), held, AMBIENT_K, amps, horizon_s)

        ref = heat(int(round(horizon_s)))
        rise = ref - AMBIENT_K
        print(f'heating, {label}, {horizon_s:.0f} s at {amps:g} A: rise '
              + ', '.join(f'{q} {r:.1f} K' for q, r in zip(NAMES, rise)), flush=True)
        for steps in (4, 8, 16, 64):
            t0 = time.process_time()
            y = heat(steps)
            cpu = time.process_time() - t0
            print(f'  {steps} steps ({cpu:.2f} s CPU): error against 1 s steps '
                  + ', '.join(f'{q} {e:+.2f} K' for q, e in zip(NAMES, y - ref)), flush=True)
        if p_a == 15e6:
            half = heat(int(round(2 * horizon_s)))
            print('  the reference: 0.5 s steps against 1 s: '
                  + ', '.join(f'{q} {e:+.3f} K' for q, e in zip(NAMES, half - ref)), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--horizon', type=float, default=1200.0,
                    help='forecast horizon (s); the heating takes the longest limit horizon')
    args = ap.parse_args()
    cfg = load_config()
    heatings(cfg, max(cfg.estimator.limits.horizons_s))
    forecasts(cfg, args.horizon)


if __name__ == '__main__':
    main()
