"""
Wall time of the motor model: one steady-state solve, one simulated hour of transient.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_motor.py [--repeat N]
Prints medians over the repeats (steady solves) and each transient run.
"""

import argparse
import statistics
import time

import numpy as np

from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.motor import MotorInputs, WetMotor
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.units import C_TO_K


def main() -> None:
    """Time the solves and print a small report."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--repeat', type=int, default=20)
    parser.add_argument('--hours', type=float, default=1.0)
    parser.add_argument('--dt', type=float, default=0.01, help='transient step, s')
    args = parser.parse_args()
    cfg = load_config()
    oil = get_oil(cfg.fluid.grade)
    u = MotorInputs(current_sq_mean_A2=15.0 ** 2, speed_rad_s=10000 * np.pi / 30,
                    oil_inlet_K=40 + C_TO_K, oil_flow_m3_s=1.0 / 60000,
                    ambient_K=20 + C_TO_K, case_pressure_Pa=6e5)
    t0 = time.perf_counter()
    motor = WetMotor(cfg.motor, oil)
    build = time.perf_counter() - t0
    print(f'network: {motor.node_count} nodes ({motor.state_count} with heat capacity), '
          f'{len(motor.net.boundary_names)} boundaries, {len(motor.net.conductance)} '
          f'conductance links; build {build * 1e3:.1f} ms')
    cold, warm, iters = [], [], []
    for _ in range(args.repeat):
        m = WetMotor(cfg.motor, oil)
        t0 = time.perf_counter()
        m.steady_state(u)
        cold.append(time.perf_counter() - t0)
        iters.append(m.iterations)
        t0 = time.perf_counter()
        m.steady_state(u)   # from its own solution: one iteration
        warm.append(time.perf_counter() - t0)
    print(f'steady state (10000 r/min, 15 A), from a uniform start: median '
          f'{statistics.median(cold) * 1e3:.1f} ms over {args.repeat} '
          f'({statistics.median(iters):.0f} fixed-point iterations); '
          f'from a converged state: {statistics.median(warm) * 1e3:.1f} ms')
    steps = int(round(args.hours * 3600 / args.dt))
    motor.initialise(20 + C_TO_K)
    t0 = time.perf_counter()
    for _ in range(steps):
        motor.step(args.dt, u)
    wall = time.perf_counter() - t0
    out = motor.outputs()
    print(f'transient from 20 degC, {args.hours:g} h at {args.dt * 1e3:g} ms ({steps} steps): '
          f'{wall:.1f} s wall, {wall / steps * 1e6:.0f} us/step, '
          f'{args.hours * 3600 / wall:.0f}x real time; winding mean at the end '
          f'{out["winding_mean"] - C_TO_K:.2f} degC')


if __name__ == '__main__':
    main()
