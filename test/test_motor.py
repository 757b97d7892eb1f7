"""Wet motor model: check 7 of docs/model.md, convergence, heat balance, transient accuracy."""

import numpy as np
import pytest

from wet_eha_thermal.config import ConfigError, load_config
from wet_eha_thermal.model.motor import MotorInputs, WetMotor
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.offline.maps import compute_maps
from wet_eha_thermal.units import C_TO_K, RPM


def make_motor(cfg, refresh_dT_K=0.25, max_substep_s=0.1, **overrides):
    if overrides:
        cfg = load_config(overrides={f'motor.{k}': v for k, v in overrides.items()})
    return WetMotor(cfg.motor, get_oil(cfg.fluid.grade), refresh_dT_K=refresh_dT_K,
                    max_substep_s=max_substep_s)


def inputs(rpm=10000.0, amps=15.0, inlet_C=40.0, flow_L_min=1.0):
    return MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM,
                       oil_inlet_K=inlet_C + C_TO_K, oil_flow_m3_s=flow_L_min / 60000,
                       ambient_K=20.0 + C_TO_K, case_pressure_Pa=6e5)


@pytest.fixture(scope='module')
def maps(cfg):
    return compute_maps(cfg)


def test_default_network_size_and_names(cfg):
    m = make_motor(cfg)
    assert m.cfg.slices == 5
    layers = m.cfg.winding_layers
    # 7 stack parts and the winding's layers x 5 slices, 5 end parts (the cap's hub and the
    # bearing with them) and the end winding's layers x 2 sides, 5 + 2 oil volumes
    assert m.state_count == (7 + layers) * 5 + (5 + layers) * 2 + 7
    m.steady_state(inputs())
    assert m.temperature('winding.l3.s3') > m.temperature('gap_oil.s3')
    assert m.temperature('gap_oil.s5') == m.outputs()['airgap_oil_outlet']
    with pytest.raises(KeyError, match='winding'):
        m.temperature('winding.l1.s9')


def test_speed_sweep_rises_monotonically(maps):
    # docs/model.md check 7: at 15 A, winding and frame rise with speed 2000 -> 20000 r/min
    pts = [p for p in maps if p.sweep == 'speed']
    assert [p.speed_rpm for p in pts] == sorted(p.speed_rpm for p in pts)
    assert pts[0].speed_rpm == 2000 and pts[-1].speed_rpm == 20000
    # from 2000 to 4000 r/min the friction is nearly laminar (exact Couette below the
    # vortex onset at Ta_m 1700, about 2 W at 2000 r/min) while the onset lifts the gap
    # convection: the winding stays level there (within 0.05 K), and rises from there on
    for key in ('winding_mean', 'winding_hotspot', 'frame'):
        t = [p.temperatures_C[key] for p in pts]
        assert t[1] > t[0] - 0.05, key
        assert all(b > a for a, b in zip(t[1:], t[2:])), key
    # core and friction losses grow with speed; copper only through R(T)
    for key in ('gap_friction', 'core_yoke', 'core_teeth', 'end_face_friction', 'bearings'):
        v = [p.losses_W[key] for p in pts]
        assert all(b > a for a, b in zip(v, v[1:])), key


def test_current_sweep_rises_as_current_squared(maps):
    pts = [p for p in maps if p.sweep == 'current']
    amps = np.array([p.current_A for p in pts])
    rise = np.array([p.temperatures_C['winding_mean'] for p in pts])
    assert np.all(np.diff(rise) > 0)
    # winding rise above the 5 A point against I^2: a straight line explains it
    # (R^2 > 0.99); R(T) bends it slightly upwards, so the fit is not exact
    x, y = amps ** 2 - amps[0] ** 2, rise - rise[0]
    slope = np.dot(x, y) / np.dot(x, x)
    r2 = 1 - np.sum((y - slope * x) ** 2) / np.sum((y - y.mean()) ** 2)
    assert r2 > 0.99
    top = pts[-1].losses_W
    copper = top['copper_slot'] + top['copper_end']
    assert copper > sum(v for k, v in top.items() if not k.startswith('copper'))


def test_steady_state_heat_balance_closes(maps):
    for p in maps:
        total = sum(p.losses_W.values())
        heat = p.heat_W
        assert heat['to_ambient'] + heat['to_oil'] == pytest.approx(total, rel=1e-9)
        # the oil carries off what the solids give it through the bore and the end spaces
        # and the friction made in it
        in_oil = p.losses_W['gap_friction'] + p.losses_W['end_face_friction']
        assert heat['bore'] + heat['end_spaces'] + in_oil == pytest.approx(heat['to_oil'],
                                                                           rel=1e-9)


@pytest.mark.slow
def test_airgap_outlet_converges_with_section_count(cfg):
    outlet = {}
    for n in (2, 5, 10, 20, 40):
        m = make_motor(cfg, slices=n)
        m.steady_state(inputs(rpm=16000))
        outlet[n] = m.outputs()['airgap_oil_outlet']
    diffs = [abs(outlet[b] - outlet[a]) for a, b in ((2, 5), (5, 10), (10, 20), (20, 40))]
    assert all(b < a for a, b in zip(diffs, diffs[1:])), diffs
    # first-order upwind error halves with each doubling: 40 sections are within
    # about the last difference of the limit; 0.05 K is well below sensor accuracy
    assert diffs[-1] < 0.05


@pytest.mark.slow
def test_transient_settles_on_the_steady_state(cfg):
    u = inputs(rpm=12000, amps=20)
    ref = make_motor(cfg)
    ref.steady_state(u)
    # near the steady state nothing moves fast: 5 s steps without sub-steps; the
    # 0.01 K refresh threshold keeps the coefficient lag below the 2 mK tolerance
    m = make_motor(cfg, refresh_dT_K=0.01, max_substep_s=5.0)
    m.initialise(20.0 + C_TO_K)
    for _ in range(6 * 720):      # six hours: many housing time constants
        m.step(5.0, u)
    for key, value in ref.outputs().items():
        assert m.outputs()[key] == pytest.approx(value, abs=2e-3), key


@pytest.mark.slow
@pytest.mark.parametrize('dt', [1.0, 0.1])
def test_transient_is_step_size_independent(cfg, dt):
    u = inputs(rpm=14000, amps=25)
    horizon = 120.0

    def run(step):
        m = make_motor(cfg)
        m.initialise(20.0 + C_TO_K)
        for _ in range(int(round(horizon / step))):
            m.step(step, u)
        return m.outputs()

    ref, out = run(0.01), run(dt)
    for key in ref:
        # coefficients lag by at most one step while temperatures rise at up to
        # about 0.5 K/s in the first minutes: 0.05 K bounds that lag at dt = 1 s
        assert out[key] == pytest.approx(ref[key], abs=0.05), key


def run_load_step(cfg, dt, refresh_dT_K=0.25):
    """Jump from 10 000 r/min, 15 A steady to 20 000 r/min, 35 A for one second."""
    m = make_motor(cfg, refresh_dT_K)
    m.steady_state(inputs())
    for _ in range(int(round(1.0 / dt))):
        m.step(dt, inputs(rpm=20000, amps=35))
    return m.outputs()


@pytest.fixture(scope='module')
def load_step_reference(cfg):
    # coefficients refreshed every 0.005 K of drift at a 0.1 ms step
    return run_load_step(cfg, 1e-4, refresh_dT_K=0.005)


@pytest.mark.slow
@pytest.mark.parametrize('dt', [1e-4, 1e-2, 1.0])
def test_any_step_follows_a_violent_load_step(cfg, load_step_reference, dt):
    # the airgap oil heats by 19 K in that second and its viscosity (so the
    # friction) falls with it; 0.05 K is a tenth of a class-1 thermocouple's
    # tolerance (0.5 K); measured 0.02 K at 1 s
    out = run_load_step(cfg, dt)
    for key, value in load_step_reference.items():
        assert out[key] == pytest.approx(value, abs=0.05), key


@pytest.mark.slow
def test_transient_energy_ledger_closes(cfg):
    # a load that changes every step: losses = stored + to ambient + carried by the oil
    m = make_motor(cfg)
    m.initialise(30.0 + C_TO_K)
    rng = np.random.default_rng(1)
    for k in range(600):
        rpm = 12000 + 6000 * np.sin(k / 40)
        speeds = rng.normal(rpm * RPM, 20.0, size=20)    # 20 speed samples in the step
        m.step(0.05, MotorInputs(current_sq_mean_A2=(15 + 10 * np.cos(k / 25)) ** 2,
                                 speed_rad_s=speeds, oil_inlet_K=(40 + k / 60) + C_TO_K,
                                 oil_flow_m3_s=(1.0 + 0.3 * np.sin(k / 30)) / 60000,
                                 ambient_K=20.0 + C_TO_K))
    e = m.energy_J
    assert e['losses'] > 1e4
    # exact discretisation with the coefficients in use: round-off only
    assert e['stored'] + e['to_ambient'] + e['to_oil'] == pytest.approx(e['losses'], rel=1e-9)


def test_losses_average_friction_over_speed_samples(cfg):
    # friction grows as about speed^2.5: samples alternating 0 and 2w give more loss
    # than a steady w, exactly the mean of the two sample losses
    m = make_motor(cfg)
    m.steady_state(inputs())
    w = 10000 * RPM
    steady = m.losses(inputs(rpm=10000))
    u = inputs()
    u.speed_rad_s = np.array([0.0, 2 * w])
    mixed = m.losses(u)
    u.speed_rad_s = 2 * w
    double = m.losses(u)
    for group in ('gap_friction', 'end_face_friction', 'bearings'):
        src = m.sources[group]
        assert np.allclose(mixed[src], 0.5 * double[src], rtol=1e-12), group
    gap = m.sources['gap_friction']
    assert mixed[gap].sum() > 2.5 * steady[gap].sum()


def test_laminar_airgap_flow_is_reported(cfg):
    m = make_motor(cfg)
    m.steady_state(inputs())
    flags = {(f.correlation, f.quantity): f for f in m.log}
    assert any('Re' in q for (_, q) in flags), [str(f) for f in m.log]


def test_airgap_nusselt_is_chosen_by_name(cfg):
    """Default and 'becker_kaye' agree bit for bit; another law moves the temperatures."""
    u = inputs(rpm=12000, amps=20)
    motors = [make_motor(cfg), make_motor(cfg, airgap_nusselt='becker_kaye'),
              make_motor(cfg, airgap_nusselt='tachibana_fukui')]
    for m in motors:
        m.steady_state(u)
    default, named, other = (m.outputs() for m in motors)
    assert named == default
    assert any(other[key] != value for key, value in default.items())


def test_unknown_airgap_nusselt_names_the_key_and_the_choices():
    """A bad name is refused at load with the key, the value and the allowed names."""
    with pytest.raises(ConfigError, match=r"motor\.airgap_nusselt = 'gazley': unknown; "
                                          r'allowed: becker_kaye, tachibana_fukui'):
        load_config(overrides={'motor.airgap_nusselt': 'gazley'})
