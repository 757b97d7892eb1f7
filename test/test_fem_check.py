"""
The motor network against an independent finite-element solution (check 8 of docs/model.md).

Coarse meshes (the benchmark benchmarks/fem_check.py refines them and shows that the figures
asserted here have converged to well within the tolerances): the analytic annulus as the mesh
check; the 2-D slot pitch against a one-slice network built by the production builder; the
published hot spot against the 2-D slot pitch of the network's hottest slice; the r-z motor
against the full network at three map points of config/reference_eha.yaml.
"""

import numpy as np
import pytest

from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.motor import WetMotor
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.verification import fem

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

POINTS = ((10000, 15.0), (10000, 30.0), (20000, 15.0))
H_SLOT_M = 0.001     # the slot pitch: winding mean within 0.05 K of the 0.25 mm mesh
H_RZ_M = 0.00075     # r-z: within 0.03 K of the 0.5 mm mesh (1.5 mm: 0.11 K)


@pytest.fixture(scope='module')
def checks():
    cfg = load_config()
    oil = get_oil(cfg.fluid.grade)
    return {(rpm, amps): fem.check_point(cfg, oil, rpm, amps, H_SLOT_M, H_RZ_M)
            for rpm, amps in POINTS}


@pytest.mark.parametrize('axisymmetric', [False, True])
def test_annulus_against_its_exact_solution(axisymmetric):
    # P1 elements converge as h^2: 1 mm gives about 0.02 % of the mean rise, 4 mm 0.3 %
    fine = fem.annulus_check(0.001, axisymmetric)
    coarse = fem.annulus_check(0.004, axisymmetric)
    for key in ('mean', 'peak'):
        exact = fine[f'{key}_exact']
        assert fine[f'{key}_fe'] == pytest.approx(exact, rel=1e-3)
        err_fine, err_coarse = abs(fine[f'{key}_fe'] - exact), abs(coarse[f'{key}_fe'] - exact)
        assert err_coarse / err_fine > 8.0     # second order: 16 at 4x


def _rise(values, oil_K):
    return {k: (v - oil_K if not k.endswith('W_m') else v) for k, v in values.items()}


@pytest.mark.parametrize('point', POINTS)
def test_slot_pitch_against_one_slice_network(checks, point):
    """Winding mean and hot spot, yoke, frame within 5 % (or 0.5 K); heat split within 5 %."""
    pc = checks[point]
    oil = fem.slot_problem(pc.motor, pc.inputs).oil_K
    fe, net = _rise(pc.slot, oil), _rise(pc.slot_net, oil)
    # the network's hot spot is its hottest winding block: with one slice, its mean
    assert fe['winding_mean'] == pytest.approx(net['winding_mean'], rel=0.05, abs=0.5)
    for part in ('yoke', 'frame'):
        assert fe[part] == pytest.approx(net[part], rel=0.05)
    for path in ('bore_W_m', 'frame_W_m'):
        assert fe[path] == pytest.approx(net[path], rel=0.05)
    # the field closes its balance: losses out through the bore and the frame
    losses = sum(getattr(fem.slot_problem(pc.motor, pc.inputs), k)
                 for k in ('copper_W_m', 'yoke_W_m', 'teeth_W_m'))
    assert fe['bore_W_m'] + fe['frame_W_m'] == pytest.approx(losses, rel=1e-9)


@pytest.mark.parametrize('point', POINTS)
def test_rz_cross_section_reproduces_the_slot_pitch(checks, point):
    """The r-z stack, fitted on winding and yoke means, gives the 2-D teeth mean and bore heat."""
    pc = checks[point]
    prob = fem.slot_problem(pc.motor, pc.inputs)
    motor, u = fem.slice_motor(pc.motor.cfg, pc.motor.oil, prob)
    fe = fem.motor_rz(motor, u, pc.coupling, H_RZ_M)
    oil = prob.oil_K
    # not fitted: 3 % of the rise (the mesh alone moves it by 1 %)
    assert fe.mean(fe.blocks_of('teeth')) - oil == pytest.approx(pc.slot['teeth'] - oil,
                                                                 rel=0.03)
    bore = fem.fe_figures(fe, motor)['bore'] / pc.motor.cfg.stack_length_m
    assert bore == pytest.approx(pc.slot['bore_W_m'], rel=0.01)


#: the published hot spot against the FE: 10 000 r/min from rated to peak current, 20 000 r/min
HOTSPOT_POINTS = ((10000, 15.0), (10000, 30.0), (10000, 45.0), (20000, 15.0))
H_PEAK_M = 0.0005    # the slot pitch's peak-over-mean within 0.5 % of the 0.25 mm mesh's


@pytest.mark.parametrize('point', HOTSPOT_POINTS)
def test_published_hot_spot_is_the_fe_peak_of_the_hottest_slice(point):
    """
    The hot spot within 0.5 K of the 2-D FE's peak in the hottest slice, never lower by more.

    The FE solves that slice's section (the network's losses, axial heat flows, h and oil);
    the hot spot comes from the network's temperatures (model/hot_spot.py). The block mean
    alone sits several K below the peak at 45 A: the test fails on it.
    """
    cfg = load_config()
    oil = get_oil(cfg.fluid.grade)
    motor = WetMotor(cfg.motor, oil)
    u = fem.map_inputs(cfg.maps, *point)
    motor.steady_state(u)
    means = motor.winding_slices_K()
    i = int(np.argmax(means)) + 1
    _, fe = fem.slot_pitch(cfg.motor, fem.slice_problem(motor, u, i), H_PEAK_M)
    hot = motor.outputs()['winding_hotspot']
    assert hot == pytest.approx(fe['winding_peak'], abs=0.5)
    # the FE's section is the network's slice: their means agree (check 8's 5 %, or 0.5 K)
    oil = motor.temperature(f'gap_oil.s{i}')
    assert means[i - 1] - oil == pytest.approx(fe['winding_mean'] - oil, rel=0.05, abs=0.5)


def _rz_targets(pc):
    fe, net = pc.fe, pc.network
    return {'winding_mean': abs(fe['winding_mean'] - net['winding_mean']) <= 1.0,
            'winding_hottest_block': abs(fe['winding_hottest_block']
                                         - net['winding_hottest_block']) <= 2.0,
            'magnet': abs(fe['magnet'] - net['magnet']) <= 3.0}


@pytest.mark.parametrize('point', POINTS)
def test_rz_motor_against_network(checks, point):
    """Winding mean within 1 K, hottest block within 2 K, magnet within 3 K; energy closes."""
    pc = checks[point]
    met = _rz_targets(pc)
    assert all(met.values()), {k: (pc.fe[k], pc.network[k]) for k in met}
    # the FE's own energy balance: losses = heat to ambient + enthalpy carried off by the oil
    fe = pc.rz
    oil_out = fe.T[fe.node(pc.motor.oil_nodes[-1])]
    rate = pc.motor.net.advection_rate[pc.motor.adv[0]]
    to_amb = pc.fe['frame_to_ambient'] + pc.fe['caps_to_ambient']
    assert to_amb + rate * (oil_out - pc.inputs.oil_inlet_K) == pytest.approx(
        float(np.sum(pc.motor.power_W)), rel=1e-6)
