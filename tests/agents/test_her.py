"""agents.algorithms.sb3.her: the HER buffer that keeps only the info entries compute_reward reads."""

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
from stable_baselines3 import HerReplayBuffer  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv  # noqa: E402

import scara_gym  # noqa: E402,F401
from agents.algorithms.sb3.her import KeptInfoHerReplayBuffer  # noqa: E402


def _filled(buffer_class, steps=400, **kwargs):
    """A buffer filled with the same transitions: the PD set-point straight at the goal, so the
    arm passes through the wall (collision="penalty") and some steps carry a collision cost."""
    env = DummyVecEnv([lambda: gym.make("Scara-C11-Goal-v0", reward_type="dense", collision="penalty",
                                        collision_penalty=400.0, max_episode_steps=120)])
    env.seed(0)
    buffer = buffer_class(2_000, env.observation_space, env.action_space, env=env, n_sampled_goal=4,
                          goal_selection_strategy="future", copy_info_dict=True, **kwargs)
    obs = env.reset()
    task = env.envs[0].unwrapped
    for _ in range(steps):
        action = np.array([task.setpoint_to_action(goal) for goal in obs["desired_goal"]])
        next_obs, reward, done, infos = env.step(action.astype(np.float32))
        buffer.add(obs, next_obs, action, reward, done, infos)
        obs = next_obs
    return buffer


def test_relabeled_rewards_are_sb3s_with_only_the_cost_kept():
    stock = _filled(HerReplayBuffer)
    kept = _filled(KeptInfoHerReplayBuffer, info_keys=["cost"])
    stored = [info for info in kept.infos[:kept.pos, 0]]
    assert all(set(info) == {"cost"} for info in stored)
    assert any(info["cost"] > 0 for info in stored), "the scripted path must cross the wall"
    assert len(stock.infos[0, 0]) > 5  # SB3's buffer holds the whole step info
    np.random.seed(0)
    expected = stock.sample(512)
    np.random.seed(0)
    got = kept.sample(512)
    np.testing.assert_array_equal(got.rewards.numpy(), expected.rewards.numpy())
    np.testing.assert_array_equal(got.observations["desired_goal"].numpy(),
                                  expected.observations["desired_goal"].numpy())
    assert (got.rewards.numpy() < -100).any(), "some sampled transitions pay the collision term"


def test_info_keys_must_be_in_the_step_info_and_need_copy_info_dict():
    with pytest.raises(KeyError, match="info_keys: the step info has no \\['power'\\]"):
        _filled(KeptInfoHerReplayBuffer, steps=2, info_keys=["power"])
    env = DummyVecEnv([lambda: gym.make("Scara-C11-Goal-v0")])
    with pytest.raises(ValueError, match="copy_info_dict=True"):
        KeptInfoHerReplayBuffer(100, env.observation_space, env.action_space, env=env, info_keys=["cost"])
