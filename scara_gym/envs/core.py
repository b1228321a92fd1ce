"""Compiled per-robot control step shared by the single and the vector environment.

One call integrates one control step with located events, summarizes the events,
computes the named reward terms and writes the observation. The single environment
calls it once per step; the vector environment calls it for every robot inside one
parallel loop, so both give bit-identical rollouts.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from scara_gym.dynamics import JIT, tip_position, voltages
from scara_gym.integrator import initial_modes, integrate
from scara_gym.layout import (
    ENERGY, EV_COLLISION, EV_TARGET_IN, H_OBS, K_EVENTS, M_CRITICAL, TARGET, X_OBS,
)

# the progress term measures the target error in these units [rad, rad, m]
DISTANCE_SCALE = np.array([1.0, 1.0, 0.1])

# reward weight vector
W_PROGRESS, W_TIME, W_ENERGY, W_COLLISION, W_SUCCESS = range(5)
REWARD_TERMS = ("progress", "time", "energy", "collision", "success")

# per-step result vector
R_REWARD = 0
R_TERMS = 1            # 5 weighted terms, in REWARD_TERMS order
R_COLLISIONS = 6       # collisions in this step
R_REACHED = 7          # 1.0 if the target was reached in this step
R_REACH_TIME = 8       # located instant [s] (NaN if not reached)
R_DISTANCE = 9         # scaled target distance after the step
R_STATUS = 10          # integrator status
R_VOLTAGE = 11         # 3 armature voltages at the end of the step [V]
R_TIP = 14             # tip x, y [m] after the step
R_CLIPPED = 16         # action components clipped to [-1, 1]
N_RESULT = 17

# per-environment constants (spec vector): one array instead of a dozen arguments,
# because the dispatch cost of a compiled call grows with its argument count
S_DT, S_RTOL, S_ATOL, S_TIME_LIMIT, S_OBSTACLE, S_PD = range(6)
S_WEIGHTS = 6          # 5 reward weights, in REWARD_TERMS order
S_CENTER = 11          # 3: "pd" set-point = center + half * action
S_HALF = 14            # 3
N_SPEC = 17

N_OBS = 18


@njit(**JIT)
def scaled_distance(x, p):
    total = 0.0
    for i in range(3):
        e = (x[i] - p[TARGET + i]) / DISTANCE_SCALE[i]
        total += e * e
    return math.sqrt(total)


@njit(**JIT)
def _put(out, i, value, low, high):
    v = np.float32(value)
    out[i] = min(max(v, low[i]), high[i])


@njit(**JIT)
def observe(x, p, t, time_limit, obstacle, critical, low, high, out):
    """The 18 observation values of the card, clipped to the space (float32 out)."""
    x_tip, y_tip, _ = tip_position(x[0], x[1], x[2], p)
    for i in range(9):
        _put(out, i, x[i], low, high)
    for i in range(3):
        _put(out, 9 + i, p[TARGET + i] - x[i], low, high)
    _put(out, 12, x_tip, low, high)
    _put(out, 13, y_tip, low, high)
    _put(out, 14, x_tip - p[X_OBS] if obstacle else 0.0, low, high)
    _put(out, 15, x[2] - p[H_OBS] if obstacle else 0.0, low, high)
    _put(out, 16, 1.0 if (obstacle and critical) else 0.0, low, high)
    _put(out, 17, max(0.0, 1.0 - t / time_limit), low, high)


@njit(**JIT)
def control_step(x, t, dt, p, command, config, modes, rtol, atol, step_state, weights,
                 distance_before, rec_t, rec_x, rec_u, ev_t, ev_code, ev_axis, counters, result):
    """Advance one robot by one control step (or to its stop event); returns the new time."""
    counters[K_EVENTS] = 0
    energy_before = x[ENERGY]
    status, t_new = integrate(x, t, t + dt, p, command, config, modes, rtol, atol, step_state,
                              rec_t, rec_x, rec_u, ev_t, ev_code, ev_axis, counters)
    collisions = 0
    reach_time = math.nan
    for i in range(min(counters[K_EVENTS], ev_t.shape[0])):
        if ev_code[i] == EV_COLLISION:
            collisions += 1
        elif ev_code[i] == EV_TARGET_IN and math.isnan(reach_time):
            reach_time = ev_t[i]
    reached = not math.isnan(reach_time)
    distance = scaled_distance(x, p)
    result[R_TERMS + W_PROGRESS] = weights[W_PROGRESS] * (distance_before - distance)
    result[R_TERMS + W_TIME] = -weights[W_TIME] * (t_new - t)
    result[R_TERMS + W_ENERGY] = -weights[W_ENERGY] * (x[ENERGY] - energy_before)
    result[R_TERMS + W_COLLISION] = -weights[W_COLLISION] * collisions
    result[R_TERMS + W_SUCCESS] = weights[W_SUCCESS] if reached else 0.0
    total = 0.0
    for k in range(5):
        total += result[R_TERMS + k]
    result[R_REWARD] = total
    result[R_COLLISIONS] = collisions
    result[R_REACHED] = 1.0 if reached else 0.0
    result[R_REACH_TIME] = reach_time
    result[R_DISTANCE] = distance
    result[R_STATUS] = status
    volts = np.empty(3)
    voltages(x, p, command, config, modes, volts)
    for i in range(3):
        result[R_VOLTAGE + i] = volts[i]
    result[R_TIP], result[R_TIP + 1], _ = tip_position(x[0], x[1], x[2], p)
    return t_new


@njit(**JIT)
def start_episode(x, p, command, config, modes, step_state, counters, spec, bounds, obs, result):
    """Modes, step size, counters and the first observation of a new episode; returns d(q)."""
    initial_modes(x, p, command, config, modes)
    step_state[0] = 0.0
    step_state[1] = spec[S_DT]
    counters[:] = 0
    observe(x, p, 0.0, spec[S_TIME_LIMIT], spec[S_OBSTACLE] == 1.0, modes[M_CRITICAL] == 1,
            bounds[0], bounds[1], obs)
    result[:] = 0.0
    result[R_TIP], result[R_TIP + 1], _ = tip_position(x[0], x[1], x[2], p)
    distance = scaled_distance(x, p)
    result[R_DISTANCE] = distance
    return distance


@njit(**JIT)
def robot_step(action, x, t, p, command, config, modes, step_state, spec, bounds, distance_before,
               ev_t, ev_code, ev_axis, counters, result, obs):
    """One environment step of one robot: the action checked, clipped and mapped to the
    command, control_step, then the observation. Returns the new time, or NaN (with
    nothing changed) when the action is not finite.
    """
    for i in range(3):
        if not math.isfinite(action[i]):
            return math.nan
    clipped = 0
    for i in range(3):
        a = float(action[i])
        if a > 1.0 or a < -1.0:
            clipped += 1
            a = min(max(a, -1.0), 1.0)
        command[i] = spec[S_CENTER + i] + spec[S_HALF + i] * a if spec[S_PD] == 1.0 else a
    rec_t = np.empty(0)
    rec_x = np.empty((0, x.shape[0]))
    rec_u = np.empty((0, 3))
    t_new = control_step(x, t, spec[S_DT], p, command, config, modes, spec[S_RTOL], spec[S_ATOL],
                         step_state, spec[S_WEIGHTS:S_WEIGHTS + 5], distance_before, rec_t, rec_x,
                         rec_u, ev_t, ev_code, ev_axis, counters, result)
    result[R_CLIPPED] = clipped
    observe(x, p, t_new, spec[S_TIME_LIMIT], spec[S_OBSTACLE] == 1.0, modes[M_CRITICAL] == 1,
            bounds[0], bounds[1], obs)
    return t_new


@njit(cache=True, nogil=True, parallel=True)
def robot_step_batch(active, actions, x, t, p, command, config, modes, step_state, spec, bounds,
                     distance, ev_t, ev_code, ev_axis, counters, result, obs):
    """robot_step for every active robot, in parallel (actions already checked finite)."""
    for i in prange(x.shape[0]):
        if not active[i]:
            continue
        t[i] = robot_step(actions[i], x[i], t[i], p[i], command[i], config, modes[i], step_state[i],
                          spec, bounds, distance[i], ev_t[i], ev_code[i], ev_axis[i], counters[i],
                          result[i], obs[i])
        distance[i] = result[i, R_DISTANCE]
