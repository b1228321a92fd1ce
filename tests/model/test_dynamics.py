"""Analytic checks of the model functions, one equation at a time."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from scara_gym.benchmark.tasks import sample_point_to_point
from scara_gym.model import records as R
from scara_gym.model.dynamics import (
    accelerations,
    accelerations_explicit,
    accelerations_implicit,
    bias_vector,
    derivative,
    determinant,
    free_current_rate,
    joint_torque,
    kinetic_energy,
    mass_matrix,
    pd_voltage,
    tip_position,
    voltage_limit,
)
from scara_gym.model.params import DEFAULT_PARAMS

P = DEFAULT_PARAMS.to_record()


def make_config(**fields):
    config = np.zeros(1, dtype=R.CONFIG)[0]
    for name, value in fields.items():
        config[name] = value
    return config


def make_robot(command, hold=(0, 0, 0), critical=0):
    robot = np.zeros(1, dtype=R.ROBOT)[0]
    robot["command"], robot["hold"], robot["critical"] = command, hold, critical
    return robot


def test_mass_matrix_is_symmetric_positive_definite_with_the_correct_determinant():
    for q2 in np.linspace(-math.pi, math.pi, 37):
        m = mass_matrix(q2, P)
        assert np.allclose(m, m.T)
        assert np.all(np.linalg.eigvalsh(m) > 0)
        assert determinant(q2, P) == pytest.approx(np.linalg.det(m[:2, :2]), rel=1e-12)
        # the seed's eq. 12 (th1 th3 - th2^2 cos q2) is not the determinant
    assert determinant(1.0, P) != pytest.approx(P["theta1"] * P["theta3"] - P["theta2"] ** 2 * math.cos(1.0))


def test_explicit_and_implicit_accelerations_equal_a_numpy_solve():
    rng = np.random.default_rng(1)
    for _ in range(200):
        q2, v1, v2 = rng.uniform(-4, 4, 3)
        torques = rng.uniform(-300, 300, 3)
        expected = np.linalg.solve(mass_matrix(q2, P), bias_vector(q2, v1, v2, *torques, P))
        assert np.allclose(accelerations_explicit(q2, v1, v2, *torques, P), expected, rtol=1e-12, atol=1e-12)
        assert np.allclose(accelerations_implicit(q2, v1, v2, *torques, P), expected, rtol=1e-12, atol=1e-12)


def test_bias_vector_terms():
    q2, v1, v2 = 0.7, 1.3, -2.1
    b = bias_vector(q2, v1, v2, 1.0, 2.0, 3.0, P)
    assert b[0] == pytest.approx(1.0 + 0.72 * (2 * v1 * v2 + v2**2) * math.sin(q2))
    assert b[1] == pytest.approx(2.0 - 0.72 * v1**2 * math.sin(q2))
    assert b[2] == pytest.approx(3.0 - 0.5 * 9.81)


def test_tip_kinematics():
    assert tip_position(0.0, 0.0, 0.1, P) == pytest.approx((0.7, 0.0, 0.1))
    assert tip_position(math.pi / 2, 0.0, 0.0, P) == pytest.approx((0.0, 0.7, 0.0), abs=1e-15)
    assert tip_position(0.0, math.pi / 2, 0.0, P) == pytest.approx((0.4, 0.3, 0.0))
    x, y, _ = tip_position(2.0, 2.0, 0.3, P)
    assert math.hypot(x, y) == pytest.approx(math.sqrt(0.4**2 + 0.3**2 + 2 * 0.12 * math.cos(2.0)))


def test_pd_law_saturates_at_the_given_limit():
    assert pd_voltage(2.0, 0.0, 0.0, P, 0, 100.0) == 100.0
    assert pd_voltage(-2.0, 0.0, 0.0, P, 1, 75.0) == -75.0
    assert pd_voltage(0.3, 0.29, 0.1, P, 2, 90.0) == pytest.approx(5000 * 0.01 - 10 * 0.1)


def test_current_equation_uses_the_joint_rate_for_the_back_emf():
    rate = free_current_rate(50.0, 0.2, 1.0, P, 0)
    assert rate == pytest.approx((50.0 - 0.4 * 130 * 0.2 - 3.9 * 1.0) / 0.0073)


@pytest.mark.parametrize("form", [R.FORM_EXPLICIT, R.FORM_IMPLICIT])
@pytest.mark.parametrize("control", [R.CONTROL_PD, R.CONTROL_VOLTAGE])
def test_derivative_is_the_composition_of_the_model_equations(form, control):
    """derivative writes the voltage law, eq. 13 and T = kT u I out for speed; it must stay
    the composition of pd_voltage, free_current_rate, joint_torque and accelerations."""
    rng = np.random.default_rng(7)
    config = make_config(form=form, control=control, widen=True)
    for _ in range(50):
        x = np.concatenate([rng.uniform(-3, 3, 2), rng.uniform(0, 0.4, 1), rng.uniform(-5, 5, 3),
                            rng.uniform(-3, 3, 3), [0.0]])
        command = rng.uniform(-1, 1, 3) if control == R.CONTROL_VOLTAGE else rng.uniform(-3, 3, 3)
        hold = rng.integers(-1, 2, 3)  # held and free currents
        robot = make_robot(command, hold, critical=rng.integers(0, 2))
        out, volts = np.empty(10), np.empty(3)
        derivative(x, robot, P, config, out, volts)
        limits = [voltage_limit(P, i, robot["critical"] == 1) for i in range(3)]
        u = [pd_voltage(command[i], x[i], x[3 + i], P, i, limits[i]) if control == R.CONTROL_PD
             else command[i] * limits[i] for i in range(3)]
        torques = [joint_torque(x[6 + i], P, i) for i in range(3)]
        expected = [x[3], x[4], x[5], *accelerations(x[1], x[3], x[4], *torques, P, form)]
        expected += [0.0 if hold[i] else free_current_rate(u[i], x[3 + i], x[6 + i], P, i) for i in range(3)]
        expected.append(sum(u[i] * x[6 + i] for i in range(3)))
        assert np.array_equal(volts, u)
        assert np.allclose(out, expected, rtol=1e-13, atol=0.0)


def test_dec_rule_scales_only_the_kinematic_rows():
    x = np.array([0.3, 0.5, 0.05, 2.0, -3.0, 0.1, 1.0, -0.5, 0.2, 0.0])
    config = make_config(decelerate=True)
    robot = make_robot([2.0, 2.0, 0.3])
    plain, volts = np.empty(10), np.empty(3)
    derivative(x, robot, P, config, plain, volts)
    robot["critical"] = 1
    slowed = np.empty(10)
    derivative(x, robot, P, config, slowed, volts)
    assert slowed[0] == pytest.approx(5e-5 * 2.0) and slowed[1] == pytest.approx(5e-5 * -3.0)
    assert np.array_equal(slowed[2:], plain[2:])


def test_gravity_offset_of_axis_3_under_pure_p_action():
    params = DEFAULT_PARAMS.replace({"axes.2.d_gain": 0.0})
    x = sample_point_to_point([40.0], params)[0]
    axis = params.axes[2]
    expected = params.arm.load_mass * params.arm.gravity * axis.resistance / (
        axis.torque_constant * axis.gear_ratio * axis.p_gain)
    assert params.task.target[2] - x[2] == pytest.approx(expected, rel=1e-6)
    assert expected > 1e-6  # the offset is real, not a rounding residue


@pytest.mark.parametrize("accelerations", [accelerations_explicit, accelerations_implicit])
def test_free_motion_conserves_the_kinetic_energy_of_axes_1_and_2(accelerations):
    def rhs(_t, y):
        a1, a2, _ = accelerations(y[1], y[2], y[3], 0.0, 0.0, P["load_mass"] * P["gravity"], P)
        return [y[2], y[3], a1, a2]

    y0 = [0.0, 0.4, 3.0, -5.0]
    sol = solve_ivp(rhs, (0.0, 20.0), y0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    energies = [kinetic_energy(y[1], y[2], y[3], 0.0, P) for y in sol.sol(np.linspace(0, 20, 400)).T]
    assert max(abs(e / energies[0] - 1) for e in energies) < 1e-9
    # the test has teeth: without the Coriolis terms (b = 0) the rates stay constant while
    # M(q2) changes, and the energy drifts by far more than the bound above
    drifted = kinetic_energy(y0[1] + y0[3] * 0.3, y0[2], y0[3], 0.0, P)
    assert abs(drifted / energies[0] - 1) > 1e-2


def test_electrical_energy_balances_losses_and_stored_energy():
    """Below the current limits: int U.I dt = int R I^2 dt + 1/2 L I^2 + 1/2 q'^T M q' + m3L g q3."""
    from scara_gym.model.simulator import Simulator, start_state

    sim = Simulator(DEFAULT_PARAMS, stop=(), rtol=1e-11, atol=1e-13, max_step=1e-3)
    sim.reset(start_state(DEFAULT_PARAMS), command=[0.005, -0.004, 0.002])
    sim.advance(0.3)
    run = sim.trajectory(0)
    assert run.events == []  # no current limit reached: the power balance is exact
    from scipy.integrate import cumulative_trapezoid

    axes = DEFAULT_PARAMS.axes
    resistive = sum(cumulative_trapezoid(a.resistance * run.currents[:, i] ** 2, run.t, initial=0.0)
                    for i, a in enumerate(axes))
    magnetic = sum(0.5 * a.inductance * run.currents[:, i] ** 2 for i, a in enumerate(axes))
    kinetic = np.array([kinetic_energy(x[1], x[3], x[4], x[5], P) for x in run.x])
    potential = 0.5 * 9.81 * run.q[:, 2]
    stored = resistive + magnetic + kinetic + potential
    # the trapezoid rule over the integrator's steps bounds the agreement, not the model
    assert np.abs(run.energy - stored).max() < 1e-5 * run.energy[-1]
    assert kinetic.max() > 0.05 * run.energy[-1]  # the balance involves the mechanics, not only losses


def test_the_written_out_implicit_solve_gives_the_bits_of_the_linear_solve():
    """accelerations_implicit repeats solve_linear's elimination on scalars (no allocation, for
    the GPU): the same operations, so the same bits, pivoting included."""
    from scara_gym.model.dynamics import solve_linear

    rng = np.random.default_rng(0)
    for _ in range(2000):
        q2, v1, v2 = rng.uniform(-7.0, 7.0), rng.normal(0.0, 5.0), rng.normal(0.0, 5.0)
        torques = rng.normal(0.0, 50.0, 3)
        expected = solve_linear(mass_matrix(q2, P), bias_vector(q2, v1, v2, *torques, P))
        assert np.array_equal(np.array(accelerations_implicit(q2, v1, v2, *torques, P)), expected)
