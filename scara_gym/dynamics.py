"""The C11 model as pure functions of (state, input, params).

Plain float arithmetic on arrays, compiled with numba (``cache=True`` keeps the
machine code on disk). Every function is also callable from Python, which is how
the tests check them one by one. ``p`` is ``ScaraParams.to_array()``; indices
come from :mod:`scara_gym.layout`. Equation numbers are those of the seed paper.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from scara_gym.layout import (
    A_D, A_GEAR, A_IMAX, A_KT, A_L, A_P, A_R, A_UMAX, A_UWIDE, ACC, AXIS0, AXIS_STRIDE,
    C_CONTROL, C_DEC, C_FORM, C_WIDEN, CONTROL_PD, D_CRIT, DEC, FORM_EXPLICIT, GRAVITY,
    H_OBS, L1, L2, M3L, M_CRITICAL, MA33, TARGET, TH1, TH2, TH3, X_OBS,
)

JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
# for the functions of the integrator's inner loop: a compiled call with array arguments
# costs reference counting on each array, more than the arithmetic of these bodies
JIT_INLINE = dict(JIT, inline="always")


@njit(**JIT)
def mass_matrix(q2, p):
    """M(q) of eq. 2-6 (3x3)."""
    c = math.cos(q2)
    m = np.zeros((3, 3))
    m[0, 0] = p[TH1] + 2.0 * p[TH2] * c + p[TH3]
    m[0, 1] = p[TH2] * c + p[TH3]
    m[1, 0] = m[0, 1]
    m[1, 1] = p[TH3]
    m[2, 2] = p[MA33]
    return m


@njit(**JIT)
def bias_vector(q2, v1, v2, t1, t2, t3, p):
    """b(q, q', T) of eq. 7-9: joint torques plus Coriolis/centrifugal terms and gravity."""
    s = math.sin(q2)
    b = np.empty(3)
    b[0] = t1 + p[TH2] * (2.0 * v1 * v2 + v2 * v2) * s
    b[1] = t2 - p[TH2] * v1 * v1 * s
    b[2] = t3 - p[M3L] * p[GRAVITY]
    return b


@njit(**JIT)
def determinant(q2, p):
    """det of the 2x2 block: th1 th3 - th2^2 cos^2 q2 (the seed's eq. 12 drops the square)."""
    c = math.cos(q2)
    return p[TH1] * p[TH3] - p[TH2] * p[TH2] * c * c


@njit(**JIT)
def accelerations_explicit(q2, v1, v2, t1, t2, t3, p):
    """q'' = M^-1 b with the analytic inverse of the 2x2 block (explicit form)."""
    c = math.cos(q2)
    s = math.sin(q2)
    m11 = p[TH1] + 2.0 * p[TH2] * c + p[TH3]
    m12 = p[TH2] * c + p[TH3]
    m22 = p[TH3]
    b1 = t1 + p[TH2] * (2.0 * v1 * v2 + v2 * v2) * s
    b2 = t2 - p[TH2] * v1 * v1 * s
    det = p[TH1] * p[TH3] - p[TH2] * p[TH2] * c * c
    a1 = (m22 * b1 - m12 * b2) / det
    a2 = (m11 * b2 - m12 * b1) / det
    a3 = (t3 - p[M3L] * p[GRAVITY]) / p[MA33]
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
    """q'' from M q'' = b by a linear solve (implicit form)."""
    acc = solve_linear(mass_matrix(q2, p), bias_vector(q2, v1, v2, t1, t2, t3, p))
    return acc[0], acc[1], acc[2]


@njit(**JIT)
def accelerations(q2, v1, v2, t1, t2, t3, p, form):
    if form == FORM_EXPLICIT:
        return accelerations_explicit(q2, v1, v2, t1, t2, t3, p)
    return accelerations_implicit(q2, v1, v2, t1, t2, t3, p)


@njit(**JIT)
def kinetic_energy(q2, v1, v2, v3, p):
    """1/2 q'^T M q' [J]."""
    c = math.cos(q2)
    m11 = p[TH1] + 2.0 * p[TH2] * c + p[TH3]
    m12 = p[TH2] * c + p[TH3]
    return 0.5 * (m11 * v1 * v1 + 2.0 * m12 * v1 * v2 + p[TH3] * v2 * v2 + p[MA33] * v3 * v3)


@njit(**JIT)
def tip_position(q1, q2, q3, p):
    """Tool tip (x, y, z) [m]."""
    return (p[L1] * math.cos(q1) + p[L2] * math.cos(q1 + q2),
            p[L1] * math.sin(q1) + p[L2] * math.sin(q1 + q2),
            q3)


@njit(**JIT)
def axis_param(p, axis, offset):
    return p[AXIS0 + AXIS_STRIDE * axis + offset]


@njit(**JIT)
def voltage_limit(p, axis, widened):
    """Umax_i, or Umax_wide_i where the obstacle rule widens the bound."""
    return axis_param(p, axis, A_UWIDE) if widened else axis_param(p, axis, A_UMAX)


@njit(**JIT)
def pd_voltage(setpoint, q, v, p, axis, limit):
    """U_i = sat(P_i (q^_i - q_i) - D_i q_i', +-limit) (eq. 15-16)."""
    u = axis_param(p, axis, A_P) * (setpoint - q) - axis_param(p, axis, A_D) * v
    return min(max(u, -limit), limit)


@njit(**JIT)
def free_current_rate(voltage, v, current, p, axis):
    """I_i' = (U_i - kT_i u_i q_i' - R_i I_i) / L_i (eq. 13, back-EMF from the joint rate)."""
    emf = axis_param(p, axis, A_KT) * axis_param(p, axis, A_GEAR) * v
    return (voltage - emf - axis_param(p, axis, A_R) * current) / axis_param(p, axis, A_L)


@njit(**JIT)
def joint_torque(current, p, axis):
    """T_i = kT_i u_i I_i [N m, N for the prismatic axis]."""
    return axis_param(p, axis, A_KT) * axis_param(p, axis, A_GEAR) * current


@njit(**JIT)
def is_critical_state(x, p):
    """The seed's critical condition: |x_tip - x_obs| < d_crit and q3 < h_obs."""
    xt, _, _ = tip_position(x[0], x[1], x[2], p)
    return abs(xt - p[X_OBS]) < p[D_CRIT] and x[2] < p[H_OBS]


@njit(**JIT)
def target_error(x, p):
    """max_i |q_i - q^_i| (mixed units: the benchmark's own acc test)."""
    return max(abs(x[0] - p[TARGET]), abs(x[1] - p[TARGET + 1]), abs(x[2] - p[TARGET + 2]))


@njit(**JIT)
def is_inside_target(x, p):
    return target_error(x, p) < p[ACC]


@njit(**JIT_INLINE)
def voltages(x, p, command, config, modes, out):
    """Armature voltages for the configured control: PD law or commanded fraction of the limit."""
    widened = modes[M_CRITICAL] == 1 and config[C_WIDEN] == 1
    for axis in range(3):
        limit = voltage_limit(p, axis, widened)
        if config[C_CONTROL] == CONTROL_PD:
            out[axis] = pd_voltage(command[axis], x[axis], x[3 + axis], p, axis, limit)
        else:
            out[axis] = command[axis] * limit
    return out


@njit(**JIT_INLINE)
def derivative(x, p, command, config, modes, out, volts):
    """x' of the model (9 states and the energy accumulator) in the current hybrid mode.

    A held current (modes[i] = +-1) has I_i' = 0. While critical with the dec rule,
    only the kinematic rows are scaled (q1' = dec v1, q2' = dec v2); the mechanics,
    back-EMF and PD damping keep using the rate states v.

    The hot loop of every simulation: one pass over the axes with the voltage law,
    eq. 13 and T_i = kT_i u_i I_i written out (the same arithmetic as pd_voltage,
    free_current_rate and joint_torque, which the tests compare it with), then the
    mechanics in the configured form.
    """
    widened = modes[M_CRITICAL] == 1 and config[C_WIDEN] == 1
    pd = config[C_CONTROL] == CONTROL_PD
    power = 0.0
    t1 = t2 = t3 = 0.0
    for axis in range(3):
        base = AXIS0 + AXIS_STRIDE * axis
        limit = p[base + A_UWIDE] if widened else p[base + A_UMAX]
        if pd:
            u = p[base + A_P] * (command[axis] - x[axis]) - p[base + A_D] * x[3 + axis]
            u = min(max(u, -limit), limit)
        else:
            u = command[axis] * limit
        volts[axis] = u
        ku = p[base + A_KT] * p[base + A_GEAR]
        current = x[6 + axis]
        if modes[axis] != 0:
            out[6 + axis] = 0.0
        else:
            out[6 + axis] = (u - ku * x[3 + axis] - p[base + A_R] * current) / p[base + A_L]
        power += u * current
        if axis == 0:
            t1 = ku * current
        elif axis == 1:
            t2 = ku * current
        else:
            t3 = ku * current
    dec = p[DEC] if (modes[M_CRITICAL] == 1 and config[C_DEC] == 1) else 1.0
    if config[C_FORM] == FORM_EXPLICIT:
        a1, a2, a3 = accelerations_explicit(x[1], x[3], x[4], t1, t2, t3, p)
    else:
        a1, a2, a3 = accelerations_implicit(x[1], x[3], x[4], t1, t2, t3, p)
    out[0] = dec * x[3]
    out[1] = dec * x[4]
    out[2] = x[5]
    out[3] = a1
    out[4] = a2
    out[5] = a3
    out[9] = power
    return out


@njit(**JIT)
def current_limit(p, axis):
    return axis_param(p, axis, A_IMAX)
