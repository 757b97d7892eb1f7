"""
The cold start's sigma per K of rise: its steps against many, on several held duties.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/heated_relative.py [--reference 120]

On a cold start the limits take each quantity's sigma per K of rise from the
uncertainty's copies heated once at the continuous rating over the longest
horizon (:class:`~wet_eha_thermal.estimator.uncertainty.Heating`, in as many
equal exact steps as the unperturbed copy's rise needs). Here the copies of
the reference rig, started at ambient, are heated that way on held duties
from idle to a pump loaded past the motor's continuous torque, and with
``--reference`` steps; printed, each duty's step count, the figures of the
limited quantities both ways, the largest relative difference over them, and
the CPU time of the heating.
"""

import argparse
import time

from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.core import Estimator
from wet_eha_thermal.estimator.limits import HeldDuty
from wet_eha_thermal.estimator.uncertainty import Heating

#: held duties: speed (rad/s), port A (Pa); port B and the accumulator at 1 MPa
DUTIES = {'idle': (0.0, 1e6), '800 rad/s, 3 MPa': (800.0, 3e6),
          '1000 rad/s, 10 MPa': (1000.0, 10e6), '500 rad/s, 15 MPa': (500.0, 15e6)}
LIMITED = ('winding_hotspot', 'magnet', 'oil')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--reference', type=int, default=120, help='steps of the reference heating')
    args = ap.parse_args()
    est = Estimator(load_config(), outlook='off')
    for t in (0.0, 0.02):        # a first sample starts the model and the copies at ambient
        for name, value in {'current_A': 0.0, 'speed_rad_s': 0.0, 'p_a_Pa': 1e6,
                            'p_b_Pa': 1e6, 'p_acc_Pa': 1e6, 'position_m': 0.0}.items():
            est.push(name, t, value)
    est.advance(0.02)
    prop, ambient_K = est.propagation, est.ambient_K
    for label, (speed, p_a) in DUTIES.items():
        held = HeldDuty(speed, p_a, 1e6, 1e6, 0.0)
        t0 = time.process_time()
        heating = Heating(prop.models, prop.names, held, ambient_K, est.cfg, 0.0, LIMITED)
        few = prop.per_rise(*heating.result())
        cpu_s = time.process_time() - t0
        many = prop.per_rise(*Heating(prop.models, prop.names, held, ambient_K, est.cfg, 0.0,
                                      steps=args.reference).result())
        worst = max(abs(few[q] / many[q] - 1.0) for q in LIMITED)
        shown = ', '.join(f'{q} {few[q]:.4f} ({many[q]:.4f})' for q in LIMITED)
        print(f'{label}: {heating.steps()} steps ({args.reference}): {shown}; '
              f'largest difference {100 * worst:.1f} %; {cpu_s:.2f} s of CPU', flush=True)


if __name__ == '__main__':
    main()
