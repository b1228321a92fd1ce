"""The C11 model in CasADi: the symbolic twin of the compiled dynamics, for optimal control.

Everything the compiled core evaluates, as CasADi functions built from the same
`ScaraParams` and the same switches (`symbolic_model`):

- ``rhs(x, command, modes) -> x'``: `scara_gym.model.dynamics.derivative` in every
  hybrid mode: held currents, the PD law's located saturation (or its clip), the critical
  zone's widened voltage limits and the ``dec`` rule's scaled kinematics;
- ``voltages(x, command, modes) -> U``: the armature voltages of that mode;
- ``events(x, command, modes) -> g``: the event functions of
  `scara_gym.model.integrator.event_values` (positive while the mode holds; the
  indices ``E_*`` of `scara_gym.model.records`);
- ``tip(q) -> (x, y, z)``: the forward kinematics of the joint positions;
- ``free(x, U) -> x'``: the model driven by voltages with the currents free (no hold), on
  the 9 physical states: what a direct transcription integrates, keeping the currents
  inside their limits by a path constraint instead.

``x`` is the state vector of `STATE` (10 entries: q, rates,
currents, energy); ``modes`` the discrete modes of a ``ROBOT`` record as floats, in the
order of `MODES`. A test holds every function to the compiled one at random states in
every mode. CasADi is the ``control`` install extra; this module imports it when a model is
built. Example, a fixed-step integrator of the PD-controlled arm (currents free)::

    import casadi as ca
    from scara_gym.model.symbolic import symbolic_model

    model = symbolic_model(control="pd", exact_switches=False)  # the PD law clipped at every evaluation
    x, setpoint = ca.SX.sym("x", 10), ca.SX.sym("q_hat", 3)
    modes = model.free_modes()                      # nothing held or critical
    f = lambda x: model.rhs(x, setpoint, modes)
    h = 1e-4                                        # one classic Runge-Kutta step
    k1 = f(x); k2 = f(x + h / 2 * k1); k3 = f(x + h / 2 * k2); k4 = f(x + h * k3)
    step = ca.Function("step", [x, setpoint], [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])

An optimal-control problem uses ``free`` (smooth) with the mode structure as constraints,
as `agents.policies.optimal` and `agents.policies.mpc` do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from scara_gym.extras import require
from scara_gym.model import checks
from scara_gym.model.checks import UserError, UserTypeError
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams
from scara_gym.model.records import CURRENT, ENERGY, N_EVENTS, N_STATE, RATE, Q

MODES = ("hold1", "hold2", "hold3", "saturation1", "saturation2", "saturation3", "critical", "side", "above",
         "inside")
"""the entries of ``modes``: a ROBOT record's hold (-1/0/1 per axis), saturation (-1/0/1 per
axis), critical (0/1), side (+-1: the sign of x_tip - x_obs), above (0/1), inside (0/1)"""
CONTROLS = ("pd", "voltage")
CRITICAL_RULES = ("off", "switch", "forced")


@dataclass(frozen=True)
class SymbolicModel:
    """The CasADi functions of one parameter set and configuration (module docstring)."""

    params: ScaraParams
    control: str
    rhs: Any
    voltages: Any
    events: Any
    tip: Any
    free: Any

    @staticmethod
    def free_modes() -> np.ndarray:
        """modes with nothing held, saturated, critical, above or inside; the tip on the + side."""
        modes = np.zeros(len(MODES))
        modes[MODES.index("side")] = 1.0
        return modes


def _values(params: ScaraParams):
    """The PARAMS record as Python floats and float tuples (constants of the expressions)."""
    record = params.to_record()
    return {name: (float(record[name]) if np.ndim(record[name]) == 0 else tuple(map(float, record[name])))
            for name in record.dtype.names}


def symbolic_model(params: ScaraParams = DEFAULT_PARAMS, *, control: str = "voltage", widen: bool = True,
                   decelerate: bool = False, critical_rule: str = "switch", wall: bool = True,
                   exact_switches: bool = True) -> SymbolicModel:
    """The CasADi twin of the compiled model for ``params`` and a CONFIG's switches.

    The environments use control_mode's control, widen=True, decelerate=False,
    critical_rule="switch" (with the wall) and exact_switches=True (v1, v2).

    Args:
        params: the parameter tree (default: the C11 set).
        control: "pd" (command = set-point, eq. 15-16) or "voltage" (command = U / limit).
        widen: the voltage limit is Umax_wide while critical.
        decelerate: the dec rule's kinematics while critical.
        critical_rule: "off", "switch" or "forced" (the critical event function).
        wall: track the wall plane.
        exact_switches: the PD saturation a located mode (else clipped at every evaluation).

    Returns:
        The SymbolicModel: CasADi functions ``rhs``, ``voltages``, ``events``, ``tip`` and
        ``free`` (voltages in, currents free), and the ``params`` they were built from.
    """
    require("casadi")
    import casadi as ca

    if not isinstance(params, ScaraParams):
        raise UserTypeError(f"params must be a ScaraParams, got {type(params).__name__}")
    if control not in CONTROLS:
        raise UserError(f"control must be one of {CONTROLS}, got {control!r}")
    widen, exact_switches = checks.flag("widen", widen), checks.flag("exact_switches", exact_switches)
    if critical_rule not in CRITICAL_RULES:
        raise UserError(f"critical_rule must be one of {CRITICAL_RULES}, got {critical_rule!r}")
    p = _values(params)
    pd = control == "pd"
    x = ca.SX.sym("x", N_STATE)
    command = ca.SX.sym("command", 3)
    modes = ca.SX.sym("modes", len(MODES))
    hold, saturation = modes[0:3], modes[3:6]
    critical, side, above, inside = (modes[MODES.index(name)] for name in ("critical", "side", "above", "inside"))
    widened = critical * (1.0 if widen else 0.0)  # 1 where the widened limit applies
    ku = [p["torque_constant"][i] * p["gear_ratio"][i] for i in range(3)]

    def limit(axis):
        return p["voltage_limit"][axis] + widened * (p["wide_voltage_limit"][axis] - p["voltage_limit"][axis])

    def linear_pd(axis):
        return p["p_gain"][axis] * (command[axis] - x[Q + axis]) - p["d_gain"][axis] * x[RATE + axis]

    def mode_voltage(axis):
        if not pd:
            return command[axis] * limit(axis)
        u = linear_pd(axis)
        if exact_switches:
            return ca.if_else(saturation[axis] == 0, u, saturation[axis] * limit(axis))
        return ca.fmin(ca.fmax(u, -limit(axis)), limit(axis))

    def free_current_rate(volts, rate, current, axis):
        return (volts - ku[axis] * rate - p["resistance"][axis] * current) / p["inductance"][axis]

    def tip_x(q1, q2):
        return p["link1_length"] * ca.cos(q1) + p["link2_length"] * ca.cos(q1 + q2)

    def accelerations(q2, v1, v2, t1, t2, t3):
        """The explicit form (dynamics.accelerations_explicit), operation for operation."""
        c, s = ca.cos(q2), ca.sin(q2)
        m11 = p["theta1"] + 2.0 * p["theta2"] * c + p["theta3"]
        m12 = p["theta2"] * c + p["theta3"]
        m22 = p["theta3"]
        b1 = t1 + p["theta2"] * (2.0 * v1 * v2 + v2 * v2) * s
        b2 = t2 - p["theta2"] * v1 * v1 * s
        det = p["theta1"] * p["theta3"] - p["theta2"] * p["theta2"] * c * c
        return ((m22 * b1 - m12 * b2) / det, (m11 * b2 - m12 * b1) / det,
                (t3 - p["load_mass"] * p["gravity"]) / p["vertical_mass"])

    def mechanics(state, volts, current_rates, dec):
        """x' from the voltages and the current rates (the part every mode shares)."""
        torques = [ku[i] * state[CURRENT + i] for i in range(3)]
        a1, a2, a3 = accelerations(state[Q + 1], state[RATE], state[RATE + 1], *torques)
        return [dec * state[RATE], dec * state[RATE + 1], state[RATE + 2], a1, a2, a3, *current_rates]

    volts = [mode_voltage(axis) for axis in range(3)]
    rates = [ca.if_else(hold[axis] != 0, 0.0, free_current_rate(volts[axis], x[RATE + axis], x[CURRENT + axis], axis))
             for axis in range(3)]
    dec = 1.0 + critical * ((p["dec"] - 1.0) if decelerate else 0.0)
    power = sum(volts[axis] * x[CURRENT + axis] for axis in range(3))
    xdot = ca.vertcat(*mechanics(x, volts, rates, dec), power)
    assert xdot.shape[0] == N_STATE and ENERGY == N_STATE - 1

    # event functions, as integrator.event_values
    g = [None] * N_EVENTS
    for axis in range(3):
        imax = p["current_limit"][axis]
        held = hold[axis] * free_current_rate(volts[axis], x[RATE + axis], hold[axis] * imax, axis)
        g[axis] = ca.if_else(hold[axis] == 0, imax - ca.fabs(x[CURRENT + axis]), held)
    xt = tip_x(x[Q], x[Q + 1])
    if critical_rule == "switch":
        measure = ca.fmin(p["critical_distance"] - ca.fabs(xt - p["wall_x"]), p["wall_height"] - x[Q + 2])
        g[3] = ca.if_else(critical == 1, measure, -measure)
    else:
        g[3] = ca.SX(1.0)
    g[4] = side * (xt - p["wall_x"]) if wall else ca.SX(1.0)
    g[5] = ca.if_else(above == 1, x[Q + 2] - p["wall_height"], p["wall_height"] - x[Q + 2])
    error = ca.fmax(ca.fmax(ca.fabs(x[Q] - p["target"][0]), ca.fabs(x[Q + 1] - p["target"][1])),
                    ca.fabs(x[Q + 2] - p["target"][2]))
    g[6] = ca.if_else(inside == 1, p["accuracy"] - error, error - p["accuracy"])
    for axis in range(3):
        if exact_switches and pd:
            u = linear_pd(axis)
            g[7 + axis] = ca.if_else(saturation[axis] == 0, limit(axis) - ca.fabs(u),
                                     saturation[axis] * u - limit(axis))
        else:
            g[7 + axis] = ca.SX(1.0)

    q = ca.SX.sym("q", 3)
    tip = ca.vertcat(tip_x(q[0], q[1]), p["link1_length"] * ca.sin(q[0]) + p["link2_length"] * ca.sin(q[0] + q[1]), q[2])

    # the free model: voltages in, currents free, 9 states
    y = ca.SX.sym("x", 9)
    u_in = ca.SX.sym("U", 3)
    free_rates = [free_current_rate(u_in[i], y[RATE + i], y[CURRENT + i], i) for i in range(3)]
    ydot = ca.vertcat(*mechanics(y, [u_in[i] for i in range(3)], free_rates, 1.0))

    inputs, names = [x, command, modes], ["x", "command", "modes"]
    return SymbolicModel(
        params=params, control=control,
        rhs=ca.Function("rhs", inputs, [xdot], names, ["xdot"]),
        voltages=ca.Function("voltages", inputs, [ca.vertcat(*volts)], names, ["U"]),
        events=ca.Function("events", inputs, [ca.vertcat(*g)], names, ["g"]),
        tip=ca.Function("tip", [q], [tip], ["q"], ["tip"]),
        free=ca.Function("free", [y, u_in], [ydot], ["x", "U"], ["xdot"]),
    )
