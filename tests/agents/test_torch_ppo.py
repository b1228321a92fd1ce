"""agents.algorithms.torch_ppo: the single-file PPO trains, checkpoints, resumes and is evaluated."""

import dataclasses
import json

import gymnasium as gym
import numpy as np
import pytest
import torch

import scara_gym  # noqa: F401
from agents.algorithms.torch_ppo import (
    Adam,
    Agent,
    Config,
    RunningMeanStd,
    make_env,
    ppo_gradients,
    ppo_loss,
    train,
)
from agents.algorithms.torch_ppo_config import parse_reward_weights
from agents.algorithms.torch_ppo_hooks import DemoCloning, DemoResets, Lagrangian, ShieldedActions, TargetReplay
from agents.cli import run
from agents.experiments.evaluation import make_policy
from agents.policies import run_episode
from scara_gym.wrappers import residual_setpoint


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


@pytest.mark.parametrize("spread", [0.01, 0.5])  # old log probs near the new ones, and far: clipped
def test_the_written_out_gradient_is_autograds(spread):
    torch.manual_seed(0)
    agent = Agent(18, 3, 16, 10.0)
    with torch.no_grad():
        agent.actor_logstd.copy_(torch.tensor([-0.5, 0.0, 0.3]))
        for bias in agent.biases:
            bias.normal_(0.0, 0.3)
        agent.weights[-1].normal_(0.0, 0.3)  # the init's 0.01-gain actor head leaves the chain rule untested
    config = Config(ent_coef=0.01, vf_coef=0.7, clip_coef=0.2)
    x, actions = torch.randn(64, 18), torch.randn(64, 3)
    with torch.no_grad():
        _, logprob, _, _ = agent.act(x, actions)
    old_logprobs = logprob + spread * torch.randn(64)
    advantages, returns = torch.randn(64), torch.randn(64)
    loss = ppo_loss(agent, x, actions, old_logprobs, advantages, returns, config)
    names, parameters = zip(*agent.named_parameters())
    expected = dict(zip(names, torch.autograd.grad(loss, parameters)))
    grads, (policy_loss, value_loss, clip_fraction) = ppo_gradients(agent, x, actions, old_logprobs, advantages,
                                                                     returns, config, with_stats=True)
    assert grads.keys() == expected.keys()
    without_stats = ppo_gradients(agent, x, actions, old_logprobs, advantages, returns, config)
    assert without_stats[1] is None and without_stats[0].keys() == expected.keys()
    for name, reference in expected.items():
        grad = grads[name]
        assert grad.shape == reference.shape
        assert torch.allclose(grad, reference, rtol=1e-4, atol=1e-6), (grad - reference).abs().max()
    assert (clip_fraction > 0.3) == (spread > 0.1)  # the far case exercises the clipped branch
    entropy = (agent.actor_logstd + 0.5 + 0.5 * np.log(2 * np.pi)).sum()
    assert torch.allclose(policy_loss + config.vf_coef * value_loss - config.ent_coef * entropy, loss.detach())


def test_adam_takes_torch_optims_steps_and_resumes():
    torch.manual_seed(0)
    mine, reference = [torch.randn(4, 3), torch.randn(5)], [torch.nn.Parameter(torch.randn(4, 3)), torch.nn.Parameter(torch.randn(5))]
    with torch.no_grad():
        torch._foreach_copy_(mine, reference)
    adam = Adam(mine, lr=3e-3, eps=1e-5)
    optimizer = torch.optim.Adam(reference, lr=3e-3, eps=1e-5)
    for step in range(6):
        grads = [torch.randn(4, 3), torch.randn(5)]
        if step == 3:  # a new Adam from the saved state carries on as the old one would
            state = adam.state_dict()
            adam = Adam(mine, lr=1.0, eps=1e-5)
            adam.load_state_dict(state)
        adam.step([g.clone() for g in grads])
        for parameter, grad in zip(reference, grads):
            parameter.grad = grad
        optimizer.step()
    assert adam.steps == 6
    for a, b in zip(mine, reference):
        assert torch.allclose(a, b, rtol=1e-6, atol=1e-7)
        assert not torch.equal(a, torch.zeros_like(a))


def test_reward_weights_reach_the_env_and_bad_ones_are_named():
    assert parse_reward_weights("") == {}
    assert parse_reward_weights("energy=0.05, time=20") == {"energy": 0.05, "time": 20.0}
    envs = make_env(Config(num_envs=2, reward_weights={"energy": 0.05, "time": 20.0}))
    weights = envs.unwrapped.reward_weights
    assert (weights.energy, weights.time, weights.collision) == (0.05, 20.0, 50.0)  # the rest: the env's
    with pytest.raises(ValueError, match="reward_weights: expected name=number"):
        parse_reward_weights("energy")
    with pytest.raises(ValueError, match="reward_weights.*energi"):
        make_env(Config(num_envs=2, reward_weights={"energi": 1.0}))


def test_the_protocols_training_distribution_reaches_the_env():
    from scara_gym.benchmark.protocol import SENSOR_NOISE, START_OFFSETS

    task = make_env(Config(num_envs=2, randomize_start=True, sensor_noise=2.0)).unwrapped._task
    assert task.start_region is START_OFFSETS
    assert task.sim_to_real.sensor_std.tolist() == [2 * SENSOR_NOISE["q"]] * 3 + [2 * SENSOR_NOISE["rate"]] * 3 + \
        [2 * SENSOR_NOISE["current"]] * 3
    plain = make_env(Config(num_envs=2)).unwrapped._task
    assert plain.start_region is None and not plain.sim_to_real.noisy


@pytest.mark.slow
def test_a_tiny_run_trains_resumes_and_is_evaluated(tmp_path):
    out = tmp_path / "run"
    config = Config(num_envs=4, num_steps=16, num_minibatches=2, update_epochs=2, total_timesteps=128,
                    checkpoint_every=1, out=str(out))
    first = train(config)
    assert first["global_step"] == 128
    before = torch.load(out / "model.pt", weights_only=False)["state_dict"]
    # resume: two more updates from the checkpoint, not from scratch
    run(["torch-ppo", "--num-envs", "4", "--num-steps", "16", "--num-minibatches", "2", "--update-epochs", "2",
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


def test_a_run_starts_from_another_runs_policy_with_init_from(tmp_path):
    source, tuned = tmp_path / "source", tmp_path / "tuned"
    tiny = dict(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16)
    train(Config(**tiny, out=str(source)))
    # with a zero learning rate the fine-tuned weights are the source's (its own observations
    # move only the normalizer, a buffer)
    train(Config(**tiny, learning_rate=0.0, seed=5, init_from=str(source), reward_weights={"energy": 0.05},
                 out=str(tuned)))
    saved = {run: torch.load(run / "model.pt", weights_only=False)["state_dict"] for run in (source, tuned)}
    parameters = [name for name, _ in Agent(18, 3, 64, 10.0).named_parameters()]
    assert all(torch.equal(saved[source][name], saved[tuned][name]) for name in parameters)
    fresh = tmp_path / "fresh"
    train(Config(**tiny, learning_rate=0.0, seed=5, out=str(fresh)))
    fresh_weights = torch.load(fresh / "model.pt", weights_only=False)["state_dict"]
    assert not all(torch.equal(saved[source][name], fresh_weights[name]) for name in parameters)
    with pytest.raises(ValueError, match=r"init_from: .* sizes \(18, 3, 64\), this run \(18, 3, 32\)"):
        train(Config(**tiny, hidden_size=32, init_from=str(source), out=str(tmp_path / "other")))
    with pytest.raises(FileNotFoundError, match="init_from: no model.pt"):
        train(Config(**tiny, init_from=str(tmp_path / "nowhere"), out=str(tmp_path / "other2")))


def test_the_residual_set_point_option_acts_around_the_target_in_training_and_evaluation(tmp_path):
    from agents.algorithms.torch_ppo import TorchPPOPolicy
    from scara_gym.wrappers import ResidualSetpoint

    out = tmp_path / "run"
    train(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16, randomize_target=True,
                 residual_scale=(2.5, 2.5, 0.05), residual_deadzone=0.5, out=str(out)))
    env = gym.make("Scara-C11-v1", randomize_target=True)
    obs, info = env.reset(seed=7)
    policy = TorchPPOPolicy(env, out)
    with torch.no_grad():
        mean = policy.agent.heads(policy.agent.normalize(torch.as_tensor(obs)[None]))[0][0].clamp(-1, 1).numpy()
    mapping = ResidualSetpoint(env.unwrapped, [2.5, 2.5, 0.05], 0.5)
    assert np.array_equal(policy(obs), mapping(obs, mean.astype(np.float64))[0])
    # inside the dead zone the set-point is the target itself, read from the observation
    inside = mapping(obs, np.array([0.3, -0.49, 0.0]))[0]
    np.testing.assert_allclose(env.unwrapped.action_to_setpoint(inside), info["target"], atol=1e-6)
    with pytest.raises(ValueError, match="residual_scale must be 3 finite numbers"):
        residual_setpoint(env.unwrapped, (1.0, 2.0), 0.5)
    with pytest.raises(ValueError, match="residual_scale: expected 3 numbers"):
        Config.from_dict({"residual_scale": "a,b,c"})
    legacy = Config.from_dict({"residual_scale": "2.5,2.5,0.05", "reward_weights": "time=20", "init_from": ""})
    assert legacy.residual_scale == (2.5, 2.5, 0.05) and legacy.reward_weights == {"time": 20.0}
    assert legacy.init_from is None


def test_the_residual_on_pd_trains_and_acts_on_the_pd_laws_voltages(tmp_path):
    """residual_on='pd' (the interface ablation's third interface): trained and evaluated through
    ResidualOnPD in "voltage" mode; refused in "pd" mode before anything trains."""
    from agents.algorithms.torch_ppo import TorchPPOPolicy
    from scara_gym.wrappers import ResidualOnPD

    out = tmp_path / "run"
    train(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16,
                 control_mode="voltage", residual_scale=(0.5, 0.5, 0.5), residual_on="pd", out=str(out)))
    env = gym.make("Scara-C11-v2", control_mode="voltage")
    obs, _ = env.reset(seed=3)
    policy = TorchPPOPolicy(env, out)
    with torch.no_grad():
        mean = policy.agent.heads(policy.agent.normalize(torch.as_tensor(obs)[None]))[0][0].clamp(-1, 1).numpy()
    assert np.array_equal(policy(obs), ResidualOnPD(env, (0.5, 0.5, 0.5))(obs, mean.astype(np.float64))[0])
    with pytest.raises(ValueError, match="residual_on='pd' corrects the PD law's voltages"):
        Config(residual_scale=(0.5, 0.5, 0.5), residual_on="pd")


def test_demo_resets_start_episodes_on_the_reference_path_and_training_uses_them(tmp_path):
    config = Config(num_envs=8, demo_resets=1.0)
    envs = make_env(config)
    obs, _ = envs.reset(seed=0)
    resets = DemoResets(envs, config)
    moved = resets(obs.copy(), range(8))
    times = {round(s["t"], 6): s for s in resets.snapshots}
    for i in range(8):  # each robot stands where the reference stood at some step, and sees it
        state = envs.unwrapped.snapshot(i)
        assert np.array_equal(state["x"], times[round(state["t"], 6)]["x"])
        assert np.array_equal(moved[i], envs.unwrapped.noise_free_observation(i))
    assert moved[:, -1].max() < 1.0  # time_left: no robot at the start
    none = DemoResets(envs, Config(num_envs=8, demo_resets=0.0))
    assert np.array_equal(none(obs.copy(), range(8)), obs)
    with pytest.raises(ValueError, match=r"demo_resets must be .*in \[0, 1\]"):
        DemoResets(envs, Config(demo_resets=1.5))
    with pytest.raises(ValueError, match="without randomize_target"):
        DemoResets(envs, Config(demo_resets=0.5, randomize_target=True))
    out = tmp_path / "rsi"
    train(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=32, demo_resets=0.5,
                 residual_scale=(2.5, 2.5, 0.05), residual_deadzone=0.5, out=str(out)))
    assert json.loads((out / "config.json").read_text())["demo_resets"] == 0.5


def test_target_replay_gives_new_episodes_the_failed_targets_until_they_succeed(tmp_path):
    config = Config(num_envs=4, randomize_target=True, target_replay=1.0)
    envs = make_env(config)
    obs, _ = envs.reset(seed=0)
    targets = lambda: envs.unwrapped.targets  # noqa: E731
    replay = TargetReplay(envs, config)
    first = targets()
    no, yes, rng = np.zeros(4, dtype=bool), np.ones(4, dtype=bool), np.random.default_rng(5)
    assert np.array_equal(replay(obs.copy(), range(4), yes, no), obs)  # nothing failed yet: the targets stay

    def ended(rows, success, collided):  # what the autoreset does before the replay: fresh targets
        for i in rows:
            envs.unwrapped.reset_robot(i, rng=rng)
        return replay(obs.copy(), rows, success, collided)

    moved = ended([0], no, no)  # robot 0 stopped short on first[0]: its next episode is on it again
    assert np.array_equal(targets()[0], first[0]) and len(replay.failed) == 1
    assert np.array_equal(moved[0], envs.unwrapped.noise_free_observation(0))  # it sees its new episode
    assert np.array_equal(moved[1:], obs[1:])
    ended([0], yes, no)  # ... and succeeds there: the target leaves, the fresh draw stays
    assert replay.failed == [] and not np.array_equal(targets()[0], first[0])
    ended([1, 2], yes, yes)  # collisions count as failures
    assert len(replay.failed) == 2 and np.array_equal(targets()[1], first[1])
    ended([1], no, no)  # failing again on a replayed target keeps one entry of it
    assert len(replay.failed) == 2
    with pytest.raises(ValueError, match=r"target_replay must be .*in \[0, 1\]"):
        TargetReplay(envs, Config(randomize_target=True, target_replay=2.0))
    with pytest.raises(ValueError, match="randomize_target=True"):
        TargetReplay(envs, Config(target_replay=0.5))
    out = tmp_path / "replay"
    train(Config(num_envs=2, num_steps=64, num_minibatches=1, update_epochs=1, total_timesteps=256,
                 randomize_target=True, target_replay=0.5, out=str(out)))
    assert json.loads((out / "config.json").read_text())["target_replay"] == 0.5


def test_a_shielded_run_applies_the_shields_actions_and_acts_behind_it_in_evaluation(tmp_path, monkeypatch):
    """PD drives the C11 arm into the wall by step ~40; the residual agent starts as PD (its
    outputs inside the dead zone), so a shielded run must be overruled there, and never collide."""
    import agents.algorithms.torch_ppo as torch_ppo
    from scara_gym.wrappers import Shield

    calls, replaced, collisions = [0], [0], [0]
    filter_ = Shield.filter

    def counting_filter(self, task, index, action):
        out = filter_(self, task, index, action)
        calls[0] += 1
        replaced[0] += out[1]
        return out

    def counting_env(config):
        envs = make_env(config)
        step = envs.step

        def counted_step(action):
            result = step(action)
            collisions[0] += int(np.sum(result[4]["collisions"] > 0))
            return result
        envs.step = counted_step
        return envs

    monkeypatch.setattr(Shield, "filter", counting_filter)
    monkeypatch.setattr(torch_ppo, "make_env", counting_env)
    out = tmp_path / "run"
    train(Config(num_envs=2, num_steps=64, num_minibatches=1, update_epochs=1, total_timesteps=128,
                 residual_scale=(2.5, 2.5, 0.05), residual_deadzone=0.5, shield=True, out=str(out)))
    assert calls[0] == 128 and replaced[0] > 0 and collisions[0] == 0
    env = gym.make("Scara-C11-v1")
    policy = make_policy(f"torchppo:{out}", env)
    assert policy.shield is not None
    result = run_episode(env, policy, seed=0)
    assert result["collisions"] == 0
    with pytest.raises(ValueError, match="shield: the shield's model runs on the CPU"):
        ShieldedActions(Config(shield=True, device="cuda"))


def test_the_lagrangian_penalizes_the_cost_and_follows_dual_ascent_on_the_episode_cost():
    """lambda x cost comes off each step's reward; after a rollout, lambda moves by lagrange_lr x
    (mean cost of the episodes that ended - cost_limit) and never below 0."""
    hook = Lagrangian(Config(cost_limit=0.5, lagrange_lr=0.1, lagrange_init=0.2))
    no, yes = np.array([False, False]), np.array([True, False])
    hook.on_step(None, None, None, no, no, {"cost": np.array([1.0, 0.0])})
    assert torch.equal(hook.shape_reward(torch.tensor([1.0, 1.0], dtype=torch.float64), {}),
                       torch.tensor([0.8, 1.0], dtype=torch.float64))
    hook.on_step(None, None, None, yes, no, {"cost": np.array([1.0, 1.0])})  # robot 0's episode: cost 2
    hook.on_step(None, None, None, no, yes[::-1], {"cost": np.array([0.0, 0.0])})  # robot 1's: cost 1
    hook.on_rollout_end()
    assert hook.mean_cost == 1.5 and hook.multiplier == pytest.approx(0.2 + 0.1 * (1.5 - 0.5))
    hook.on_rollout_end()  # no episode ended since: lambda stays
    assert hook.multiplier == pytest.approx(0.3)
    for _ in range(10):  # robot 0's next episodes cost nothing: lambda falls by 0.05 each, to 0, not below
        hook.on_step(None, None, None, yes, no, {"cost": np.array([0.0, 0.0])})
        hook.on_rollout_end()
    assert hook.multiplier == 0.0 and hook.episode_cost[0] == 0.0 and hook.episode_cost[1] == 0.0
    with pytest.raises(ValueError, match="cost_limit"):
        Config(cost_limit=-1.0)


def test_a_lagrangian_run_keeps_its_multiplier_in_the_checkpoint_and_resumes_from_it(tmp_path):
    out = tmp_path / "run"
    config = Config(num_envs=4, num_steps=16, num_minibatches=2, update_epochs=1, total_timesteps=128,
                    checkpoint_every=1, cost_limit=0.0, lagrange_init=0.3, out=str(out))
    first = Lagrangian(config)
    train(config, hooks=[first])
    assert first.multiplier >= 0.3  # with cost_limit 0 it never falls
    kept = torch.load(out / "checkpoint.pt", weights_only=True)["hooks"]
    assert kept == [{"multiplier": first.multiplier}]
    loaded = []

    class Recorded(Lagrangian):
        def load_state_dict(self, state: dict) -> None:
            loaded.append(state["multiplier"])
            super().load_state_dict(state)

    train(dataclasses.replace(config, total_timesteps=192), resume=True, hooks=[Recorded(config)])
    assert loaded == [first.multiplier]


def test_the_residual_maps_inverse_replays_the_optimal_reference():
    from agents.policies.optimal import reference_demonstration, replaying
    from scara_gym.wrappers import ResidualSetpoint

    observations, actions = reference_demonstration(wall_margin=0.008)
    env = gym.make("Scara-C11-v1", control_mode="voltage")
    mapping = ResidualSetpoint(env.unwrapped, [2.5, 2.5, 0.05], 0.5)
    outputs = mapping.agent_actions(observations, actions)
    assert outputs.shape == actions.shape and np.all(np.abs(outputs) <= 1.0)
    obs, _ = env.reset(seed=0)
    for output in outputs:
        obs, _, terminated, truncated, info = env.step(mapping(obs, output)[0])
        if terminated or truncated:
            break
    replayed = run_episode(*replaying(actions, "Scara-C11-v1", (0, 0, 0), (2, 2, 0.3), scara_gym.DEFAULT_PARAMS),
                           seed=0)
    assert info["is_success"] and info["collisions"] == 0
    assert abs(info["reach_time"] - replayed["reach_time"]) < 1e-6 and replayed["reach_time"] < 1.23
    # "pd" mode: the inverse of the map's own outputs outside the dead zone is the output itself
    pd_env = gym.make("Scara-C11-v1")
    pd_mapping = ResidualSetpoint(pd_env.unwrapped, [2.5, 2.5, 0.05], 0.5)
    obs, _ = pd_env.reset(seed=0)
    r = np.array([[0.7, -0.6, 0.7], [-0.9, 0.55, -1.0]])  # set-points inside the "pd" range
    np.testing.assert_allclose(pd_mapping.agent_actions(np.stack([obs, obs]), pd_mapping(np.stack([obs, obs]), r)),
                               r, atol=1e-9)


def test_demo_cloning_starts_the_policy_on_the_reference_and_checks_its_arguments(tmp_path):
    config = Config(control_mode="voltage", residual_scale=(2.5, 2.5, 0.05), residual_deadzone=0.5, demo_bc=1.0,
                    demo_bc_decay=0.5, demo_bc_pretrain=300, demo_wall_margin=0.008, init_log_std=-1.0,
                    num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=32,
                    out=str(tmp_path / "run"))
    envs = make_env(config)
    cloning = DemoCloning(envs, config, residual_setpoint(envs.unwrapped, config.residual_scale, config.residual_deadzone))
    assert cloning.weight(1) == 1.0 and cloning.weight(3) == 0.25
    agent = Agent(18, 3, 64, 10.0)
    with torch.no_grad():
        before = ((agent.heads(agent.normalize(cloning.obs))[0] - cloning.actions) ** 2).sum(-1).mean().item()
    after = cloning.pretrain(agent, 300, 1e-3)
    assert after < 0.1 * before
    train(config)
    saved = torch.load(tmp_path / "run" / "model.pt", weights_only=False)["state_dict"]
    assert saved["actor_logstd"].max() < -0.9  # init_log_std, moved by two small updates at most
    for bad, match in ((dict(demo_bc=-1.0), "demo_bc must be .*>= 0"), (dict(demo_bc_decay=0.0), "demo_bc_decay"),
                       (dict(control_mode="pd"), "control_mode='voltage'"), (dict(residual_scale=None), "residual_scale"),
                       (dict(randomize_target=True), "randomize_target")):
        with pytest.raises(ValueError, match=match):  # the Config refuses what it can tell alone
            wrong = Config(**{**dataclasses.asdict(config), **bad})
            DemoCloning(make_env(wrong), wrong,
                        residual_setpoint(make_env(wrong).unwrapped, wrong.residual_scale, wrong.residual_deadzone))


STEPS_DIGESTS = {
    "plain": ("98d02c9383f2b9786cb8d7e5ab778084aab7c87e27980c3fde4820523f8f3f7d",
              "7e02117f30067e16e73cac3f9c27a16e26288a0cf80d51a8780c7ccd9e6a901b"),
    "hooks": ("b4d1c1cd533687db2e1584c3a3b4103102aca302b530d90967b53f4ec7c52e84",
              "ca56f1a61e3fb647f34a85bda8720590eec4013b85c340891c5e9449bf815a78"),
}
"""SHA-256 of the saved policy's tensors after the short runs below, recorded at commit 4e2a39a
(before ``_train`` was split into its rollout, advantages and update steps, issue 55 item 4). One
digest per CPU family the project's machines have: torch's float32 kernels take other paths on
another CPU (the first pair on the machine that recorded them, the second on an AMD EPYC, where
commit 93cc828 and its successors give the same second pair); a change of the loop's steps gives
neither."""


@pytest.mark.parametrize("name, extra", [
    ("plain", {}),
    ("hooks", {"demo_resets": 0.5, "demo_bc": 0.1, "control_mode": "voltage", "residual_scale": (0.1, 0.1, 0.1)}),
])
def test_a_short_run_takes_the_same_steps_bit_for_bit(tmp_path, name, extra):
    """The training loop's steps are those of the single 182-line ``_train`` of commit 4e2a39a:
    a short run (3 updates, one torch thread, a fixed seed; with and without the research hooks,
    the residual set-point and episodes that end) leaves the same parameters to the bit."""
    import hashlib

    config = Config(num_envs=4, num_steps=32, total_timesteps=384, num_minibatches=4, update_epochs=2,
                    hidden_size=16, torch_threads=1, seed=3, checkpoint_every=2, out=str(tmp_path / name), **extra)
    train(config)
    state = torch.load(tmp_path / name / "model.pt", weights_only=False)["state_dict"]
    digest = hashlib.sha256()
    for key in sorted(state):
        digest.update(key.encode() + state[key].numpy().tobytes())
    assert digest.hexdigest() in STEPS_DIGESTS[name]
