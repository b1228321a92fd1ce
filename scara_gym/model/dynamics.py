"""The C11 model as pure functions of (state, input, params).

Plain float arithmetic, compiled with numba (``cache=True`` keeps the machine code on
disk). Every function is also callable from Python, which is how the tests check them
one by one. ``p`` is a ``PARAMS`` record (``ScaraParams.to_record()``), ``robot`` a
``ROBOT`` record and ``config`` a ``CONFIG`` record of `scara_gym.model.records`;
the state vector ``x`` is addressed through the offsets of ``STATE``. Equation numbers
are those of the seed paper.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from scara_gym.model.compilation import JIT, JIT_INLINE
from scara_gym.model.records import CONTROL_PD, CURRENT, ENERGY, FORM_EXPLICIT, RATE, Q


@njit(**JIT)
def mass_matrix(q2, p):
    """M(q) of eq. 2-6 (3x3)."""
    c = math.cos(q2)
    m = np.zeros((3, 3))
    m[0, 0] = p.theta1 + 2.0 * p.theta2 * c + p.theta3
    m[0, 1] = p.theta2 * c + p.theta3
    m[1, 0] = m[0, 1]
    m[1, 1] = p.theta3
    m[2, 2] = p.vertical_mass
    return m


@njit(**JIT)
def bias_vector(q2, v1, v2, t1, t2, t3, p):
    """b(q, q', T) of eq. 7-9: joint torques plus Coriolis/centrifugal terms and gravity."""
    s = math.sin(q2)
    b = np.empty(3)
    b[0] = t1 + p.theta2 * (2.0 * v1 * v2 + v2 * v2) * s
    b[1] = t2 - p.theta2 * v1 * v1 * s
    b[2] = t3 - p.load_mass * p.gravity
    return b


@njit(**JIT)
def determinant(q2, p):
    """det of the 2x2 block: th1 th3 - th2^2 cos^2 q2 (the seed's eq. 12 drops the square)."""
    c = math.cos(q2)
    return p.theta1 * p.theta3 - p.theta2 * p.theta2 * c * c


@njit(**JIT)
def accelerations_explicit(q2, v1, v2, t1, t2, t3, p):
    """q'' = M^-1 b with the analytic inverse of the 2x2 block (explicit form)."""
    c = math.cos(q2)
    s = math.sin(q2)
    m11 = p.theta1 + 2.0 * p.theta2 * c + p.theta3
    m12 = p.theta2 * c + p.theta3
    m22 = p.theta3
    b1 = t1 + p.theta2 * (2.0 * v1 * v2 + v2 * v2) * s
    b2 = t2 - p.theta2 * v1 * v1 * s
    det = p.theta1 * p.theta3 - p.theta2 * p.theta2 * c * c
    a1 = (m22 * b1 - m12 * b2) / det
    a2 = (m11 * b2 - m12 * b1) / det
    a3 = (t3 - p.load_mass * p.gravity) / p.vertical_mass
    return a1, a2, a3


@njit(**JIT)
def solve_linear(a, b):
    """Gaussian elimination with partial pivoting (the implicit form's solve per evaluation)."""
    n = b.shape[0]
    a = a.copy()
    x = b.copy()
    for k in range(n):
        pivot = k
        for r in range(k + 1, n):
            if abs(a[r, k]) > abs(a[pivot, k]):
                pivot = r
        if pivot != k:
            for col in range(n):
                a[k, col], a[pivot, col] = a[pivot, col], a[k, col]
            x[k], x[pivot] = x[pivot], x[k]
        for r in range(k + 1, n):
            factor = a[r, k] / a[k, k]
            for col in range(k, n):
                a[r, col] -= factor * a[k, col]
            x[r] -= factor * x[k]
    for k in range(n - 1, -1, -1):
        total = x[k]
        for col in range(k + 1, n):
            total -= a[k, col] * x[col]
        x[k] = total / a[k, k]
    return x


@njit(**JIT)
def accelerations_implicit(q2, v1, v2, t1, t2, t3, p):
    """q'' from M q'' = b by a linear solve (implicit form): solve_linear(mass_matrix, bias_vector)
    written out on scalars, every operation of the elimination kept (those on M's zero entries
    too), so that it gives the same bits and allocates nothing (a GPU device function).
    """
    c = math.cos(q2)
    s = math.sin(q2)
    a00, a01, a02 = p.theta1 + 2.0 * p.theta2 * c + p.theta3, p.theta2 * c + p.theta3, 0.0
    a10, a11, a12 = a01, p.theta3, 0.0
    a20, a21, a22 = 0.0, 0.0, p.vertical_mass
    x0 = t1 + p.theta2 * (2.0 * v1 * v2 + v2 * v2) * s
    x1 = t2 - p.theta2 * v1 * v1 * s
    x2 = t3 - p.load_mass * p.gravity
    if abs(a10) > abs(a00):  # partial pivoting; row 2 (a20 = 0) never wins column 0
        a00, a01, a02, a10, a11, a12 = a10, a11, a12, a00, a01, a02
        x0, x1 = x1, x0
    factor = a10 / a00
    a10, a11, a12 = a10 - factor * a00, a11 - factor * a01, a12 - factor * a02
    x1 -= factor * x0
    factor = a20 / a00
    a20, a21, a22 = a20 - factor * a00, a21 - factor * a01, a22 - factor * a02
    x2 -= factor * x0
    if abs(a21) > abs(a11):
        a11, a12, a21, a22 = a21, a22, a11, a12
        x1, x2 = x2, x1
    factor = a21 / a11
    a21, a22 = a21 - factor * a11, a22 - factor * a12
    x2 -= factor * x1
    x2 = x2 / a22
    x1 = (x1 - a12 * x2) / a11
    x0 = ((x0 - a01 * x1) - a02 * x2) / a00
    return x0, x1, x2


@njit(**JIT)
def accelerations(q2, v1, v2, t1, t2, t3, p, form):
    if form == FORM_EXPLICIT:
        return accelerations_explicit(q2, v1, v2, t1, t2, t3, p)
    return accelerations_implicit(q2, v1, v2, t1, t2, t3, p)


@njit(**JIT)
def kinetic_energy(q2, v1, v2, v3, p):
    """1/2 q'^T M q' [J]."""
    c = math.cos(q2)
    m11 = p.theta1 + 2.0 * p.theta2 * c + p.theta3
    m12 = p.theta2 * c + p.theta3
    return 0.5 * (m11 * v1 * v1 + 2.0 * m12 * v1 * v2 + p.theta3 * v2 * v2 + p.vertical_mass * v3 * v3)


@njit(**JIT)
def elbow_position(q1, p):
    """End of link 1 (x, y) [m]."""
    return p.link1_length * math.cos(q1), p.link1_length * math.sin(q1)


@njit(**JIT)
def tip_position(q1, q2, q3, p):
    """Tool tip (x, y, z) [m]: the forward kinematics every part of the package uses."""
    elbow_x, elbow_y = elbow_position(q1, p)
    return elbow_x + p.link2_length * math.cos(q1 + q2), elbow_y + p.link2_length * math.sin(q1 + q2), q3


@njit(**JIT)
def tip_positions(q, p):
    """tip_position for joint positions q of shape (n, 3) -> (n, 3) [m]."""
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = tip_position(q[i, 0], q[i, 1], q[i, 2], p)
    return out


@njit(**JIT)
def voltage_limit(p, axis, widened):
    """Umax_i, or Umax_wide_i where the obstacle rule widens the bound."""
    return p.wide_voltage_limit[axis] if widened else p.voltage_limit[axis]


@njit(**JIT_INLINE)
def pd_unsaturated(setpoint, q, v, p, axis):
    """P_i (q^_i - q_i) - D_i q_i': the PD law of eq. 15 before its saturation."""
    return p.p_gain[axis] * (setpoint - q) - p.d_gain[axis] * v


@njit(**JIT)
def pd_voltage(setpoint, q, v, p, axis, limit):
    """U_i = sat(P_i (q^_i - q_i) - D_i q_i', +-limit) (eq. 15-16)."""
    return min(max(pd_unsaturated(setpoint, q, v, p, axis), -limit), limit)


@njit(**JIT)
def free_current_rate(voltage, v, current, p, axis):
    """I_i' = (U_i - kT_i u_i q_i' - R_i I_i) / L_i (eq. 13, back-EMF from the joint rate)."""
    emf = p.torque_constant[axis] * p.gear_ratio[axis] * v
    return (voltage - emf - p.resistance[axis] * current) / p.inductance[axis]


@njit(**JIT)
def joint_torque(current, p, axis):
    """T_i = kT_i u_i I_i [N m, N for the prismatic axis]."""
    return p.torque_constant[axis] * p.gear_ratio[axis] * current


@njit(**JIT)
def is_critical_state(x, p):
    """The seed's critical condition: |x_tip - x_obs| < d_crit and q3 < h_obs."""
    xt, _, _ = tip_position(x[Q], x[Q + 1], x[Q + 2], p)
    return abs(xt - p.wall_x) < p.critical_distance and x[Q + 2] < p.wall_height


@njit(**JIT)
def target_error(x, p):
    """max_i |q_i - q^_i| (mixed units: the benchmark's own acc test)."""
    return max(abs(x[Q] - p.target[0]), abs(x[Q + 1] - p.target[1]), abs(x[Q + 2] - p.target[2]))


@njit(**JIT)
def is_inside_target(x, p):
    return target_error(x, p) < p.accuracy


@njit(**JIT_INLINE)
def is_widened(robot, config):
    """The voltage limit is Umax_wide: critical, with the obstacle rule's widening on."""
    return robot.critical == 1 and config.widen


@njit(**JIT_INLINE)
def pd_linear_voltage(robot, x, p, axis):
    """pd_unsaturated for the robot's set-point and state."""
    return pd_unsaturated(robot.command[axis], x[Q + axis], x[RATE + axis], p, axis)


@njit(**JIT_INLINE)
def mode_voltage(x, robot, p, config, axis, limit):
    """U_i in the robot's hybrid mode. With exact_switches the PD law's saturation is a
    located mode (robot.saturation), so that the right-hand side is smooth between
    switches; without, the law is clipped at every evaluation (a kink inside steps).
    """
    if config.control != CONTROL_PD:
        return robot.command[axis] * limit
    u = pd_linear_voltage(robot, x, p, axis)
    if config.exact_switches:
        s = robot.saturation[axis]
        return u if s == 0 else s * limit
    return min(max(u, -limit), limit)


@njit(**JIT_INLINE)
def voltages(x, robot, p, config, out):
    """Armature voltages in the robot's mode: PD law or commanded fraction of the limit."""
    widened = is_widened(robot, config)
    for axis in range(3):
        out[axis] = mode_voltage(x, robot, p, config, axis, voltage_limit(p, axis, widened))
    return out


@njit(**JIT_INLINE)
def applied_voltages(x, robot, p, config, out):
    """voltages() as reported: within +-limit also where a located saturation switch lies
    a rounding error away (the mode's linear law may then exceed the limit by ~1e-9 V).
    """
    widened = is_widened(robot, config)
    for axis in range(3):
        limit = voltage_limit(p, axis, widened)
        out[axis] = min(max(mode_voltage(x, robot, p, config, axis, limit), -limit), limit)
    return out


@njit(**JIT)
def settle_saturation(x, robot, p, config):
    """The PD saturation modes the state implies (exact_switches; else all linear): at the
    start of every call, since a new set-point moves the law, and after every event.
    """
    exact_pd = config.exact_switches and config.control == CONTROL_PD
    widened = is_widened(robot, config)
    for axis in range(3):
        mode = 0
        if exact_pd:
            limit = voltage_limit(p, axis, widened)
            u = pd_linear_voltage(robot, x, p, axis)
            mode = 1 if u > limit else (-1 if u < -limit else 0)
        robot.saturation[axis] = mode


@njit(**JIT_INLINE)
def derivative(x, robot, p, config, out, volts):
    """x' of the model (9 states and the energy accumulator) in the robot's hybrid mode.

    A held current (robot.hold[i] = +-1) has I_i' = 0. While critical with the dec rule,
    only the kinematic rows are scaled (q1' = dec v1, q2' = dec v2); the mechanics,
    back-EMF and PD damping keep using the rate states v.

    The hot loop of every simulation: one pass over the axes with the voltage law
    (mode_voltage), eq. 13 and T_i = kT_i u_i I_i written out (the same arithmetic as pd_voltage,
    free_current_rate and joint_torque, which the tests compare it with), then the
    mechanics in the configured form.
    """
    widened = is_widened(robot, config)
    pd = config.control == CONTROL_PD
    exact = config.exact_switches
    power = 0.0
    t1 = t2 = t3 = 0.0
    for axis in range(3):
        limit = p.wide_voltage_limit[axis] if widened else p.voltage_limit[axis]
        if pd:
            u = p.p_gain[axis] * (robot.command[axis] - x[Q + axis]) - p.d_gain[axis] * x[RATE + axis]
            if not exact:
                u = min(max(u, -limit), limit)
            elif robot.saturation[axis] != 0:
                u = robot.saturation[axis] * limit
        else:
            u = robot.command[axis] * limit
        volts[axis] = u
        ku = p.torque_constant[axis] * p.gear_ratio[axis]
        current = x[CURRENT + axis]
        if robot.hold[axis] != 0:
            out[CURRENT + axis] = 0.0
        else:
            out[CURRENT + axis] = (u - ku * x[RATE + axis] - p.resistance[axis] * current) / p.inductance[axis]
        power += u * current
        if axis == 0:
            t1 = ku * current
        elif axis == 1:
            t2 = ku * current
        else:
            t3 = ku * current
    dec = p.dec if (robot.critical == 1 and config.decelerate) else 1.0
    if config.form == FORM_EXPLICIT:
        a1, a2, a3 = accelerations_explicit(x[Q + 1], x[RATE], x[RATE + 1], t1, t2, t3, p)
    else:
        a1, a2, a3 = accelerations_implicit(x[Q + 1], x[RATE], x[RATE + 1], t1, t2, t3, p)
    out[Q] = dec * x[RATE]
    out[Q + 1] = dec * x[RATE + 1]
    out[Q + 2] = x[RATE + 2]
    out[RATE] = a1
    out[RATE + 1] = a2
    out[RATE + 2] = a3
    out[ENERGY] = power
    return out
