"""agents.torch_ppo: the single-file PPO trains, checkpoints, resumes and is evaluated."""

import json

import gymnasium as gym
import numpy as np
import pytest
import torch

import scara_gym  # noqa: F401
from agents.evaluate import make_policy
from agents.policies import run_episode
from agents.torch_ppo import Agent, Config, RunningMeanStd, main, train


def test_running_mean_std_matches_the_batch_statistics():
    rms = RunningMeanStd((3,))
    data = torch.from_numpy(np.random.default_rng(0).normal(2.0, 3.0, (1000, 3)))
    for chunk in data.split(97):
        rms.update(chunk)
    assert np.allclose(rms.mean.numpy(), data.mean(0).numpy(), atol=1e-6)
    assert np.allclose(rms.var.numpy(), data.var(0, unbiased=False).numpy(), rtol=1e-3)


def test_the_log_probability_is_the_gaussian_one():
    agent = Agent(18, 3, 16, 10.0)
    with torch.no_grad():
        agent.actor_logstd.copy_(torch.tensor([-0.5, 0.0, 0.3]))
    x = torch.randn(5, 18)
    action, log_prob, entropy, value = agent.act(x)
    mean, _ = agent.heads(x)
    reference = torch.distributions.Normal(mean, agent.actor_logstd.exp())
    assert torch.allclose(log_prob, reference.log_prob(action).sum(-1), atol=1e-5)
    assert torch.allclose(entropy, reference.entropy().sum(-1), atol=1e-5)
    assert value.shape == (5,)


@pytest.mark.slow
def test_a_tiny_run_trains_resumes_and_is_evaluated(tmp_path):
    out = tmp_path / "run"
    config = Config(num_envs=4, num_steps=16, num_minibatches=2, update_epochs=2, total_timesteps=128,
                    checkpoint_every=1, out=str(out))
    first = train(config)
    assert first["global_step"] == 128
    before = torch.load(out / "model.pt", weights_only=False)["state_dict"]
    # resume: two more updates from the checkpoint, not from scratch
    main(["--num-envs", "4", "--num-steps", "16", "--num-minibatches", "2", "--update-epochs", "2",
          "--total-timesteps", "256", "--checkpoint-every", "1", "--out", str(out), "--resume"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["global_step"] == 256
    after = torch.load(out / "model.pt", weights_only=False)["state_dict"]
    assert any(not torch.equal(before[k], after[k]) for k in before)
    assert list((out / "tb").glob("events.out.tfevents.*")), "no TensorBoard log"
    env = gym.make("Scara-C11-v1")
    policy = make_policy(f"torchppo:{out}", env)
    result = run_episode(env, policy, seed=1000)
    assert result["steps"] > 0 and np.isfinite(result["return"])
    with pytest.raises(ValueError, match="trained in 'pd' mode"):
        make_policy(f"torchppo:{out}", gym.make("Scara-C11-v1", control_mode="voltage"))
