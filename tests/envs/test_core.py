"""The compiled per-robot step, called directly on its records (not through an environment)."""

import math

import numpy as np
import pytest

from scara_gym.envs.core import (
    N_OBS,
    N_TIMERS,
    OBSERVATION,
    OUTCOME,
    REWARD_TERMS,
    T_STEP,
    TASK,
    profile_robot,
    start_robot,
    step_robot,
)
from scara_gym.envs.task import OBSERVATION_LAYOUT, OBSERVATION_NAMES, ScaraTask
from scara_gym.model import records as R
from scara_gym.model.integrator import T_LOCATE, T_SEARCH


def fresh_task(**kwargs) -> ScaraTask:
    task = ScaraTask(**kwargs)
    task.reset_robot(0, np.random.default_rng(0))
    return task


def call(task, action):
    return step_robot(0, np.asarray(action, dtype=np.float64), task.robots, task.robot_params, task.step_config,
                      task.constants, task.log, task.outcomes, task.obs)


def test_layouts_are_derived_from_the_record_types():
    assert N_OBS == 18 == len(OBSERVATION_NAMES) == OBSERVATION.itemsize // 4
    assert OBSERVATION_LAYOUT["q"] == slice(0, 3) and OBSERVATION_LAYOUT["target_error"] == slice(9, 12)
    assert OBSERVATION_LAYOUT["time_left"] == 17
    assert (R.Q, R.RATE, R.CURRENT, R.ENERGY, R.N_STATE) == (0, 3, 6, 9, 10)
    assert all(f"{term}_weight" in TASK.names and term in OUTCOME.names for term in REWARD_TERMS)


def test_a_step_writes_the_outcome_and_the_observation():
    task = fresh_task(control_mode="voltage", collision="penalty")
    status = call(task, [0.5, -0.3, 1.5])
    outcome, robot, obs = task.outcomes[0], task.robots[0], task.obs[0]
    assert status == R.STATUS_END
    assert robot["t"] == pytest.approx(0.01)
    assert outcome["clipped"] == 1 and outcome["episode_steps"] == 1
    assert outcome["reward"] == sum(outcome[term] for term in REWARD_TERMS)
    assert outcome["time"] == pytest.approx(-10.0 * 0.01)
    assert np.allclose(outcome["voltage"], [0.5 * 100.0, -0.3 * 75.0, 1.0 * 90.0])
    x = robot["x"]
    assert np.array_equal(obs[OBSERVATION_LAYOUT["q"]], x[R.Q:R.Q + 3].astype(np.float32))
    assert np.array_equal(obs[OBSERVATION_LAYOUT["current"]], x[R.CURRENT:R.CURRENT + 3].astype(np.float32))
    assert obs[OBSERVATION_LAYOUT["time_left"]] == np.float32(1.0 - 0.01 / 3.0)
    assert robot["n_rhs"] > 0 and robot["n_steps"] > 0


@pytest.mark.parametrize("exact_switches", [False, True])
def test_the_timed_step_of_the_cost_breakdown_is_the_step_bit_for_bit(exact_switches):
    """profile_robot (bench's cost breakdown) times the parts of the step without changing it."""
    kwargs = dict(control_mode="pd", exact_switches=exact_switches, rtol=1e-7, atol=1e-9)
    plain, timed = fresh_task(**kwargs), fresh_task(**kwargs)
    timers = np.zeros(N_TIMERS, dtype=np.int64)
    rng = np.random.default_rng(1)
    for action in rng.uniform(-1.0, 1.0, (40, 3)):
        assert call(plain, action) == profile_robot(0, action, timed.robots, timed.robot_params, timed.step_config,
                                                    timed.constants, timed.log, timed.outcomes, timed.obs, timers)
    for name in ("robots", "outcomes", "obs", "log"):
        assert getattr(plain, name).tobytes() == getattr(timed, name).tobytes()
    assert timed.robots[0]["n_events"] > 0  # the location was timed too
    assert 0 < timers[T_SEARCH] < timers[T_STEP] and 0 < timers[T_LOCATE] < timers[T_STEP]


def test_a_non_finite_action_returns_a_status_and_changes_nothing():
    task = fresh_task()
    call(task, [0.1, 0.2, 0.3])
    before = [a.tobytes() for a in (task.robots, task.outcomes, task.obs, task.log)]
    assert call(task, [0.0, math.nan, 0.0]) == R.STATUS_BAD_ACTION
    assert call(task, [math.inf, 0.0, 0.0]) == R.STATUS_BAD_ACTION
    assert [a.tobytes() for a in (task.robots, task.outcomes, task.obs, task.log)] == before


def test_start_resets_the_outcome_and_counters():
    task = fresh_task(control_mode="voltage")
    for _ in range(5):
        call(task, [1.0, 1.0, 1.0])
    task.robots[0]["t"] = 0.0
    start_robot(0, task.robots, task.robot_params, task.step_config, task.constants, task.outcomes, task.obs)
    outcome, robot = task.outcomes[0], task.robots[0]
    assert outcome["episode_steps"] == 0 and outcome["reward"] == 0.0 and not outcome["reached"]
    assert robot["n_rhs"] == 0 and robot["step_size"] == 0.0 and robot["max_step"] == 0.01


def test_the_pd_action_is_the_pd_law_the_environment_applies():
    """In "voltage" mode, commanding pd_action(obs, q^) once per step equals the "pd" mode's PD law
    at the start of each step: the voltages match at the start of the first step."""
    task = fresh_task(control_mode="voltage", obstacle=False)
    obs = task.obs[0].astype(np.float64)
    setpoint = np.array([2.0, 2.0, 0.3])
    action = task.pd_action(obs, setpoint)
    p = task.params
    expected = [np.clip(a.p_gain * (setpoint[i] - obs[i]) - a.d_gain * obs[3 + i], -a.voltage_limit,
                        a.voltage_limit) / a.voltage_limit for i, a in enumerate(p.axes)]
    assert np.array_equal(action, expected)
    assert task.pd_action(np.tile(obs, (4, 1)), setpoint).shape == (4, 3)
