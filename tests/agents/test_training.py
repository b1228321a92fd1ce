"""Resumable SB3 training (agents.algorithms.sb3.training) and the hyperparameter files of the baselines."""

import json
import os

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401

pytest.importorskip("stable_baselines3")
from agents import files  # noqa: E402
from agents.algorithms.sb3 import training  # noqa: E402
from agents.algorithms.sb3.hyperparams import load_hyperparams  # noqa: E402
from agents.algorithms.sb3.policy import SB3Policy  # noqa: E402
from agents.policies import run_episode  # noqa: E402


@pytest.mark.parametrize("algo", training.ALGORITHMS)
@pytest.mark.parametrize("control_mode", ["pd", "voltage"])
def test_every_hyperparameter_block_builds_its_algorithm(algo, control_mode):
    hyper = load_hyperparams(algo, "Scara-C11-v1", control_mode)
    assert hyper.get("env_kwargs", {}) == {}  # the standard baselines: the env as users get it
    train_env, eval_env = training.make_envs("Scara-C11-v1", {"control_mode": control_mode},
                                             {**hyper, "n_envs": 4}, seed=0)
    model = training.algorithm_class(algo)("MlpPolicy", train_env, device="cpu",
                                           **training.algorithm_kwargs(algo, hyper, 3))
    assert model.gamma == hyper["gamma"]
    with pytest.raises(KeyError, match="no sac hyperparameters"):
        load_hyperparams("sac", "Scara-C11-v0", control_mode)


def _tiny(algo, library="sb3"):
    hyper = load_hyperparams(algo)
    hyper.update(n_envs=2, eval_freq=100, eval_episodes=1, snapshot_freq=100, library=library)
    if algo == "ppo":
        hyper.update(n_steps=50, batch_size=50, n_epochs=1)
    else:
        hyper.update(learning_starts=50, buffer_size=1000)
    return hyper


@pytest.mark.parametrize("algo, library", [("ppo", "sb3"), ("td3", "sb3"), ("sac", "sbx"), ("tqc", "sbx")])
def test_an_interrupted_run_resumes_from_its_snapshot(algo, library, tmp_path, monkeypatch):
    """sbx's JAX SAC goes through the same snapshots, manifests, resume and evaluation as SB3's."""
    if library != "sb3":
        pytest.importorskip(library)
    out = tmp_path / algo
    tiny = _tiny(algo, library)
    make_snapshot = training._snapshot_callback

    def interrupting(*args):
        callback = make_snapshot(*args)
        save = callback.save

        def save_then_stop():
            save()
            if callback.num_timesteps >= 200:
                raise KeyboardInterrupt  # the session ends right after a snapshot
        callback.save = save_then_stop
        return callback

    monkeypatch.setattr(training, "_snapshot_callback", interrupting)
    with pytest.raises(KeyboardInterrupt):
        training.train(algo, out, hyperparams=tiny, total_timesteps=400)
    assert (out / "snapshot" / "progress.json").exists() and not (out / "config.json").exists()
    stopped_at = json.loads((out / "snapshot" / "progress.json").read_text())["num_timesteps"]
    monkeypatch.setattr(training, "_snapshot_callback", make_snapshot)

    with pytest.raises(ValueError, match="holds this run already; resume=True"):
        training.train(algo, out, hyperparams=tiny, total_timesteps=400)
    with pytest.raises(ValueError, match=r"holds another run \(gamma 0\.\d+ \(this run: 0\.5\)\)"):
        training.train(algo, out, hyperparams={**tiny, "gamma": 0.5}, total_timesteps=400, resume=True)
    trusted_here = os.environ[files.TRUST_STORE_ENV]
    monkeypatch.setenv(files.TRUST_STORE_ENV, str(tmp_path / "another-machine"))  # a snapshot from elsewhere
    with pytest.raises(files.UntrustedFolder, match="snapshot: its pickle files"):
        training.train(algo, out, hyperparams=tiny, total_timesteps=400, resume=True)
    monkeypatch.setenv(files.TRUST_STORE_ENV, trusted_here)
    training.train(algo, out, hyperparams=tiny, total_timesteps=400, resume=True)
    config = json.loads((out / "config.json").read_text())
    assert config["resumed"] and config["total_timesteps"] == 400
    assert not (out / "snapshot").exists()
    history = np.load(out / "eval" / "evaluations.npz")
    steps = history["timesteps"]
    assert np.all(np.diff(steps) > 0) and steps[0] <= stopped_at < steps[-1]  # one curve across the break
    assert history["results"].shape == (len(steps), 1)
    env = gym.make("Scara-C11-v1")
    policy = SB3Policy(env, out)
    assert run_episode(env, policy, seed=0)["steps"] >= 1
    assert files.is_trusted(out)  # recorded as this machine's own
    assert type(policy.model).__module__.split(".")[0] == {"sb3": "stable_baselines3", "sbx": "sbx"}[library]
    mtime = (out / "model.zip").stat().st_mtime_ns
    assert training.train(algo, out, hyperparams=tiny, resume=True) == out.resolve()  # finished: nothing to do
    assert (out / "model.zip").stat().st_mtime_ns == mtime
    with pytest.raises(ValueError, match="holds this run already"):
        training.train(algo, out, hyperparams=tiny)


@pytest.mark.parametrize("variant, expected", [
    ("dr", {"randomize_params": "all"}),
    ("frugal", {"reward_weights": {"time": 20.0, "collision": 100.0, "success": 50.0, "energy": 0.05}}),
])
def test_the_engineered_agents_variants_train_on_their_environment(variant, expected, tmp_path):
    hyper = load_hyperparams("ppo-residual", "Scara-C11-v1", "pd", variant=variant)
    for key, value in expected.items():
        assert hyper["env_kwargs"][key] == value
    hyper.update(n_envs=2, n_steps=50, batch_size=50, n_epochs=1, eval_freq=100, eval_episodes=1,
                 snapshot_freq=100)
    out = training.train_residual_ppo("pd", seed=0, total_timesteps=100, out=tmp_path / variant, hyperparams=hyper,
                                      progress_bar=False, env_id="Scara-C11-v1", variant=variant)
    config = json.loads((out / "config.json").read_text())
    for key, value in expected.items():
        assert config["env_kwargs"][key] == value
    env = gym.make("Scara-C11-v1")
    assert run_episode(env, SB3Policy(env, out), seed=0)["steps"] >= 1
    with pytest.raises(ValueError, match="variant must be None or one of"):
        training.train_residual_ppo("pd", out=tmp_path / "x", variant="fast")


def test_sac_with_her_trains_on_the_goal_env_resumes_and_is_evaluated(tmp_path):
    """A short HER run on Scara-C11-Goal-v0: relabeled rewards come from the env's
    compute_reward; the saved model reloads with its HER buffer; the evaluation runs it."""
    from stable_baselines3 import HerReplayBuffer

    from agents.experiments.evaluation import evaluate

    hyper = load_hyperparams("sac", "Scara-C11-Goal-v0", "pd")
    assert hyper["replay_buffer_class"] == "HerReplayBuffer"
    # HER samples only finished episodes: learning starts after the first (at most 300 steps)
    hyper.update(learning_starts=310, eval_freq=400, eval_episodes=1, snapshot_freq=400, buffer_size=2000)
    out = tmp_path / "her"
    training.train("sac", out, "Scara-C11-Goal-v0", "pd", seed=0, hyperparams=hyper, total_timesteps=500)
    config = json.loads((out / "config.json").read_text())
    assert config["env_id"] == "Scara-C11-Goal-v0" and config["total_timesteps"] == 500
    model = training.algorithm_class("sac").load(out / "model.zip", env=training.make_envs(
        "Scara-C11-Goal-v0", {"control_mode": "pd"}, hyper, seed=0)[0])
    assert isinstance(model.replay_buffer, HerReplayBuffer)
    rows, _ = evaluate([f"sb3:{out}"], env_id="Scara-C11-Goal-v0", condition="random-targets", episodes=2)
    assert rows[0]["episodes"] == 2 and 0.0 <= rows[0]["success rate"] <= 1.0
    assert all(o["success"] or o["collisions"] or o["reach_time"] is None for o in rows[0]["outcomes"])


def test_a_blocks_library_must_train_its_algorithm(tmp_path):
    with pytest.raises(ValueError, match=r"library must be one of \['sb3', 'sb3-contrib', 'sbx'\], got 'jax'"):
        training.train("sac", tmp_path / "x", hyperparams={**_tiny("sac"), "library": "jax"})
    with pytest.raises(ValueError, match=r"library 'sb3-contrib' trains \['tqc'\] here, not 'sac'"):
        training.train("sac", tmp_path / "x", hyperparams={**_tiny("sac"), "library": "sb3-contrib"})
    assert not (tmp_path / "x").exists()  # refused before the folder is made


def test_a_run_without_checkpoints_records_no_empty_manifest(tmp_path):
    import hashlib

    out = tmp_path / "ppo"
    training.train("ppo", out, hyperparams={**_tiny("ppo"), "checkpoint_freq": 10**6}, total_timesteps=100)
    assert not (out / "checkpoints" / files.DIGESTS).exists()  # no checkpoint: nothing to list
    assert hashlib.sha256(b"").hexdigest() not in files.trust_store().read_text().split()
    assert files.is_trusted(out)
