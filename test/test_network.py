"""Thermal network engine: checks 2 and 3 of docs/model.md, stiffness, energy, errors."""

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.motor import MotorInputs, WetMotor
from wet_eha_thermal.model.network import NetworkError, ThermalNetwork
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.units import C_TO_K


def advected_chain(n_cells, ntu, capacity=0.0):
    """Plug flow past a wall at 0 K: n cells, inlet at 1 K, total NTU = hA / (m_dot c_p)."""
    net = ThermalNetwork()
    net.add_boundary('inlet')
    net.add_boundary('wall')
    cells = [net.add_node(f'oil.s{i + 1}', capacity) for i in range(n_cells)]
    adv = [net.add_advection(u, d) for u, d in zip(['inlet'] + cells[:-1], cells)]
    links = [net.add_conductance(c, 'wall', ntu / n_cells) for c in cells]
    net.set_advection_rates(adv, np.ones(n_cells))   # m_dot c_p = 1 W/K
    return net, cells, links


@pytest.mark.parametrize('ntu', [0.1, 1.0, 3.0])
def test_one_cell_gives_one_over_one_plus_ntu(ntu):
    net, cells, _ = advected_chain(1, ntu)
    T = net.steady_state([1.0, 0.0], [])
    assert T[net.index(cells[-1])] == pytest.approx(1.0 / (1.0 + ntu), rel=1e-12)


@pytest.mark.parametrize('ntu', [0.5, 2.0])
def test_cells_converge_to_plug_flow_exp_minus_ntu(ntu):
    outlet = {}
    for n in (1, 2, 5, 10, 40, 200):
        net, cells, _ = advected_chain(n, ntu)
        outlet[n] = net.steady_state([1.0, 0.0], [])[net.index(cells[-1])]
        # each chain is exactly the upwind formula (1 + NTU/n)^-n
        assert outlet[n] == pytest.approx((1.0 + ntu / n) ** -n, rel=1e-12)
    errors = [abs(outlet[n] - np.exp(-ntu)) for n in (1, 2, 5, 10, 40, 200)]
    assert all(b < a for a, b in zip(errors, errors[1:]))
    # upwind error is first order: about NTU^2 exp(-NTU) / (2 n)
    assert errors[-1] < ntu ** 2 * np.exp(-ntu) / (2 * 200) * 1.05


@pytest.mark.parametrize('dt', [1e-4, 1e-2, 0.37, 1.0])
def test_first_order_node_follows_the_exponential_at_any_step(dt):
    C, R, P, T_amb = 80.0, 0.4, 25.0, 293.15
    net = ThermalNetwork()
    net.add_boundary('ambient')
    net.add_node('m', C)
    net.add_resistance('m', 'ambient', R)
    net.add_source('m')
    x = np.array([T_amb])
    steps = int(round(3.0 / dt)) if dt < 0.1 else 40
    for k in range(1, steps + 1):
        x = net.step(x, dt, [T_amb], [P])
    t = steps * dt
    exact = T_amb + P * R * (1 - np.exp(-t / (R * C)))
    # exact discretisation: only round-off accumulates over the steps
    assert x[0] == pytest.approx(exact, abs=1e-9 * steps + 1e-10)


def stiff_network():
    """Return a thin oil film (ms) next to a heavy housing (hours): stiffness ratio ~1e7."""
    net = ThermalNetwork()
    net.add_boundary('ambient')
    net.add_node('film', 0.01)
    net.add_node('housing', 2000.0)
    net.add_node('surface')                       # algebraic junction
    net.add_conductance('film', 'surface', 20.0)
    net.add_conductance('surface', 'housing', 50.0)
    net.add_conductance('housing', 'ambient', 0.5)
    net.add_source('film')
    return net


@pytest.mark.parametrize('dt', [1e-4, 1e-3, 0.1, 1.0])
def test_stiff_network_matches_an_independent_ode_solver(dt):
    net = stiff_network()
    A, B = net.state_space()
    assert np.linalg.cond(A) > 1e5   # really stiff
    w = np.array([293.15, 30.0])
    x0 = np.array([293.15, 293.15])
    horizon = 2.0
    sol = scipy.integrate.solve_ivp(lambda t, x: A @ x + B @ w, (0, horizon), x0,
                                    method='Radau', rtol=1e-10, atol=1e-10)
    x = x0.copy()
    for _ in range(int(round(horizon / dt))):
        x = net.step(x, dt, w[:1], w[1:])
    assert np.allclose(x, sol.y[:, -1], atol=1e-6)


@pytest.mark.slow
def test_step_mean_gives_exact_energy_balance():
    net = stiff_network()
    x = np.array([293.15, 293.15])
    dt, P = 0.5, 30.0
    C = net.freeze().capacity[net.dynamic]
    stored0 = C @ x
    to_amb = 0.0
    link = 2   # housing -> ambient
    for _ in range(50):
        x_new, x_mean = net.step(x, dt, [293.15], [P], mean=True)
        T_mean = net.temperatures(x_mean, [293.15], [P])
        to_amb += net.link_heat_flows(T_mean, [293.15])[link] * dt
        x = x_new
    stored = C @ x - stored0
    assert stored + to_amb == pytest.approx(P * dt * 50, rel=1e-9)


@pytest.mark.slow
def test_mean_over_a_step_matches_quadrature():
    net = stiff_network()
    A, B = net.state_space()
    w = np.array([300.0, 12.0])
    x0 = np.array([350.0, 310.0])
    dt = 0.3
    _, mean = net.step(x0, dt, w[:1], w[1:], mean=True)
    ref = scipy.integrate.quad_vec(
        lambda t: scipy.linalg.expm(A * t) @ x0
        + scipy.integrate.quad_vec(lambda s: scipy.linalg.expm(A * s) @ B @ w, 0, t)[0],
        0, dt)[0] / dt
    assert np.allclose(mean, ref, rtol=1e-9)


def test_negative_conductances_are_accepted():
    net = ThermalNetwork()
    net.add_boundary('b')
    net.add_node('m', 1.0)
    net.add_node('j')
    net.add_resistance('j', 'm', -0.1)
    net.add_resistance('j', 'b', 0.3)
    net.add_source('m')
    # series resistance 0.2 K/W: 10 W gives 2 K
    assert net.steady_state([0.0], [10.0])[net.index('m')] == pytest.approx(2.0, rel=1e-12)


def test_names_are_looked_up_and_bad_builds_are_refused():
    net = ThermalNetwork()
    net.add_boundary('ambient')
    net.add_node('a.s1', 1.0)
    with pytest.raises(NetworkError, match='twice'):
        net.add_node('a.s1')
    with pytest.raises(NetworkError, match='unknown'):
        net.add_conductance('a.s1', 'nowhere', 1.0)
    with pytest.raises(NetworkError, match='>= 0'):
        net.add_node('neg', -1.0)
    net.add_conductance('a.s1', 'ambient', 1.0)
    net.freeze()
    with pytest.raises(KeyError, match='a.s1'):
        net.index('a.s9')
    with pytest.raises(NetworkError, match='fixed'):
        net.add_node('late')


def test_isolated_algebraic_group_is_reported():
    net = ThermalNetwork()
    net.add_boundary('ambient')
    net.add_node('m', 1.0)
    net.add_conductance('m', 'ambient', 1.0)
    net.add_node('p')
    net.add_node('q')
    net.add_conductance('p', 'q', 1.0)
    with pytest.raises(NetworkError, match='no path'):
        net.discretise(0.1)


def stepped_motor(steps: int):
    """Return the reference motor after ``steps`` 20 ms steps from 40 degC, and its inputs."""
    cfg = load_config()
    motor = WetMotor(cfg.motor, get_oil(cfg.fluid.grade))
    motor.initialise(C_TO_K + 40.0)
    u = MotorInputs(current_sq_mean_A2=225.0, speed_rad_s=800.0, oil_inlet_K=C_TO_K + 40.0,
                    oil_flow_m3_s=1e-5, ambient_K=C_TO_K + 20.0)
    for _ in range(steps):
        motor.step(0.02, u)
    return motor, u


def test_algebraic_nodes_from_the_maps_nonzeros_agree_with_the_dense_maps_to_round_off():
    # the step takes the algebraic nodes' map by its nonzeros (out_x is about 9 % full):
    # the same sums in another order, so they agree within the round-off of a sum of n
    # terms either way, 2 gamma_n sum |terms| (Higham, Accuracy and Stability, 3.1)
    motor, u = stepped_motor(50)        # coefficients, losses and a state with gradients
    net, Tb, P = motor.net, motor.boundaries(u), motor.power_W
    a, out_x = net.algebraic_map()
    out_w = net._reduce()[5]
    w = net.inputs(Tb, P)
    x_new, T_end, _ = net.step_temperatures(motor.x, 0.02, Tb, P)
    dense = out_x @ x_new + out_w @ w
    n = out_x.shape[1] + out_w.shape[1] + 1
    gamma = n * np.finfo(float).eps / (1.0 - n * np.finfo(float).eps)
    bound = 2.0 * gamma * (np.abs(out_x) @ np.abs(x_new) + np.abs(out_w) @ np.abs(w))
    assert a.size > 300 and np.count_nonzero(out_x) < 0.2 * out_x.size
    assert np.all(np.abs(T_end[a] - dense) <= bound)
    assert np.array_equal(T_end[net.dynamic], x_new)


def test_the_reductions_blocks_are_the_assembled_matrices_to_the_bit():
    # the reduction sums only the blocks it reads (K's state rows, the band of its algebraic
    # block, the algebraic solve's right-hand side), each entry in matrices()' order: the
    # same sums, so the same bits as the dense K, G_b and E sliced, at any coefficients
    motor, _ = stepped_motor(1)
    net = motor.net
    rng = np.random.default_rng(3)
    g = net.conductance
    net.set_conductances(slice(None), g * rng.uniform(0.5, 2.0, g.size))
    net.set_advection_rates(slice(None), rng.uniform(0.0, 5.0, net.advection_rate.size))
    m, (order, half, entries, places) = net.dynamic.size, net._band
    K, Gb, E = net.matrices(reduced_order=True)
    W = np.hstack([Gb, E])
    band = np.zeros((3 * half + 1, net._a.size))
    band[places] = K[entries]
    K_dd, K_da, W_d, band_blocks, rhs = net._reduction_matrices()
    for got, want in ((K_dd, K[:m, :m]), (K_da, K[:m, m:]), (W_d, W[:m]), (band_blocks, band),
                      (rhs, np.hstack([K[m:, :m], W[m:]])[order])):
        assert got.shape == want.shape and got.tobytes() == np.ascontiguousarray(want).tobytes()
