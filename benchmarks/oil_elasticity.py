"""
Why the kinetic model may keep the oil incompressible: the reference rig's hydraulic time scales.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/oil_elasticity.py
     [--png docs/oil-elasticity.png]

Over the oil's range (-40 to 135 degC), with the isentropic tangent bulk modulus
K_S(T, p) of the oil (the one of a compression faster than heat exchange: a
chamber within a duty cycle) at the working pressure, for one side of the
actuator (pump port + line + chamber at mid-stroke, the volume V whose
pressure the load sets):

- the decay time of a pressure trapped on that side through the pump's two
  leakage paths, tau = (V / K_S) / (dQ_int/dp + dQ_ext/dp), the leakage
  conductances of the gap law (laminar here) at the mean gap pressure;
- the actuator's hydraulic natural frequency, f_h = sqrt(k_h / M) / (2 pi), with
  the oil spring of both sides k_h = K_S A^2 (1 / V_A + 1 / V_B) at mid-stroke
  and a load mass M the datasheet does not give: 100 kg and 1000 kg (est.,
  a control surface's equivalent mass at the rod lies in that band);
- the first organ-pipe (quarter-wave) mode of a line, c / (4 L), c = sqrt(K_S / rho);
- for every stage of the reference duty, the compressibility flow
  (V / K_S) d(dp)/dt as a share of the actuator flow: both are cos(2 pi f t),
  so the share is (V / K_S) dp_a 2 pi f / Q_a, with V at the stage's peak
  position (the larger chamber) as an upper bound.

It prints a table and draws docs/oil-elasticity.png.
"""

import argparse
import math

import numpy as np
from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.duty import STAGES
from wet_eha_thermal.model.fluid_power import gap_leakage
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.units import C_TO_K

P_WORK = 21.0e6          # Pa gauge, the rig's highest working pressure
MASSES_KG = (100.0, 1000.0)
LIVE_STEP_S, OFFLINE_STEP_S = 0.02, 1.0


def time_scales(cfg, T_K: np.ndarray) -> dict:
    """Return the time scales (s) and frequencies (Hz) of the module docstring at ``T_K``."""
    h = cfg.hydraulics
    oil = get_oil(cfg.fluid.grade)
    act, pump, ln = h.actuator, h.pump, h.lines
    p_acc = h.accumulator.pressure_Pa
    line_vol = 0.25 * math.pi * ln.bore_m ** 2 * ln.length_m
    v_side = pump.port_volume_m3 + line_vol + act.dead_volume_m3 + act.area_m2 * act.half_stroke_m
    k_s = oil.isentropic_bulk_modulus(T_K, P_WORK)
    rho = oil.density(T_K, P_WORK)
    # the leakage conductances dQ/dp of both paths at the working point, by differences of
    # the gap law (laminar at the rig: Q / dp)
    dp = P_WORK - p_acc
    p_mean = 0.5 * (P_WORK + p_acc)
    rho_g = oil.density(T_K, p_mean)
    mu = oil.kinematic_viscosity(T_K, p_mean) * rho_g
    gap = (pump.leak_gap_height_m, pump.leak_gap_length_m, pump.leak_discharge_coeff)
    g = 0.0
    for c in (pump.internal_leak_coeff_m3, pump.external_leak_coeff_m3):
        q1, _ = gap_leakage(c, dp * 1.001, mu, rho_g, *gap)
        q0, _ = gap_leakage(c, dp * 0.999, mu, rho_g, *gap)
        g = g + (q1 - q0) / (0.002 * dp)
    k_h = k_s * act.area_m2 ** 2 * 2.0 / v_side
    share = {}
    for n, st in STAGES.items():
        if st.load_dp_amplitude_Pa == 0.0:
            continue
        omega = 2.0 * math.pi * st.frequency_Hz
        x_peak = st.flow_amplitude_m3_s / (act.area_m2 * omega)
        v = v_side + act.area_m2 * x_peak
        share[n] = v / k_s * st.load_dp_amplitude_Pa * omega / st.flow_amplitude_m3_s
    return {'tau_leak_s': v_side / k_s / g,
            'f_h_Hz': {m: np.sqrt(k_h / m) / (2.0 * math.pi) for m in MASSES_KG},
            'f_line_Hz': np.sqrt(k_s / rho) / (4.0 * ln.length_m),
            'share': share, 'V_side_m3': v_side, 'K_S_Pa': k_s}


def main() -> None:
    """Print the time scales over the temperature range; draw the figure."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--png', default='docs/oil-elasticity.png', help='figure to write')
    args = p.parse_args()
    cfg = load_config()
    T_C = np.linspace(-40.0, 135.0, 36)
    s = time_scales(cfg, T_C + C_TO_K)
    print(f'one side of the actuator at mid-stroke: V = {s["V_side_m3"] * 1e6:.1f} mL; '
          f'K_S at {P_WORK / 1e6:g} MPa')
    print(' T degC   K_S GPa  tau_leak s  f_h(100 kg) Hz  f_h(1000 kg) Hz  f_line Hz  '
          + '  '.join(f'stage {n} %' for n in s['share']))
    for i in range(0, T_C.size, 5):
        print(f'{T_C[i]:7.0f}  {s["K_S_Pa"][i] / 1e9:7.3f}  {s["tau_leak_s"][i]:10.4f}  '
              f'{s["f_h_Hz"][100.0][i]:14.1f}  {s["f_h_Hz"][1000.0][i]:15.1f}  '
              f'{s["f_line_Hz"][i]:9.0f}  '
              + '  '.join(f'{100 * v[i]:9.2f}' for v in s['share'].values()))

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax.axhspan(1.0 / 3.0, 5.0, color='0.9', label='duty periods (0.2-3 Hz)')
    ax.semilogy(T_C, s['tau_leak_s'], 'C0', label='trapped pressure through leakage, (V/K_S)/G')
    for m, ls in zip(MASSES_KG, ('-', '--')):
        ax.semilogy(T_C, 1.0 / (2.0 * math.pi * s['f_h_Hz'][m]), 'C1' + ls,
                    label=f'1/(2 pi f_h), load {m:g} kg (est.)')
    ax.semilogy(T_C, 1.0 / s['f_line_Hz'], 'C2', label='line quarter-wave period')
    ax.axhline(LIVE_STEP_S, color='k', ls=':', label='live step 0.02 s')
    ax.axhline(OFFLINE_STEP_S, color='k', ls='-.', label='offline step 1 s')
    ax.set_xlabel('oil temperature (degC)')
    ax.set_ylabel('time (s)')
    ax.set_title(f'hydraulic time scales at {P_WORK / 1e6:g} MPa')
    ax.set_ylim(5e-4, 300.0)
    ax.legend(fontsize=7, loc='upper right')
    for n, v in s['share'].items():
        st = STAGES[n]
        bx.plot(T_C, 100.0 * v, label=f'stage {n}: {st.load_dp_amplitude_Pa / 1e6:g} MPa, '
                f'{st.frequency_Hz:g} Hz')
    bx.set_xlabel('oil temperature (degC)')
    bx.set_ylabel('compressibility flow / actuator flow (%)')
    bx.set_title('(V/K_S) d(dp)/dt against Q, reference stages')
    bx.set_ylim(bottom=0.0)
    bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(f'figure: {args.png}')


if __name__ == '__main__':
    main()
