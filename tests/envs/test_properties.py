"""Properties over random configurations, starts, targets and action programs (hypothesis).

For every drawn episode and every step: the observation is finite and inside its space,
every |I_i| <= Imax_i, the reward is the sum of its named terms, a collision ends the step
on the wall plane below h_obs, and a step whose ends lie on both sides of the wall while
the arm is well below h_obs reports the collision. The accuracy property against a tight
integration runs on a fixed sample in tests/benchmark/test_accuracy.py.
"""

import math

import numpy as np
from hypothesis import HealthCheck, assume, event, given, settings, strategies as st

from scara_gym.envs import REWARD_TERMS, ScaraEnv
from scara_gym.envs.task import JOINT_HIGH, JOINT_LOW, TARGET_HIGH, TARGET_LOW
from scara_gym.model import records as R
from scara_gym.model.dynamics import tip_position

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
Q3_RATE_BOUND = 2.0  # [m/s] far above what axis 3 reaches (about 0.45 m/s at the widened voltage)


def joints():
    return st.tuples(*(st.floats(float(lo), float(hi)) for lo, hi in zip(JOINT_LOW, JOINT_HIGH)))


@st.composite
def configurations(draw):
    factor = lambda: draw(st.floats(0.5, 2.0))  # noqa: E731
    params = {
        "arm.load_mass": draw(st.floats(0.1, 2.0)),
        "obstacle.x_position": draw(st.floats(0.25, 0.45)),
        "obstacle.height": draw(st.floats(0.1, 0.25)),
    }
    for axis in range(3):
        params[f"axes.{axis}.p_gain"] = 1000.0 * (5.0 if axis == 2 else 1.0) * factor()
        params[f"axes.{axis}.current_limit"] = (6.64, 2.771, 1.732)[axis] * draw(st.floats(0.7, 1.3))
    kwargs = {
        "control_mode": draw(st.sampled_from(["pd", "voltage"])),
        "obstacle": draw(st.booleans()),
        "collision": draw(st.sampled_from(["terminate", "penalty"])),
        "control_dt": draw(st.sampled_from([0.005, 0.01, 0.02])),
        "exact_switches": draw(st.booleans()),
        "params": params,
    }
    if draw(st.booleans()):
        kwargs["target"] = draw(st.tuples(*(st.floats(float(lo), float(hi)) for lo, hi in zip(TARGET_LOW, TARGET_HIGH))))
    start = draw(st.sampled_from(["default", "random", "near the wall"]))
    options = {}
    if start == "random":
        options["start"] = draw(joints())
    elif start == "near the wall":  # q2 = 0: the tip at x = 0.7 cos q1, about 0.33-0.42 m
        options["start"] = (draw(st.floats(0.92, 1.08)), 0.0, draw(st.floats(0.0, 0.1)))
    steps = draw(st.integers(1, 80))
    program = draw(st.sampled_from(["uniform", "extreme", "hold", "toward the target"]))
    if program == "uniform":
        actions = draw(st.lists(st.tuples(*[st.floats(-1.0, 1.0)] * 3), min_size=steps, max_size=steps))
    elif program == "extreme":  # bang-bang, and values beyond [-1, 1] that get clipped
        actions = draw(st.lists(st.tuples(*[st.sampled_from([-1.5, -1.0, 1.0, 1.2])] * 3),
                                min_size=steps, max_size=steps))
    elif program == "hold":
        actions = [draw(st.tuples(*[st.floats(-1.0, 1.0)] * 3))] * steps
    else:  # q1, q2 driven up (across the wall), q3 held low
        actions = [None] * steps
    return kwargs, options, program, actions


def tip_x(env) -> float:
    return tip_position(*env.state[R.Q:R.Q + 3], env.params.to_record())[0]


@SETTINGS
@given(configurations(), st.integers(0, 2**31 - 1))
def test_every_step_keeps_the_invariants(configuration, seed):
    kwargs, options, program, actions = configuration
    env = ScaraEnv(**kwargs)
    if program == "toward the target":
        toward = env.setpoint_to_action(env.target) if env.control_mode == "pd" else np.array([1.0, 1.0, -0.2])
        actions = [toward] * len(actions)
    actions = np.array(actions, dtype=np.float32)
    target = np.array(kwargs.get("target", env.params.task.target))
    assume(np.max(np.abs(np.array(options.get("start", env.params.task.start)) - target))
           >= env.params.task.accuracy)
    obs, _ = env.reset(seed=seed, options=options)
    assert env.observation_space.contains(obs)
    limits = env.params.current_limits
    wall = env.params.obstacle
    margin = Q3_RATE_BOUND * env.control_dt
    for action in actions:
        x_before, q3_before = tip_x(env), env.state[R.Q + 2]
        obs, reward, terminated, truncated, info = env.step(action)
        x = env.state
        assert obs.dtype == np.float32 and np.all(np.isfinite(obs))
        assert env.observation_space.contains(obs)
        assert np.all(np.abs(x[R.CURRENT:R.CURRENT + 3]) <= limits * (1 + 1e-12))
        assert reward == sum(info["reward_terms"][term] for term in REWARD_TERMS)
        assert not truncated
        if env.obstacle:
            x_after, q3_after = tip_x(env), x[R.Q + 2]
            if info["collision"] and env.collision_mode == "terminate":
                assert terminated and math.isclose(x_after, wall.x_position, abs_tol=1e-7)
                assert q3_after < wall.height
            crossed = (x_before - wall.x_position) * (x_after - wall.x_position) < 0
            if crossed and max(q3_before, q3_after) < wall.height - margin:
                assert info["collision"]
            if info["collision"]:
                event("a collision")
        else:
            assert not info["collision"]
        if info["is_success"]:
            event("the target reached")
        if terminated:
            break
