"""The residual set-point as an env wrapper: the single and the vector twin act as the map does."""

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401
from scara_gym.envs.vector import ScaraVectorEnv
from scara_gym.wrappers import (
    ResidualAction,
    ResidualOnPD,
    ResidualSetpoint,
    ResidualVectorAction,
    residual_action,
    residual_setpoint,
)

SCALE, DEADZONE = (2.5, 2.5, 0.05), 0.5


def test_the_wrapper_steps_the_env_with_the_set_point_of_r_on_the_last_observation():
    """Bit for bit the env stepped with the map's action of r on the observation it returned."""
    wrapped, plain = residual_action(gym.make("Scara-C11-v2"), SCALE, DEADZONE), gym.make("Scara-C11-v2")
    assert isinstance(wrapped, ResidualAction) and wrapped.action_space == gym.spaces.Box(-1, 1, (3,), np.float32)
    mapping = ResidualSetpoint(plain, SCALE, DEADZONE)
    rng = np.random.default_rng(3)
    obs, _ = wrapped.reset(seed=5)
    expected, _ = plain.reset(seed=5)
    for _ in range(60):
        r = rng.uniform(-1, 1, 3)
        step = wrapped.step(r)
        again = plain.step(mapping(expected, r)[0])
        assert np.array_equal(step[0], again[0]) and step[1:4] == again[1:4]
        expected = again[0]
        if step[2] or step[3]:
            break


def test_the_vector_twin_maps_every_robot_on_its_own_observation_through_autoresets():
    wrapped = residual_action(ScaraVectorEnv(num_envs=4, control_mode="pd", time_limit=0.2), SCALE, DEADZONE)
    plain = ScaraVectorEnv(num_envs=4, control_mode="pd", time_limit=0.2)
    assert isinstance(wrapped, ResidualVectorAction) and wrapped.single_action_space.shape == (3,)
    mapping = ResidualSetpoint(plain, SCALE, DEADZONE)
    rng = np.random.default_rng(4)
    obs, _ = wrapped.reset(seed=7)
    expected, _ = plain.reset(seed=7)
    ended = 0
    for _ in range(45):  # past the 0.2 s limit: every robot's episode ends and restarts
        r = rng.uniform(-1, 1, (4, 3))
        obs, reward, terminated, truncated, _ = wrapped.step(r)
        expected, reward2, terminated2, truncated2, _ = plain.step(mapping(expected, r))
        assert np.array_equal(obs, expected) and np.array_equal(reward, reward2)
        assert np.array_equal(terminated, terminated2) and np.array_equal(truncated, truncated2)
        ended += int(np.sum(terminated | truncated))
    assert ended >= 4


def test_a_step_before_reset_and_a_wrong_scale_are_refused():
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        ResidualAction(gym.make("Scara-C11-v2"), SCALE).step(np.zeros(3))
    with pytest.raises(ValueError, match="residual_scale must be 3 finite numbers"):
        residual_action(gym.make("Scara-C11-v2"), (1.0, 2.0))
    assert residual_setpoint(gym.make("Scara-C11-v2"), None) is None  # a run in the env's own actions


def test_sb3s_adapter_acts_through_the_wrapper_as_the_map_would():
    """SB3VecEnv(action_wrapper=...) gives SB3 the residual's action space and the same steps as
    the map applied to the observations SB3 sees."""
    pytest.importorskip("stable_baselines3")
    from functools import partial

    from scara_gym.integrations.sb3 import SB3VecEnv

    wrapped = SB3VecEnv(num_envs=3, control_mode="pd",
                        action_wrapper=partial(residual_action, residual_scale=SCALE, deadzone=DEADZONE))
    plain = SB3VecEnv(num_envs=3, control_mode="pd")
    mapping = ResidualSetpoint(plain.venv, SCALE, DEADZONE)
    wrapped.seed(11)
    plain.seed(11)
    obs, expected = wrapped.reset(), plain.reset()
    rng = np.random.default_rng(5)
    for _ in range(30):
        r = rng.uniform(-1, 1, (3, 3)).astype(np.float32)
        obs, reward, dones, _ = wrapped.step(r)
        expected, reward2, dones2, _ = plain.step(mapping(expected, r))
        assert np.array_equal(obs, expected) and np.array_equal(reward, reward2) and np.array_equal(dones, dones2)


def test_the_residual_on_pd_is_the_pd_laws_voltage_plus_the_scaled_correction():
    env = gym.make("Scara-C11-v2", control_mode="voltage")
    obs, info = env.reset(seed=2)
    on_pd = residual_setpoint(env, (0.5, 0.25, 0.0), on="pd")
    assert isinstance(on_pd, ResidualOnPD)
    pd = env.unwrapped.pd_action(obs, info["target"])
    np.testing.assert_allclose(on_pd(obs, np.zeros(3))[0], pd, atol=1e-6)  # r = 0: PD itself (float32 obs)
    moved = on_pd(obs, np.array([1.0, -1.0, 1.0]))[0]
    np.testing.assert_allclose(moved, np.clip(on_pd(obs, np.zeros(3))[0] + [0.5, -0.25, 0.0], -1, 1))
    assert np.all(np.abs(on_pd(obs, np.full(3, 5.0))) <= 1.0)  # r clipped to [-1, 1], the action too
    with pytest.raises(ValueError, match="needs control_mode='voltage'"):
        residual_setpoint(gym.make("Scara-C11-v2"), (0.5, 0.5, 0.5), on="pd")
    with pytest.raises(ValueError, match="residual_on must be one of"):
        residual_setpoint(env, (0.5, 0.5, 0.5), on="torque")
