"""
An energy audit of the coupled model from its public outputs, not from its own ledger.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/audit_energy.py [--seconds 600]
     [--dt 1.0 0.1] [--cases 1 2 3 4 5 6 p2 p5]

For each case (the six reference stages, and periodic duties ``p2``/``p5``:
flow 6 L/min (2.56 L/min at 5 s, inside the stroke) and load 8 MPa, both
``cos(2 pi t / period)`` in phase, period 2 or 5 s) and each model step,
from a uniform start at ambient, it compares

- the energy put in: the electrical energy minus the work done on the load,
  both integrated from the kinetic samples the model was driven with;
- with what the outputs show: the heat stored (every motor node's capacity
  times its temperature change, summed step by step at the mean of the
  capacities before and after; every oil volume's volume at the end times
  the integral of rho c_p dT from the start temperature, at its end
  pressure; every solid shell's capacity times its rise) plus
  the heat to ambient (every ambient conductance times the step-mean
  temperature difference, integrated).

Printed per case and step: the input energy (kJ), the residual
(stored + to ambient - input) / input, and the model's own ledger residual
for comparison, then the end temperatures of the hot-spot and of the pump
case. Every oil volume starts at the same temperature, so the sum over the
volumes at the end is their energy change whatever oil moved between them.
"""

import argparse
import sys
import time

import numpy as np
from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.duty import stage_duty, TableDuty
from wet_eha_thermal.model.hydraulics import OIL_NODES
from wet_eha_thermal.offline.simulation import simulate
from wet_eha_thermal.units import C_TO_K


def periodic_duty(cfg, period_s: float) -> TableDuty:
    """
    Return flow and load 8 MPa, both cos(2 pi t / period), as a table.

    The flow amplitude is 6 L/min, or less where that would take the piston
    beyond 90 % of its half stroke (a 5 s period: 2.56 L/min on the reference rig).
    """
    t = np.linspace(0.0, period_s, 201)
    phase = np.cos(2.0 * np.pi * t / period_s)
    act = cfg.hydraulics.actuator
    flow = min(6.0 / 60000.0, 0.9 * act.half_stroke_m * act.area_m2 * 2.0 * np.pi / period_s)
    return TableDuty(t, flow * phase, 8e6 * phase, act.area_m2, act.half_stroke_m,
                     name=f'periodic {period_s:g} s')


def oil_volumes_at_end(model) -> np.ndarray:
    """Return the oil volume (m^3) of each circuit oil node at the model's present time."""
    ci, act = model.circuit, model.cfg.hydraulics.actuator
    x = model._last[1]                     # the last sample's actuator position (m)
    vol = ci.oil_volumes.copy()
    vol[OIL_NODES.index('chamber_a')] = act.dead_volume_m3 + act.area_m2 * (act.half_stroke_m + x)
    vol[OIL_NODES.index('chamber_b')] = act.dead_volume_m3 + act.area_m2 * (act.half_stroke_m - x)
    # the case buffers oil the accumulator gives (and takes back)
    vol[OIL_NODES.index('case')] += model.case_buffer_m3
    vol[OIL_NODES.index('accumulator')] -= model.case_buffer_m3
    return vol


def audit(cfg, duty, seconds: float, dt_s: float) -> dict:
    """Run ``duty`` one step at a time from ambient; return the audit's figures."""
    amb_K = 20.0 + C_TO_K
    res = simulate(cfg, duty, dt_s, dt_s=dt_s, record_every_s=dt_s)
    model = res.model
    motor, net, ci, oil = model.motor, model.motor.net, model.circuit, model.oil
    T0 = amb_K
    electrical, load = res.electrical_J, res.load_work_J
    stored_motor = 0.0
    to_ambient = 0.0
    # the first step was made by simulate() from a uniform T0
    cap_prev = net.coefficients_in_use()[2].copy()
    T_prev = np.full_like(motor.T, T0)
    boundaries = np.full(net.nb, amb_K)     # only the ambient ends of these links matter
    to_amb_links = np.array(motor.ambient_links + motor.cap_links)

    def book_step():
        nonlocal stored_motor, to_ambient, cap_prev, T_prev
        cap = net.coefficients_in_use()[2]
        d = net.dynamic
        stored_motor += float(np.dot(0.5 * (cap[d] + cap_prev[d]), motor.T[d] - T_prev[d]))
        cap_prev, T_prev = cap.copy(), motor.T.copy()
        flows = net.link_heat_flows(motor.T_mean, boundaries, to_amb_links)
        to_ambient += (float(flows.sum())
                       + float(np.dot(ci.G_amb, ci.T_mean - amb_K))) * dt_s

    book_step()
    for _ in range(int(round(seconds / dt_s)) - 1):
        r = simulate(cfg, duty, dt_s, dt_s=dt_s, record_every_s=dt_s, model=model)
        electrical += r.electrical_J
        load += r.load_work_J
        book_step()
    n_oil = len(OIL_NODES)
    T_oil = model.T_hyd[:n_oil]
    p_end = model._last[3]

    # the integral of rho c_p dT from T0, at the end pressure, times the end volume: rho
    # and c_p are linear in T, so Simpson's rule is exact
    def rho_cp(T):
        return oil.density(T, p_end) * oil.specific_heat(T)

    per_m3 = (T_oil - T0) / 6.0 * (rho_cp(np.full_like(T_oil, T0))
                                   + 4.0 * rho_cp(0.5 * (T_oil + T0)) + rho_cp(T_oil))
    stored_oil = float(np.dot(oil_volumes_at_end(model), per_m3))
    stored_solid = float(np.dot(ci.solid_capacity, model.T_hyd[n_oil:] - T0))
    put_in = electrical - load
    e = model.energy()
    out = model.outputs()
    return {'input_kJ': put_in / 1e3,
            'audit': (stored_motor + stored_oil + stored_solid + to_ambient - put_in) / put_in,
            'ledger': (e['stored'] + e['to_ambient'] - e['sources']) / e['sources'],
            'ledger_input': (e['stored'] + e['to_ambient'] - put_in) / put_in,
            'hotspot_C': out['winding_hotspot'] - C_TO_K, 'case_C': out['pump_case'] - C_TO_K}


def main() -> None:
    """Audit every asked case at every asked step and print one line each."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--seconds', type=float, default=600.0, help='simulated time per run (s)')
    p.add_argument('--dt', type=float, nargs='+', default=[1.0, 0.1], help='model steps (s)')
    p.add_argument('--cases', nargs='+', default=['1', '2', '3', '4', '5', '6', 'p2', 'p5'],
                   help='stage numbers, or pN for the periodic duty of period N s')
    args = p.parse_args()
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/audit_energy.py '
          + ' '.join(sys.argv[1:]), flush=True)
    cfg = load_config()
    for case in args.cases:
        duty = periodic_duty(cfg, float(case[1:])) if case.startswith('p') \
            else stage_duty(cfg, int(case))
        for dt in args.dt:
            t0 = time.perf_counter()
            f = audit(cfg, duty, args.seconds, dt)
            print(f'{duty.name:<14} dt {dt:5.2f} s: input {f["input_kJ"]:8.2f} kJ, audit residual '
                  f'{f["audit"]:+.2e}, ledger {f["ledger"]:+.1e}; hot-spot {f["hotspot_C"]:6.2f} '
                  f'degC, pump case {f["case_C"]:6.2f} degC ({time.perf_counter() - t0:.0f} s)',
                  flush=True)


if __name__ == '__main__':
    main()
