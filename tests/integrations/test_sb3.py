"""stable-baselines3 on the native vector environment through the adapter."""

import numpy as np
import pytest


def test_ppo_learns_on_the_native_vector_env_through_the_adapter():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from scara_gym.integrations.sb3 import SB3VecEnv

    venv = SB3VecEnv(num_envs=8, control_mode="pd", max_episode_steps=50)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=128, n_epochs=2, seed=0, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(total_timesteps=1024)
    after = list(model.policy.parameters())
    assert model.num_timesteps >= 1024
    assert len(model.ep_info_buffer) > 0  # episodes end (50-step limit): Monitor-style stats arrive
    assert any(not np.allclose(a.detach().numpy(), b.numpy()) for a, b in zip(after, before))
    obs = venv.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (8, 3) and np.all(np.abs(actions) <= 1)


def test_the_old_import_path_still_works():
    pytest.importorskip("stable_baselines3")
    from scara_gym.integrations.sb3 import SB3VecEnv
    from scara_gym.sb3 import SB3VecEnv as Old

    assert Old is SB3VecEnv
