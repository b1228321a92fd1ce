"""Sim-to-real options: sensor noise, observation noise, actuation delay, action rate limit."""

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
    out = {"obs": [obs], "true": [env.unwrapped.noise_free_observation()], "state": [], "reward": [], "end": [], "info": []}
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out["obs"].append(obs), out["true"].append(env.unwrapped.noise_free_observation())
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


SENSOR_NOISE = {"q": 1e-3, "rate": 0.01, "current3": 0.05}


def test_sensor_noise_reaches_every_entry_computed_from_the_measurements():
    """Noisy q, rates and currents; target_error, the tip, the wall distance and the height margin
    computed from the noisy q as a controller computes them; the physics untouched."""
    actions = actions_towards_target(ScaraEnv(), 300)
    clean = rollout(ScaraEnv(collision="penalty"), actions)
    env = ScaraEnv(collision="penalty", sensor_noise=SENSOR_NOISE)
    noisy = rollout(env, actions)
    for key in ("true", "state", "reward", "end"):
        np.testing.assert_array_equal(np.array(noisy[key]), np.array(clean[key]))
    obs, true = np.array(noisy["obs"], dtype=np.float64), np.array(noisy["true"], dtype=np.float64)
    L = OBSERVATION_LAYOUT
    error = obs - true
    expected = np.array([1e-3] * 3 + [0.01] * 3 + [0.0, 0.0, 0.05])
    np.testing.assert_allclose(error[:, :9].std(axis=0)[expected > 0], expected[expected > 0], rtol=0.15)
    assert np.all(error[:, :9][:, expected == 0] == 0.0)
    np.testing.assert_allclose(obs[:, L["target_error"]] + obs[:, L["q"]],  # the target, as measured q sees it
                               true[:, L["target_error"]] + true[:, L["q"]], atol=2e-6)
    p = env.params.arm
    q1, q2 = obs[:, 0], obs[:, 1]
    tip_x = p.link1_length * np.cos(q1) + p.link2_length * np.cos(q1 + q2)
    tip_y = p.link1_length * np.sin(q1) + p.link2_length * np.sin(q1 + q2)
    np.testing.assert_allclose(obs[:, L["tip_x"]], tip_x, atol=1e-6)
    np.testing.assert_allclose(obs[:, L["tip_y"]], tip_y, atol=1e-6)
    np.testing.assert_allclose(obs[:, L["wall_distance"]], tip_x - env.params.obstacle.x_position, atol=1e-6)
    np.testing.assert_allclose(obs[:, L["height_margin"]], obs[:, 2] - env.params.obstacle.height, atol=1e-6)
    assert np.std(obs[:, L["tip_x"]] - true[:, L["tip_x"]]) > 1e-4  # the noise on q reached the tip
    for name in ("critical", "time_left"):  # not measurements
        np.testing.assert_array_equal(obs[:, L[name]], true[:, L[name]])
    assert all(env.observation_space.contains(o) for o in noisy["obs"])
    again = rollout(ScaraEnv(collision="penalty", sensor_noise=SENSOR_NOISE), actions)
    np.testing.assert_array_equal(np.array(again["obs"]), np.array(noisy["obs"]))  # seeded


def test_sensor_noise_and_observation_noise_stack_in_the_vector_env():
    kwargs = dict(sensor_noise={"q": 1e-3}, observation_noise={"current": 0.01})
    venv = gym.make_vec("Scara-C11-v1", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    single = gym.make("Scara-C11-v1", **kwargs)
    obs, _ = venv.reset(seed=[5, 6])
    first, _ = single.reset(seed=6)
    np.testing.assert_array_equal(obs[1], first)  # robot i's noise from its own episode generator
    action = single.unwrapped.setpoint_to_action([0.1, 0.1, 0.1])
    obs, *_ = venv.step(np.tile(action, (2, 1)))
    np.testing.assert_array_equal(obs[1], single.step(action)[0])


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
        check_env(gym.make("Scara-C11-RandomWall-v1", **kwargs).unwrapped, skip_render_check=True)
        pytest.importorskip("stable_baselines3.common.env_checker").check_env(ScaraEnv(**kwargs), warn=True)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(observation_noise={"qq": 0.1}), ValueError, r"unknown observation_noise \['qq'\]"),
    (dict(observation_noise={"q": -0.1}), ValueError, r"observation_noise\['q'\] must be a finite number in \[0"),
    (dict(observation_noise={"q": "0.1"}), TypeError, r"observation_noise\['q'\] must be a finite number"),
    (dict(observation_noise=0.1), TypeError, "observation_noise must be a dict"),
    (dict(sensor_noise={"tip_x": 0.1}), ValueError, r"unknown sensor_noise \['tip_x'\]; allowed: \['current', 'current1', "),
    (dict(sensor_noise={"rate": -1.0}), ValueError, r"sensor_noise\['rate'\] must be a finite number in \[0"),
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
    before = env._task.actuator.pending.copy()
    with pytest.raises(ValueError, match="action must be 3 finite numbers"):
        env.step(np.array([np.nan, 0.0, 0.0], dtype=np.float32))
    np.testing.assert_array_equal(env._task.actuator.pending, before)
