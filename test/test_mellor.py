"""Check 1 of docs/model.md: the Mellor T-block against analytic conduction solutions."""

import numpy as np
import pytest
from scipy.integrate import quad

from wet_eha_thermal.model.mellor import add_cylinder, mellor_resistances
from wet_eha_thermal.model.network import ThermalNetwork

# the network solve is a dense LU of a handful of nodes: agreement is to
# round-off, so 1e-9 relative leaves a wide margin and still catches any
# wrong factor in a resistance formula (those are O(1) errors)
RTOL = 1e-9


def test_radial_resistances_sum_to_the_plain_cylinder_resistance():
    for r1, r2, L, k in ((0.052, 0.045, 0.11, 150.0), (0.038, 0.0185, 0.011, 25.0),
                         (0.5, 0.01, 2.0, 0.3)):
        R = mellor_resistances(r1, r2, L, k, 1.0)
        assert R.R4 + R.R5 == pytest.approx(np.log(r1 / r2) / (2 * np.pi * k * L), rel=1e-12)


def test_solid_cylinder_mean_rise_is_P_over_8_pi_k_L():
    r1, L, k, P = 0.007, 0.03, 45.0, 25.0
    R = mellor_resistances(r1, 0.0, L, k, 1.0)
    assert R.R5 == np.inf
    # surface held, heat leaves radially only: mean - surface = P (R4 + R6)
    assert P * (R.R4 + R.R6) == pytest.approx(P / (8 * np.pi * k * L), rel=1e-12)


def test_axial_slab_mean_rise_is_P_L_over_12_k_A():
    r1, r2, L, k, P = 0.045, 0.038, 0.055, 2.0, 13.0
    area = np.pi * (r1 ** 2 - r2 ** 2)
    net = ThermalNetwork()
    net.add_boundary('face')
    cyl = add_cylinder(net, 'slab', r1, r2, [L], 1.0, k, 1.0)
    for f in cyl.faces:
        net.add_conductance(f, 'face', 1e12)   # both faces held at the boundary temperature
    net.add_source(cyl.mean[0])
    T = net.steady_state([300.0], [P])
    rise = T[net.index(cyl.mean[0])] - 300.0
    assert rise == pytest.approx(P * L / (12 * k * area), rel=1e-6)


def hollow_cylinder_exact(r1, r2, k, q, T_out, T_in, L):
    """Return the volume-mean temperature and the heat out of each surface, analytically."""
    # T(r) = -q r^2 / (4 k) + C1 ln r + C2 with T(r1) = T_out, T(r2) = T_in
    C1, C2 = np.linalg.solve([[np.log(r1), 1.0], [np.log(r2), 1.0]],
                             [T_out + q * r1 ** 2 / (4 * k), T_in + q * r2 ** 2 / (4 * k)])
    T = lambda r: -q * r ** 2 / (4 * k) + C1 * np.log(r) + C2  # noqa: E731
    mean = quad(lambda r: T(r) * 2 * np.pi * r, r2, r1)[0] / (np.pi * (r1 ** 2 - r2 ** 2))
    dTdr = lambda r: -q * r / (2 * k) + C1 / r  # noqa: E731
    q_out = -k * dTdr(r1) * 2 * np.pi * r1 * L     # leaving through the outer surface
    q_in = k * dTdr(r2) * 2 * np.pi * r2 * L       # leaving through the inner surface
    return mean, q_out, q_in


@pytest.mark.parametrize('T_out, T_in', [(300.0, 300.0), (300.0, 340.0), (350.0, 290.0),
                                         (310.0, 312.0)])
@pytest.mark.parametrize('r1, r2', [(0.05, 0.02), (0.038, 0.0185), (0.018, 0.0175)])
def test_block_reproduces_hollow_cylinder_mean_and_heat_split(r1, r2, T_out, T_in):
    L, k, P = 0.011, 3.0, 40.0
    net = ThermalNetwork()
    net.add_boundary('out')
    net.add_boundary('in')
    cyl = add_cylinder(net, 'c', r1, r2, [L], k, 1.0, 1.0)
    # stiff links pin the surfaces (they add P / 1e13 K, far below RTOL); the heat
    # split is read on the block's own R4 and R5, where it is well conditioned
    net.add_conductance(cyl.outer[0], 'out', 1e13)
    net.add_conductance(cyl.inner[0], 'in', 1e13)
    net.add_source(cyl.mean[0])
    T = net.steady_state([T_out, T_in], [P])
    jr = cyl.mean[0] + '.jr'
    flow_out = net.heat_flow(T, [T_out, T_in], jr, cyl.outer[0])
    flow_in = net.heat_flow(T, [T_out, T_in], jr, cyl.inner[0])
    mean, q_out, q_in = hollow_cylinder_exact(r1, r2, k, P / (np.pi * (r1**2 - r2**2) * L),
                                              T_out, T_in, L)
    assert T[net.index(cyl.mean[0])] == pytest.approx(mean, rel=RTOL)
    scale = P + abs(q_out) + abs(q_in)
    assert abs(flow_out - q_out) < 1e-9 * scale
    assert abs(flow_in - q_in) < 1e-9 * scale


def test_sector_scales_every_conductance_with_its_angular_fraction():
    full = mellor_resistances(0.038, 0.02, 0.011, 0.9, 200.0)
    part = mellor_resistances(0.038, 0.02, 0.011, 0.9, 200.0, angular_fraction=0.55)
    assert np.allclose(np.array(part) * 0.55, np.array(full), rtol=1e-12)


@pytest.mark.parametrize('bad', [{'r_inner_m': 0.06}, {'length_m': -0.1},
                                 {'k_radial_W_mK': 0.0}, {'angular_fraction': 1.5}])
def test_invalid_geometry_is_refused(bad):
    args = {'r_outer_m': 0.05, 'r_inner_m': 0.02, 'length_m': 0.1, 'k_radial_W_mK': 1.0,
            'k_axial_W_mK': 1.0}
    args.update(bad)
    with pytest.raises(ValueError):
        mellor_resistances(**args)
