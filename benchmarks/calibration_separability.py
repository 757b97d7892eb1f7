"""
Which of the uncertain parameters a bench log can separate: the calibration's own screening.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/calibration_separability.py
     [--seconds 600] [--jobs 2]

The truth: the reference rig with the calibration tests' parameter truth (30 %
more frame-yoke contact gap, a 20 W seal loss) and the three factors issue 26
made calibratable off their nominal 1: end-space coefficients x 0.7, bearing
friction x 1.5, rotor eddy losses x 1.3. Logs (the simulated rig, 50 Hz
samples, 10 Hz thermocouples with 0.2 K noise): stages 1-3 of the duty, and
two spin tests without load (no pressure across the actuator, the current
only the friction's) at a constant 6 and 12 L/min. Each set is calibrated
for the five keys; printed, per set, what `calibrate` does with each key:
fitted (value against the truth, 95 % interval) or held (why: too little
effect on any thermocouple, or nearly a combination of the others).
"""

import argparse
from multiprocessing import get_context
import sys
import time

from wet_eha_thermal import calibration as cb
from wet_eha_thermal.config import load_config, with_values
from wet_eha_thermal.model.duty import stage_duty, TableDuty
from wet_eha_thermal.offline.simulated_rig import SimulatedRig
from wet_eha_thermal.units import L_MIN

GAP = 'motor.stator.frame_contact_gap_m'
SEAL = 'hydraulics.pump.extra_loss_W'
END = 'motor.end_spaces.htc_multiplier'
BEARING = 'motor.bearings.friction_factor'
ROTOR = 'motor.electromagnetic.loss_factor'
KEYS = (GAP, SEAL, END, BEARING, ROTOR)


def nominal_config():
    """Return the estimator's configuration: the reference rig, one differential pressure."""
    return load_config(overrides={'estimator.pressure_inputs': 'differential'})


def truth(cfg) -> dict:
    """Return the truth's parameter values."""
    return {GAP: 1.3 * cfg.motor.stator.frame_contact_gap_m, SEAL: 20.0, END: 0.7,
            BEARING: 1.5, ROTOR: 1.3}


def duty(cfg, name: str):
    """Return a reference stage ('1'..'6') or a spin test without load ('spin6', 'spin12')."""
    if not name.startswith('spin'):
        return stage_duty(cfg, int(name))
    act = cfg.hydraulics.actuator
    q = float(name[4:]) * L_MIN
    # back and forth inside the stroke: a constant flow one way would run out of stroke
    half = act.half_stroke_m * act.area_m2 * 0.8
    period = 4.0 * half / q
    t = [0.0, 0.25 * period, 0.75 * period, period]
    return TableDuty(t, [q, q, -q, -q], [0.0] * 4, act.area_m2, act.half_stroke_m,
                     name=f'spin {name[4:]} L/min, no load')


def record(job: tuple):
    """Record one log of the truth rig: (name, LogData)."""
    name, seconds = job
    cfg = nominal_config()
    rig_cfg = with_values(cfg, truth(cfg))
    rig = SimulatedRig(rig_cfg, duty(rig_cfg, name), rate_Hz=50.0, block_s=0.1,
                       seed=hash(name) % 1000)
    return name, cb.log_from_rig(rig, seconds, cfg.calibration, name=name,
                                 thermocouple_rate_Hz=10.0)


def main() -> None:
    """Record the logs, calibrate each set, print what each key came to."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seconds', type=float, default=600.0, help='length of each log (s)')
    p.add_argument('--jobs', type=int, default=2)
    args = p.parse_args()
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python '
          'benchmarks/calibration_separability.py ' + ' '.join(sys.argv[1:]), flush=True)
    t0 = time.perf_counter()
    names = ['1', '2', '3', 'spin6', 'spin12']
    with get_context('fork').Pool(args.jobs) as pool:
        logs = dict(pool.map(record, [(n, args.seconds) for n in names], chunksize=1))
    print(f'recorded {len(logs)} logs of {args.seconds:g} s in {time.perf_counter() - t0:.0f} s',
          flush=True)
    cfg = nominal_config()
    want = truth(cfg)
    sets = {'stages 1-3': ['1', '2', '3'], 'spin tests at 6 and 12 L/min': ['spin6', 'spin12'],
            'stages 1-3 and both spin tests': names}
    for label, chosen in sets.items():
        t1 = time.perf_counter()
        run = cb.calibrate([logs[n] for n in chosen], cfg, list(KEYS), jobs=args.jobs)
        print(f'\n{label} ({time.perf_counter() - t1:.0f} s):', flush=True)
        for prm in run.parameters:
            if prm.identifiable:
                print(f'  {prm.key}: fitted {prm.value:.4g} (truth {want[prm.key]:.4g}, '
                      f'95 % {prm.ci95[0]:.4g}..{prm.ci95[1]:.4g})')
            else:
                print(f'  {prm.key}: held at {prm.nominal:.4g} (truth {want[prm.key]:.4g}): '
                      f'{prm.note}')
        print(f'  all thermocouples, RMS over the fit logs: {run.rms_before_K:.2f} -> '
              f'{run.rms_after_K:.2f} K', flush=True)
    print(f'\nwall time {time.perf_counter() - t0:.0f} s')


if __name__ == '__main__':
    main()
