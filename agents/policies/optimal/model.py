"""The C11 model in CasADi for the minimum-time problems: free currents, no hold (the problems
keep the currents inside their limits by their constraints)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from scara_gym import DEFAULT_PARAMS, ScaraParams


def param_values(params: ScaraParams):
    """The PARAMS record's fields as attributes (floats and arrays)."""
    record = params.to_record()
    return SimpleNamespace(**{name: (float(record[name]) if np.ndim(record[name]) == 0 else np.array(record[name]))
                              for name in record.dtype.names})


def casadi_model(params: ScaraParams = DEFAULT_PARAMS):
    """CasADi functions of the C11 model with free currents (no hold: the problems keep the
    currents inside their limits): f(x, U) -> x' and the tip's x coordinate tip_x(x)."""
    import casadi as ca

    p = param_values(params)
    x = ca.SX.sym("x", 9)
    u = ca.SX.sym("u", 3)
    q2, v1, v2, v3 = x[1], x[3], x[4], x[5]
    ku = [float(p.torque_constant[i] * p.gear_ratio[i]) for i in range(3)]
    torques = [ku[i] * x[6 + i] for i in range(3)]
    current_rates = [(u[i] - ku[i] * x[3 + i] - float(p.resistance[i]) * x[6 + i]) / float(p.inductance[i])
                     for i in range(3)]
    c, s = ca.cos(q2), ca.sin(q2)
    m11 = p.theta1 + 2.0 * p.theta2 * c + p.theta3
    m12 = p.theta2 * c + p.theta3
    m22 = p.theta3
    b1 = torques[0] + p.theta2 * (2.0 * v1 * v2 + v2 * v2) * s
    b2 = torques[1] - p.theta2 * v1 * v1 * s
    det = p.theta1 * p.theta3 - p.theta2 * p.theta2 * c * c
    a1 = (m22 * b1 - m12 * b2) / det
    a2 = (m11 * b2 - m12 * b1) / det
    a3 = (torques[2] - p.load_mass * p.gravity) / p.vertical_mass
    xdot = ca.vertcat(v1, v2, v3, a1, a2, a3, *current_rates)
    tip_x = p.link1_length * ca.cos(x[0]) + p.link2_length * ca.cos(x[0] + x[1])
    return ca.Function("f", [x, u], [xdot]), ca.Function("tip_x", [x], [tip_x])
