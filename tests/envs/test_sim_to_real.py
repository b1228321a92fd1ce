"""Sim-to-real options: observation noise, actuation delay, action rate limit."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import scara_gym  # noqa: F401
from scara_gym.envs import OBSERVATION_LAYOUT, ScaraEnv
from scara_gym.envs.task import OBSERVATION_NAMES

NOISE = {"q": 1e-3, "rate": 0.05, "current1": 0.1}


def actions_towards_target(env, steps, seed=0):
    """PD set-points near the C11 target with some jitter, beyond [-1, 1] now and then."""
    rng = np.random.default_rng(seed)
    base = env.unwrapped.setpoint_to_action([2.0, 2.0, 0.35])
    return np.clip(base + rng.normal(0.0, 0.3, size=(steps, 3)), -1.3, 1.3)


def rollout(env, actions, seed=0):
    """(observations, true observations, states, rewards, ends, infos) of one episode."""
    obs, _ = env.reset(seed=seed)
    task = env.unwrapped.task
    out = {"obs": [obs], "true": [task.obs[0].copy()], "state": [], "reward": [], "end": [], "info": []}
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out["obs"].append(obs), out["true"].append(task.obs[0].copy())
        out["state"].append(env.unwrapped.state), out["reward"].append(reward)
        out["end"].append((terminated, truncated)), out["info"].append(info)
        if terminated or truncated:
            break
    return out


def test_off_by_default_and_zero_noise_changes_nothing():
    plain = ScaraEnv()
    actions = actions_towards_target(plain, 120)
    reference = rollout(plain, actions)
    assert "applied_action" not in reference["info"][0]
    zero = rollout(ScaraEnv(observation_noise={"q": 0.0}, action_delay=0), actions)
    for key in ("obs", "state", "reward", "end"):
        np.testing.assert_array_equal(np.array(zero[key]), np.array(reference[key]))


def test_observation_noise_has_its_std_per_field_and_leaves_the_physics_alone():
    actions = actions_towards_target(ScaraEnv(), 300)
    clean = rollout(ScaraEnv(collision="penalty"), actions)
    noisy = rollout(ScaraEnv(collision="penalty", observation_noise=NOISE), actions)
    # the physics, rewards and episode ends are those of the clean env
    for key in ("true", "state", "reward", "end"):
        np.testing.assert_array_equal(np.array(noisy[key]), np.array(clean[key]))
    error = np.array(noisy["obs"], dtype=np.float64) - np.array(noisy["true"], dtype=np.float64)
    expected = np.zeros(len(OBSERVATION_NAMES))
    expected[OBSERVATION_LAYOUT["q"]] = 1e-3
    expected[OBSERVATION_LAYOUT["rate"]] = 0.05
    expected[OBSERVATION_NAMES.index("current1")] = 0.1
    noisy_entries = expected > 0
    assert np.all(error[:, ~noisy_entries] == 0.0)
    # 301 samples per entry: the sample std lies within 15 % of the std with probability > 0.99
    np.testing.assert_allclose(error[:, noisy_entries].std(axis=0), expected[noisy_entries], rtol=0.15)
    assert np.all(np.abs(error[:, noisy_entries].mean(axis=0)) < 4 * expected[noisy_entries] / np.sqrt(301))
    space = ScaraEnv(observation_noise=NOISE).observation_space
    assert all(space.contains(obs) for obs in noisy["obs"])


def test_noise_follows_the_seed():
    env = ScaraEnv(observation_noise=NOISE)
    actions = actions_towards_target(env, 50)
    first, second = rollout(env, actions, seed=3), rollout(env, actions, seed=3)
    np.testing.assert_array_equal(np.array(first["obs"]), np.array(second["obs"]))
    other = rollout(env, actions, seed=4)
    assert not np.array_equal(np.array(first["obs"][:5]), np.array(other["obs"][:5]))


def test_a_delay_of_k_steps_applies_the_action_given_k_steps_before():
    k = 3
    delayed = ScaraEnv(action_delay=k, collision="penalty")
    actions = actions_towards_target(delayed, 150)
    neutral = delayed.setpoint_to_action([0.0, 0.0, 0.0])  # the start held still
    shifted = np.vstack([np.tile(neutral, (k, 1)), np.clip(actions[:-k], -1, 1)])
    got = rollout(delayed, actions)
    want = rollout(ScaraEnv(collision="penalty"), shifted)
    n = len(got["state"])
    assert n > 100
    np.testing.assert_array_equal(np.array(got["state"]), np.array(want["state"][:n]))
    np.testing.assert_array_equal([i["applied_action"] for i in got["info"]], shifted[:n])
    # clipped components are counted on the action given, not the one applied
    assert [i["clipped_actions"] for i in got["info"]] == \
        [int(np.count_nonzero(np.abs(a) > 1)) for a in actions[:n]]


def test_the_rate_limit_bounds_the_change_of_the_applied_action():
    rate, dt = 20.0, 0.01
    env = ScaraEnv(control_mode="voltage", action_rate_limit=rate, collision="penalty")
    actions = np.random.default_rng(1).uniform(-1.0, 1.0, size=(200, 3))
    got = rollout(env, actions)
    applied = np.array([np.zeros(3)] + [i["applied_action"] for i in got["info"]])
    change = np.abs(np.diff(applied, axis=0))
    assert change.max() <= rate * dt + 1e-12
    assert np.isclose(change.max(), rate * dt)  # the limit binds with these actions
    # the robot applied exactly those actions
    want = rollout(ScaraEnv(control_mode="voltage", collision="penalty"), applied[1:])
    np.testing.assert_array_equal(np.array(got["state"]), np.array(want["state"]))


def test_same_step_autoreset_keeps_the_options_per_robot():
    kwargs = dict(control_mode="pd", observation_noise=NOISE, action_delay=1, action_rate_limit=50.0)
    venv = gym.make_vec("Scara-C11-v1", num_envs=2, vectorization_mode="vector_entry_point",
                        autoreset_mode="SameStep", **kwargs)
    obs, _ = venv.reset(seed=5)
    singles = [gym.make("Scara-C11-v1", **kwargs) for _ in range(2)]
    single_obs = [env.reset(seed=5 + i)[0] for i, env in enumerate(singles)]
    np.testing.assert_array_equal(obs, np.array(single_obs))
    action = np.tile(singles[0].unwrapped.setpoint_to_action([2.0, 2.0, 0.3]), (2, 1))  # hits the wall
    for _ in range(100):
        obs, reward, terminated, truncated, info = venv.step(action)
        for i, env in enumerate(singles):
            o, r, te, tr, single_info = env.step(action[i])
            np.testing.assert_array_equal(info["applied_action"][i], single_info["applied_action"])
            if te or tr:
                np.testing.assert_array_equal(info["final_obs"][i], o)
                o, _ = env.reset()  # the robot's generator goes on, as the vector env's does
            np.testing.assert_array_equal(obs[i], o)
        if terminated.any():
            break
    assert terminated.all()


def test_envs_with_the_options_pass_the_checkers():
    kwargs = dict(observation_noise=NOISE, action_delay=2, action_rate_limit=10.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gym.make("Scara-C11-RandomWall-v0", **kwargs).unwrapped, skip_render_check=True)
        pytest.importorskip("stable_baselines3.common.env_checker").check_env(ScaraEnv(**kwargs), warn=True)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(observation_noise={"qq": 0.1}), ValueError, r"unknown observation_noise \['qq'\]"),
    (dict(observation_noise={"q": -0.1}), ValueError, r"observation_noise\['q'\] must be a finite number in \[0"),
    (dict(observation_noise={"q": "0.1"}), TypeError, r"observation_noise\['q'\] must be a finite number"),
    (dict(observation_noise=0.1), TypeError, "observation_noise must be a dict"),
    (dict(action_delay=-1), ValueError, r"action_delay must be an integer in \[0, 100\]"),
    (dict(action_delay=1.5), TypeError, r"action_delay must be an integer in \[0, 100\]"),
    (dict(action_rate_limit=0.0), ValueError, r"action_rate_limit must be a finite number in \[1e-06"),
    (dict(action_rate_limit=float("nan")), ValueError, "action_rate_limit must be a finite number"),
])
def test_bad_options_are_named(kwargs, error, match):
    with pytest.raises(error, match=match):
        ScaraEnv(**kwargs)


def test_a_bad_action_changes_nothing_in_the_delay_line():
    env = ScaraEnv(action_delay=2)
    env.reset(seed=0)
    before = env.task.actuator.pending.copy()
    with pytest.raises(ValueError, match="action must be 3 finite numbers"):
        env.step(np.array([np.nan, 0.0, 0.0], dtype=np.float32))
    np.testing.assert_array_equal(env.task.actuator.pending, before)
