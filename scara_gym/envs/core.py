"""Compiled per-robot environment step, shared by the single and the vector environment.

One call integrates one control step with located events, summarizes the events,
computes the named reward terms and writes the observation. The single environment
calls it once per step; the vector environment calls it for every robot inside one
parallel loop, so both give bit-identical rollouts.

Its interface is records (`scara_gym.model.records` and three of its own):

- ``TASK``: the environment's constants (control step, time limit, reward weights,
  set-point mapping, observation bounds), shared by all robots;
- ``OUTCOME``: per robot, the result of its last step (weighted reward terms, events,
  status) and its episode totals;
- ``OBSERVATION``: the observation's fields, written into a flat float32 vector.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from scara_gym.model import records as R
from scara_gym.model.compilation import JIT, JIT_BORROW
from scara_gym.model.dynamics import applied_voltages, pd_voltage, tip_position, voltage_limit
from scara_gym.model.integrator import N_TIMERS, cycles, initial_modes, integrate_timed, new_workspace
from scara_gym.model.records import (
    CURRENT,
    ENERGY,
    F8,
    I8,
    RATE,
    STATUS_BAD_ACTION,
    Q,
    field_offset,
)

F4 = np.float32
REWARD_TERMS = ("progress", "time", "energy", "collision", "success")

OBSERVATION = np.dtype([
    ("q", F4, 3), ("rate", F4, 3), ("current", F4, 3), ("target_error", F4, 3),
    ("tip_x", F4), ("tip_y", F4), ("wall_distance", F4), ("height_margin", F4),
    ("critical", F4), ("time_left", F4),
])
N_OBS = OBSERVATION.itemsize // 4
O_Q, O_RATE, O_CURRENT, O_TARGET_ERROR, O_TIP_X, O_TIP_Y, O_WALL, O_HEIGHT, O_CRITICAL, O_TIME_LEFT = (
    field_offset(OBSERVATION, name) for name in OBSERVATION.names)

TASK = np.dtype([
    ("control_dt", F8),          # [s]
    ("time_limit", F8),          # horizon of the time_left feature [s]
    ("obstacle", np.bool_),      # the wall and its features
    ("pd", np.bool_),            # "pd" control mode: the action is a set-point
    *[(f"{term}_weight", F8) for term in REWARD_TERMS],
    ("setpoint_center", F8, 3),  # "pd" set-point = center + half * action [rad, rad, m]
    ("setpoint_half", F8, 3),
    ("obs_low", F4, N_OBS), ("obs_high", F4, N_OBS),
], align=True)  # aligned fields, as numba-cuda needs

OUTCOME = np.dtype([
    ("reward", F8),
    *[(term, F8) for term in REWARD_TERMS],  # the weighted terms; they sum to the reward
    ("collisions", I8),          # collisions in this step
    ("reached", np.bool_),       # the target was reached in this step
    ("reach_time", F8),          # located instant [s] (NaN if not reached)
    ("distance", F8),            # scaled target distance after the step
    ("status", I8),              # integrator status (records.STATUS_*)
    ("voltage", F8, 3),          # armature voltages at the end of the step [V]
    ("tip", F8, 2),              # tip x, y after the step [m]
    ("clipped", I8),             # action components clipped to [-1, 1]
    ("episode_steps", I8), ("episode_collisions", I8),
], align=True)

# the progress term measures the target error in these units [rad, rad, m]
DISTANCE_SCALE = np.array([1.0, 1.0, 0.1])


@njit(**JIT_BORROW)
def scaled_distance(x, p):
    total = 0.0
    for i in range(3):
        e = (x[Q + i] - p.target[i]) / DISTANCE_SCALE[i]
        total += e * e
    return math.sqrt(total)


@njit(**JIT_BORROW)
def _put(out, i, value, task):
    v = np.float32(value)
    out[i] = min(max(v, task.obs_low[i]), task.obs_high[i])


@njit(**JIT_BORROW)
def observe(robot, p, task, out):
    """The observation of the card, clipped to the space (float32 out)."""
    x = robot.x
    x_tip, y_tip, _ = tip_position(x[Q], x[Q + 1], x[Q + 2], p)
    for i in range(3):
        _put(out, O_Q + i, x[Q + i], task)
        _put(out, O_RATE + i, x[RATE + i], task)
        _put(out, O_CURRENT + i, x[CURRENT + i], task)
        _put(out, O_TARGET_ERROR + i, p.target[i] - x[Q + i], task)
    _put(out, O_TIP_X, x_tip, task)
    _put(out, O_TIP_Y, y_tip, task)
    _put(out, O_WALL, x_tip - p.wall_x if task.obstacle else 0.0, task)
    _put(out, O_HEIGHT, x[Q + 2] - p.wall_height if task.obstacle else 0.0, task)
    _put(out, O_CRITICAL, 1.0 if (task.obstacle and robot.critical == 1) else 0.0, task)
    _put(out, O_TIME_LEFT, max(0.0, 1.0 - robot.t / task.time_limit), task)


@njit(**JIT_BORROW)
def control_step(robot, p, config, task, log, outcome, workspace, timers):
    """Advance one robot by one control step (or to its stop event) under its command, in the
    integrator's work arrays (``integrator.new_workspace``); timers: None, or the integrator's
    (``integrator.integrate_timed``).
    """
    x = robot.x
    t = robot.t
    distance_before = outcome.distance
    robot.n_events = robot.n_collisions = 0
    robot.reach_time = math.nan
    energy_before = x[ENERGY]
    status = integrate_timed(robot, p, config, t + task.control_dt, log, None, workspace, timers)
    t_new = robot.t
    collisions = robot.n_collisions  # counted by the integrator: a full event log loses none
    reach_time = robot.reach_time
    reached = not math.isnan(reach_time)
    distance = scaled_distance(x, p)
    outcome.progress = task.progress_weight * (distance_before - distance)
    outcome.time = -task.time_weight * (t_new - t)
    outcome.energy = -task.energy_weight * (x[ENERGY] - energy_before)
    outcome.collision = -task.collision_weight * collisions
    outcome.success = task.success_weight if reached else 0.0
    total = 0.0  # summed from 0.0 in REWARD_TERMS order, so that the sign of a zero sum is fixed
    total += outcome.progress
    total += outcome.time
    total += outcome.energy
    total += outcome.collision
    total += outcome.success
    outcome.reward = total
    outcome.collisions = collisions
    outcome.reached = reached
    outcome.reach_time = reach_time
    outcome.distance = distance
    outcome.status = status
    outcome.episode_steps += 1
    outcome.episode_collisions += collisions
    applied_voltages(x, robot, p, config, outcome.voltage)
    outcome.tip[0], outcome.tip[1], _ = tip_position(x[Q], x[Q + 1], x[Q + 2], p)
    return status


@njit(**JIT)
def start_episode(robot, p, config, task, outcome, obs):
    """Modes, step size, counters, outcome and the first observation of a new episode."""
    initial_modes(robot, p, config)
    robot.t = 0.0
    robot.step_size = 0.0
    robot.max_step = task.control_dt
    robot.n_samples = robot.n_events = robot.n_rhs = robot.n_steps = robot.n_rejected = 0
    robot.stop_event = 0
    observe(robot, p, task, obs)
    outcome.reward = outcome.progress = outcome.time = outcome.energy = 0.0
    outcome.collision = outcome.success = outcome.reach_time = 0.0
    outcome.collisions = outcome.clipped = outcome.status = 0
    outcome.episode_steps = outcome.episode_collisions = 0
    outcome.reached = False
    for i in range(3):
        outcome.voltage[i] = 0.0
    x = robot.x
    outcome.tip[0], outcome.tip[1], _ = tip_position(x[Q], x[Q + 1], x[Q + 2], p)
    outcome.distance = scaled_distance(x, p)


@njit(**JIT)
def begin_episode(robot, p, config, task, outcome, obs, start, target):
    """A new episode: the robot at rest at ``start`` with target q^ = ``target`` (written into
    its parameters ``p``; in "pd" mode also its first command), then start_episode.
    """
    for i in range(robot.x.shape[0]):
        robot.x[i] = 0.0
    for i in range(3):
        robot.x[Q + i] = start[i]
        p.target[i] = target[i]
        robot.command[i] = target[i] if task.pd else 0.0
    start_episode(robot, p, config, task, outcome, obs)


@njit(**JIT_BORROW)
def robot_step(action, robot, p, config, task, log, outcome, obs, workspace):
    """One environment step of one robot: the action checked, clipped and mapped to the
    command, control_step, then the observation. Returns the status; STATUS_BAD_ACTION
    (with nothing changed) when the action is not finite.
    """
    return timed_robot_step(action, robot, p, config, task, log, outcome, obs, workspace, None)


@njit(**JIT_BORROW)
def timed_robot_step(action, robot, p, config, task, log, outcome, obs, workspace, timers):
    """robot_step; with timers (not None) as integrate_timed's."""
    for i in range(3):
        if not math.isfinite(action[i]):
            return STATUS_BAD_ACTION
    clipped = 0
    for i in range(3):
        a = float(action[i])
        if a > 1.0 or a < -1.0:
            clipped += 1
            a = min(max(a, -1.0), 1.0)
        robot.command[i] = task.setpoint_center[i] + task.setpoint_half[i] * a if task.pd else a
    status = control_step(robot, p, config, task, log, outcome, workspace, timers)
    outcome.clipped = clipped
    observe(robot, p, task, obs)
    return status


@njit(**JIT)
def pd_actions(obs, setpoints, params, out):
    """The "voltage"-mode actions that apply the C11 PD law (eq. 15-16, ``pd_voltage``) to
    set-points on observations: U / limit, the limit widened where the observation says
    critical. obs (n, N_OBS) and setpoints (n, 3) float64; params: one record per row, or
    one for all rows; out (n, 3).
    """
    for i in range(obs.shape[0]):
        p = params[i if params.shape[0] > 1 else 0]
        widened = obs[i, O_CRITICAL] > 0.5
        for axis in range(3):
            limit = voltage_limit(p, axis, widened)
            u = pd_voltage(setpoints[i, axis], obs[i, O_Q + axis], obs[i, O_RATE + axis], p, axis, limit)
            out[i, axis] = u / limit
    return out


# entry points for Python callers: record arrays dispatch faster than records
@njit(**JIT)
def start_robot(i, robots, params, config, task, outcomes, obs):
    start_episode(robots[i], params[i], config[0], task[0], outcomes[i], obs[i])


@njit(**JIT)
def begin_robot(i, start, target, robots, params, config, task, outcomes, obs):
    begin_episode(robots[i], params[i], config[0], task[0], outcomes[i], obs[i], start, target)


@njit(**JIT)
def restore_robot(i, x, hold, t, step_size, episode_steps, robots, params, config, task, outcomes, obs):
    """Robot i in a state of an earlier episode of the same target and parameters: its state
    vector x (energy included), current holds, time t and the integrator's next step size
    (the episode goes on bit for bit), after episode_steps steps.
    """
    robot = robots[i]
    for k in range(robot.x.shape[0]):
        robot.x[k] = x[k]
    start_episode(robot, params[i], config[0], task[0], outcomes[i], obs[i])
    for axis in range(3):  # a current at its limit stays held: the free law would push it past
        robot.hold[axis] = hold[axis]
    robot.t = t
    robot.step_size = step_size
    outcomes[i].episode_steps = episode_steps
    observe(robot, params[i], task[0], obs[i])  # time_left at t


@njit(**JIT)
def step_robot(i, action, robots, params, config, task, log, outcomes, obs):
    return robot_step(action, robots[i], params[i], config[0], task[0], log[i], outcomes[i], obs[i],
                      new_workspace())


T_STEP = N_TIMERS - 1  # timers slot of profile_robot's whole step [cycles]


@njit(**JIT)
def profile_robot(i, action, robots, params, config, task, log, outcomes, obs, timers):
    """step_robot with the integrator's timers (the benchmark's cost breakdown: a separate
    compilation, so that the environment's own step carries no timer).
    """
    started = cycles()
    status = timed_robot_step(action, robots[i], params[i], config[0], task[0], log[i], outcomes[i], obs[i],
                              new_workspace(), timers)
    timers[T_STEP] += cycles() - started
    return status


@njit(**JIT)
def cycle_counter():
    """The cycle counter read from Python (the benchmark calibrates it against the clock)."""
    return cycles()


@njit(cache=True, nogil=True, parallel=True)
def step_robots(active, actions, robots, params, config, task, log, outcomes, obs):
    """robot_step for every active robot, in parallel (actions already checked finite)."""
    for i in prange(robots.shape[0]):
        if active[i]:
            robot_step(actions[i], robots[i], params[i], config[0], task[0], log[i], outcomes[i], obs[i],
                       new_workspace())


@njit(cache=True, nogil=True)
def step_robots_serial(active, actions, robots, params, config, task, log, outcomes, obs):
    """step_robots on the calling thread alone. With one thread, a parallel loop still wakes
    numba's thread pool, whose idle OpenMP worker then spins on a core (about 40 % of one
    core per process while torch trains between env steps).
    """
    for i in range(robots.shape[0]):
        if active[i]:
            robot_step(actions[i], robots[i], params[i], config[0], task[0], log[i], outcomes[i], obs[i],
                       new_workspace())


# the single environment's info, packed by compiled code into one float vector (reading
# record fields from Python costs about 1.5 us each)
INFO_FIELDS = (*REWARD_TERMS, "reached", "collisions", "episode_collisions", "critical", "time", "energy",
               "clipped", "reach_time", "hold1", "hold2", "hold3", "voltage1", "voltage2", "voltage3",
               "target1", "target2", "target3")
N_INFO = len(INFO_FIELDS)


@njit(**JIT)
def pack_info(i, robots, params, outcomes, out):
    """INFO_FIELDS of robot i into out (float64, N_INFO)."""
    outcome, robot, p = outcomes[i], robots[i], params[i]
    out[0], out[1], out[2] = outcome.progress, outcome.time, outcome.energy
    out[3], out[4] = outcome.collision, outcome.success
    out[5] = 1.0 if outcome.reached else 0.0
    out[6], out[7] = outcome.collisions, outcome.episode_collisions
    out[8], out[9], out[10] = robot.critical, robot.t, robot.x[ENERGY]
    out[11], out[12] = outcome.clipped, outcome.reach_time
    for axis in range(3):
        out[13 + axis] = robot.hold[axis]
        out[16 + axis] = outcome.voltage[axis]
        out[19 + axis] = p.target[axis]
    return out


# -- the batched step of the GPU backend (scara_gym.envs.cuda): one robot per thread --------
# Episode plans: each robot's coming episodes (start, target and, with randomized physics,
# parameters) wait in a ring of PLAN slots, drawn on the host from the robot's own generator
# in the order the CPU vector env draws them; episode e >= 1 of robot i sits in slot e % K.
PLAN_START, PLAN_TARGET = 0, 3  # offsets into a plan's 6 floats
N_PARAMS_FLOATS = R.PARAMS.itemsize // 8  # a PARAMS record read as float64 (all its fields are)
STATUS_NO_PLAN = -5  # a robot had to reset and its ring held no plan (the host refills in time)


@njit(**JIT)
def next_episode(i, robots, params, params_flat, config, task, outcomes, obs, plans, plan_params, varied_params,
                 plans_made, episodes):
    """Robot i begins its next episode from its plan ring; False when the ring holds none."""
    episode = episodes[i] + 1
    if episode > plans_made[i]:
        return False
    slot = episode % plans.shape[1]
    episodes[i] = episode
    if varied_params:  # randomized physics: the plan's own parameters
        for j in range(N_PARAMS_FLOATS):
            params_flat[i, j] = plan_params[i, slot, j]
    begin_episode(robots[i], params[i], config[0], task[0], outcomes[i], obs[i], plans[i, slot, PLAN_START:],
                  plans[i, slot, PLAN_TARGET:])
    return True


@njit(**JIT)
def goal_gap(obs_row, target) -> float:
    """max_j |q_j - q^_j| on the goals as the goal env sees them: q as observed (float32) and
    the target rounded to float32, the difference in float64 (GoalRules' success test).
    """
    gap = 0.0
    for j in range(3):
        gap = max(gap, abs(np.float64(obs_row[O_Q + j]) - np.float64(np.float32(target[j]))))
    return gap


@njit(**JIT)
def vector_robot_step(i, same_step, max_episode_steps, terminate_collisions, goal_threshold, actions, robots,
                      params, params_flat, config, task, log, outcomes, obs, prev_done, plans, plan_params,
                      varied_params, plans_made, episodes, reward, terminated, truncated, final_obs, info, workspace):
    """Robot i's part of one vector env step, as ScaraVectorEnv does it: with NextStep
    autoreset a robot whose episode ended in the last step begins its next one (reward 0,
    neither flag) instead of stepping; with SameStep an ending step's observation goes to
    final_obs and the robot begins its next episode at once. Writes reward, the flags and
    the packed info (INFO_FIELDS, before a SameStep reset); returns the status.

    goal_threshold > 0: the goal env's episode end (ScaraGoalVectorEnv): the goal test
    ``goal_gap < goal_threshold`` instead of the located target event, or a terminating
    collision; 0: the environment's own.
    """
    status = 0
    stepped = same_step or not prev_done[i]
    if not stepped:
        if not next_episode(i, robots, params, params_flat, config, task, outcomes, obs, plans, plan_params,
                            varied_params, plans_made, episodes):
            status = STATUS_NO_PLAN
    else:
        status = robot_step(actions[i], robots[i], params[i], config[0], task[0], log[i], outcomes[i], obs[i],
                            workspace)
    outcome = outcomes[i]
    collided = terminate_collisions and outcome.collisions > 0
    if goal_threshold > 0.0:
        ended = stepped and (goal_gap(obs[i], params[i].target) < goal_threshold or collided)
    else:
        ended = outcome.reached or collided
    cut = outcome.episode_steps >= max_episode_steps
    reward[i] = outcome.reward
    terminated[i] = ended
    truncated[i] = cut
    pack_info(i, robots, params, outcomes, info[i])
    done = ended or cut
    if same_step and done:
        for j in range(obs.shape[1]):
            final_obs[i, j] = obs[i, j]
        if not next_episode(i, robots, params, params_flat, config, task, outcomes, obs, plans, plan_params,
                            varied_params, plans_made, episodes) and status >= 0:
            status = STATUS_NO_PLAN
    prev_done[i] = done
    return status
