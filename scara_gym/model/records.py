"""Record types of the compiled core: structured dtypes with named fields.

numba compiles a field of a record (one element of a structured array) to a load at a
constant offset, so named fields cost nothing over hand-numbered offsets into flat
arrays, and one record replaces a dozen array arguments (it also passes as one pointer,
without reference counting). The same dtypes serve a CUDA port: numba.cuda compiles
records alike.

- ``PARAMS``: the model's parameters (``ScaraParams.to_record``), units as in
  `scara_gym.model.params`.
- ``CONFIG``: the switches and tolerances of one simulation.
- ``ROBOT``: the mutable state of one simulated robot: the state vector, time, command,
  hybrid modes, step size and counters.
- ``EVENT``: one entry of an event log; ``SAMPLE``: one recorded sample of a trajectory.

The state vector itself stays a flat float vector, because the integrator works on it
as one; the model addresses it through the offsets of ``STATE`` (``Q``, ``RATE``,
``CURRENT``, ``ENERGY``), derived from the dtype rather than numbered by hand.
"""

from __future__ import annotations

import numpy as np

F8, I8, B1 = np.float64, np.int64, np.bool_

STATE = np.dtype([
    ("q", F8, 3),          # joint angles [rad], height [m]
    ("rate", F8, 3),       # rate states [rad/s, rad/s, m/s]
    ("current", F8, 3),    # armature currents [A]
    ("energy", F8),        # electrical energy drawn since the start, int sum U_i I_i dt [J]
])


def field_offset(dtype: np.dtype, name: str) -> int:
    """Index of a field's first element when the record is read as a flat vector."""
    field_type, offset = dtype.fields[name][:2]
    return offset // field_type.base.itemsize


Q, RATE, CURRENT, ENERGY = (field_offset(STATE, name) for name in STATE.names)
N_STATE = STATE.itemsize // STATE["q"].base.itemsize
STATE_GROUPS = {name: slice(field_offset(STATE, name), field_offset(STATE, name) + int(np.prod(STATE[name].shape)))
                for name in STATE.names}
"""each STATE field's slice of the state read as a flat vector"""

PARAMS = np.dtype([
    # mechanics (ArmParams and its derived inertias)
    ("theta1", F8), ("theta2", F8), ("theta3", F8), ("vertical_mass", F8),
    ("load_mass", F8), ("gravity", F8), ("link1_length", F8), ("link2_length", F8),
    # per axis (AxisParams), and the widened voltage limit of the obstacle rule
    ("resistance", F8, 3), ("inductance", F8, 3), ("torque_constant", F8, 3), ("gear_ratio", F8, 3),
    ("current_limit", F8, 3), ("p_gain", F8, 3), ("d_gain", F8, 3), ("voltage_limit", F8, 3),
    ("wide_voltage_limit", F8, 3),
    # the wall of task c and the dec rule (ObstacleParams)
    ("wall_x", F8), ("critical_distance", F8), ("wall_height", F8), ("dec", F8),
    # the point-to-point move (TaskParams)
    ("target", F8, 3), ("accuracy", F8),
])

CONFIG = np.dtype([
    ("form", I8),           # FORM_EXPLICIT or FORM_IMPLICIT
    ("control", I8),        # CONTROL_PD (command = set-point) or CONTROL_VOLTAGE (command = U / limit)
    ("critical_rule", I8),  # CRIT_OFF, CRIT_SWITCH (evaluated at every instant), CRIT_FORCED
    ("widen", B1),          # voltage limit Umax_wide while critical
    ("decelerate", B1),     # q1' = dec v1, q2' = dec v2 while critical
    ("stops", I8),          # bit mask of STOP_*
    ("wall", B1),           # track crossings of the wall plane (collisions)
    ("max_steps", I8),      # accepted + rejected step budget of one call
    ("rtol", F8), ("atol", F8),  # error tolerances, scipy's meaning
    ("tolerance_weights", F8, N_STATE),  # per state component: a factor on both tolerances
    ("exact_switches", B1),  # the PD saturation a located mode, every switch searched inside steps
], align=True)  # aligned fields: numba-cuda loads only aligned ones

ROBOT = np.dtype([
    ("x", F8, N_STATE),     # state vector, laid out as STATE
    ("t", F8),              # time [s]
    ("command", F8, 3),     # PD set-point or U / limit, held over a call
    # hybrid modes
    ("hold", I8, 3),        # -1 / 0 / +1: current held at -Imax, free, held at +Imax
    ("saturation", I8, 3),  # -1 / 0 / +1: PD voltage at -limit, linear, at +limit (exact_switches)
    ("critical", I8),       # 0/1
    ("side", I8),           # sign of x_tip - x_obs
    ("above", I8),          # 1 while q3 >= h_obs
    ("inside", I8),         # 1 while all |q_i - q^_i| < acc
    # step size control, kept across calls
    ("step_size", F8),      # next step proposal [s]; <= 0: choose one
    ("max_step", F8),       # [s]
    # counters
    ("n_samples", I8), ("n_events", I8), ("n_rhs", I8), ("n_steps", I8), ("n_rejected", I8),
    ("stop_event", I8),     # EV_* code of the stop event of the last call
    # what must not be lost to a full event log; reset by the caller, like n_events
    ("n_collisions", I8),   # EV_COLLISION events
    ("reach_time", F8),     # instant of the first EV_TARGET_IN [s]; NaN until one happens
])

EVENT = np.dtype([("time", F8), ("code", I8), ("axis", I8)])  # axis -1: not an axis event
SAMPLE = np.dtype([("t", F8), ("x", F8, N_STATE), ("voltage", F8, 3)])

FORM_EXPLICIT, FORM_IMPLICIT = 0, 1
CONTROL_PD, CONTROL_VOLTAGE = 0, 1
CRIT_OFF, CRIT_SWITCH, CRIT_FORCED = 0, 1, 2

STOP_TARGET = 1       # entered the target band
STOP_COLLISION = 2    # crossed the wall plane below h_obs
STOP_CRITICAL = 4     # became critical
STOP_ABOVE = 8        # q3 rose to h_obs

# event functions (index into the g vector; positive while the mode holds)
E_HOLD1, E_HOLD2, E_HOLD3, E_CRITICAL, E_SIDE, E_HEIGHT, E_TARGET, E_SAT1, E_SAT2, E_SAT3 = range(10)
N_EVENTS = 10

# codes written to the event log
EV_LIMIT_ON = 1       # axis = 0..2; current reached +-Imax and is held
EV_LIMIT_OFF = 2
EV_CRITICAL_ON = 3
EV_CRITICAL_OFF = 4
EV_WALL_CROSS = 5     # crossed the wall plane above h_obs: harmless
EV_COLLISION = 6      # crossed the wall plane below h_obs
EV_ABOVE = 7          # q3 reached h_obs
EV_BELOW = 8
EV_TARGET_IN = 9
EV_TARGET_OUT = 10
EV_SATURATION_ON = 11  # axis = 0..2; the PD voltage reached +-limit (exact_switches)
EV_SATURATION_OFF = 12
EVENT_NAMES = {
    EV_LIMIT_ON: "current_limit_on", EV_LIMIT_OFF: "current_limit_off",
    EV_CRITICAL_ON: "critical_on", EV_CRITICAL_OFF: "critical_off",
    EV_WALL_CROSS: "wall_cross", EV_COLLISION: "collision",
    EV_ABOVE: "above_wall", EV_BELOW: "below_wall",
    EV_TARGET_IN: "target_reached", EV_TARGET_OUT: "target_left",
    EV_SATURATION_ON: "voltage_saturation_on", EV_SATURATION_OFF: "voltage_saturation_off",
}

# return status of integrate() and of the environment's compiled step
STATUS_END = 0            # reached t_end
STATUS_STOPPED = 1        # a stop event fired (ROBOT.stop_event)
STATUS_MAX_STEPS = -1
STATUS_STEP_UNDERFLOW = -2
STATUS_NOT_FINITE = -3
STATUS_BAD_ACTION = -4    # a non-finite action: nothing was changed
