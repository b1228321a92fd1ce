"""Resumable stable-baselines3 training (PPO, SAC, TD3) on the native vector environment.

One function, `train`, trains any of the three algorithms from a hyperparameter entry
(RL-Zoo style YAML, ``agents/hyperparams/ALGO.yml``, keyed by env id then control mode):

1. the training env: the registered id's arguments (``ENV_KWARGS``) on the
   native vector env through ``SB3VecEnv``, optionally a residual set-point wrapper (the
   engineered agent, ``ppo-residual``, only) and ``VecNormalize``;
2. the evaluation env: ``gym.make(env_id)`` in a ``Monitor``, seeded ``10_000 + seed``
   (disjoint from the evaluation seeds 1000-1099 of scara-agents evaluate), driven by
   ``EvalCallback`` every ``eval_freq`` steps: the learning curve in ``eval/evaluations.npz``;
3. a snapshot every ``snapshot_freq`` steps (``snapshot/``: model, replay buffer, normalization
   statistics, evaluation history, steps and seconds so far), written to a scratch folder
   and swapped in whole, so an interrupted run loses at most one snapshot interval:
   calling `train` again with the same ``out`` and ``resume=True`` resumes from it;
4. at the end: ``model.zip``, ``vecnormalize.pkl`` (if normalized) and ``config.json``.

A folder that holds a run is refused unless ``resume`` (continue it; a finished one is returned
as it is) or ``overwrite`` (train it again from scratch), and so is one that holds a run of other
settings (agents.files.claim_run_folder). Every snapshot, the finished run and its checkpoints
carry a manifest of digests recorded as this machine's own (agents.files.record_trusted; never one
that lists nothing: a run that saved no checkpoint writes no checkpoints manifest), and a snapshot
resumes only from a trusted manifest, from the bytes checked against it: its files are pickle.

Checkpoint rule: none. The policy at the end of the budget is the one evaluated; the
evaluation history is a learning curve, not a selector. A resumed run continues the same
schedule but not the same random streams (SB3 does not save its generators), so it is a
valid run of the recipe, not a bit-for-bit replay of an uninterrupted one.
"""

from __future__ import annotations

import io
import json
import pickle
import shutil
import time
from functools import partial
from pathlib import Path

import numpy as np

from agents.algorithms.progress import Progress
from agents.algorithms.sb3.hyperparams import check_hyperparams, load_hyperparams
from agents.algorithms.sb3.libraries import algorithm_class, check_library
from agents.algorithms.sb3.policy import SHIPPED_MODELS
from agents.files import (
    DIGESTS,
    POLICY_FILES,
    claim_run_folder,
    exclusive,
    record_trusted,
    require_trusted,
    write_digests,
    write_json,
)
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.extras import require
from scara_gym.model import checks
from scara_gym.model.checks import UserError
from scara_gym.registration import ENV_KWARGS, GOAL_ENV_IDS
from scara_gym.wrappers import residual_action

ALGORITHMS = ("ppo", "sac", "td3")
# entries of a hyperparameter block that configure the run, not the SB3 algorithm
RUN_KEYS = {"n_timesteps", "n_envs", "env_threads", "env_kwargs", "normalize", "residual_scale",
            "residual_deadzone", "net_arch", "log_std_init", "noise_std", "snapshot_freq",
            "eval_freq", "eval_episodes", "torch_threads", "checkpoint_freq", "noise_type", "library"}
DEFAULT_TORCH_THREADS = 1
"""torch's threads of a run whose block names none: one per run (agents.algorithms.torch_ppo_config's
reason: more cost most of the speed once another process wants a core)"""
RESUMABLE = ("n_timesteps", "snapshot_freq", "eval_freq", "eval_episodes", "torch_threads", "env_threads",
             "checkpoint_freq")
"""hyperparameters a resumed run may change (its budget, its bookkeeping and how fast it runs); the
others are the run's settings, which its folder keeps"""
SNAPSHOT_FILES = ("model.zip", "replay_buffer.pkl", "vecnormalize.pkl", "evaluations.npz", "progress.json")


def _normalize_kwargs(hyper: dict) -> dict | None:
    normalize = hyper.get("normalize", False)
    if normalize is True:
        return {"norm_obs": True, "norm_reward": True}
    return dict(normalize) if normalize else None


def make_envs(env_id: str, env_kwargs: dict, hyper: dict, seed: int, normalizer: bytes | None = None):
    """(training VecEnv, evaluation VecEnv), wrapped alike: residual set-points (if the block
    has them), then VecNormalize (if it asks for it; on resume unpickled from `normalizer`, the
    checked bytes of a trusted snapshot's vecnormalize.pkl)."""
    import gymnasium as gym
    require("stable_baselines3")
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from scara_gym.integrations.sb3 import SB3VecEnv

    # the residual set-point (where the block has one): both envs wrapped to act through it
    residual = (partial(residual_action, residual_scale=hyper["residual_scale"],
                        deadzone=hyper.get("residual_deadzone", 0.0))
                if "residual_scale" in hyper and env_id not in GOAL_ENV_IDS else None)

    def single():
        env = gym.make(env_id, **env_kwargs)
        return Monitor(env if residual is None else residual(env))

    if env_id in GOAL_ENV_IDS:  # HER asks the env for compute_reward: gym envs in SB3's DummyVecEnv
        train_env = DummyVecEnv([single] * hyper["n_envs"])
    else:
        train_env = SB3VecEnv(num_envs=hyper["n_envs"], env_id=env_id, num_threads=hyper.get("env_threads", 1),
                              action_wrapper=residual, **env_kwargs)
    train_env.seed(seed)
    eval_env = DummyVecEnv([single])
    eval_env.seed(10_000 + seed)
    norm = _normalize_kwargs(hyper)
    if norm is not None:
        gamma = hyper.get("gamma", 0.99)
        if normalizer is not None:
            loaded = pickle.loads(normalizer)  # VecNormalize.load, from the bytes that were checked
            loaded.set_venv(train_env)
            train_env = loaded
        else:
            train_env = VecNormalize(train_env, gamma=gamma, **norm)
        eval_env = VecNormalize(eval_env, norm_obs=norm.get("norm_obs", True), norm_reward=False,
                                training=False, gamma=gamma, norm_obs_keys=norm.get("norm_obs_keys"))
    return train_env, eval_env


def algorithm_kwargs(algo: str, hyper: dict, n_actions: int) -> dict:
    """SB3 constructor arguments from a hyperparameter block."""
    kwargs = {k: v for k, v in hyper.items() if k not in RUN_KEYS}
    policy_kwargs = {"net_arch": list(hyper.get("net_arch", [64, 64]))}
    if "log_std_init" in hyper and (algo == "ppo" or hyper.get("use_sde")):  # SAC's log std exists with gSDE only
        policy_kwargs["log_std_init"] = hyper["log_std_init"]
    if algo == "td3" and hyper.get("noise_std"):
        require("stable_baselines3")
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        noise = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
        kind = hyper.get("noise_type", "normal")
        if kind not in noise:
            raise UserError(f"noise_type must be one of {sorted(noise)}, got {kind!r}")
        kwargs["action_noise"] = noise[kind](np.zeros(n_actions), hyper["noise_std"] * np.ones(n_actions))
    if kwargs.get("replay_buffer_class") == "HerReplayBuffer":  # hindsight relabeling for the goal envs
        from agents.algorithms.sb3.her import KeptInfoHerReplayBuffer  # SB3's, with replay_buffer_kwargs' info_keys

        kwargs["replay_buffer_class"] = KeptInfoHerReplayBuffer
    return {"policy_kwargs": policy_kwargs, **kwargs}


def _snapshot_callback(out: Path, every: int, eval_callback, clock: dict):
    require("stable_baselines3")
    from stable_baselines3.common.callbacks import BaseCallback

    class Snapshot(BaseCallback):
        """Every `every` steps: model, replay buffer, normalizer and history, swapped in whole."""

        def __init__(self) -> None:
            super().__init__()
            self.last = 0

        def _on_training_start(self) -> None:
            self.last = self.num_timesteps

        def _on_step(self) -> bool:
            if self.num_timesteps - self.last >= every:
                self.save()
            return True

        def save(self) -> None:
            self.last = self.num_timesteps
            scratch, final, old = out / "snapshot.partial", out / "snapshot", out / "snapshot.old"
            shutil.rmtree(scratch, ignore_errors=True)
            scratch.mkdir(parents=True)
            self.model.save(scratch / "model.zip")
            if hasattr(self.model, "replay_buffer") and self.model.replay_buffer is not None:
                self.model.save_replay_buffer(scratch / "replay_buffer.pkl")
            if self.model.get_vec_normalize_env() is not None:
                self.model.get_vec_normalize_env().save(str(scratch / "vecnormalize.pkl"))
            _save_history(scratch / "evaluations.npz", eval_callback)
            progress = {"num_timesteps": int(self.num_timesteps), "best_mean_reward": float(eval_callback.best_mean_reward),
                        "train_seconds": clock["before"] + time.perf_counter() - clock["started"]}
            (scratch / "progress.json").write_text(json.dumps(progress))
            write_digests(scratch, SNAPSHOT_FILES)
            record_trusted(scratch)  # this machine's own: a resume may unpickle it
            if final.exists():
                final.rename(old)
            scratch.rename(final)
            shutil.rmtree(old, ignore_errors=True)

    return Snapshot()


def _progress_callback(total: int):
    require("stable_baselines3")
    from stable_baselines3.common.callbacks import BaseCallback

    class ShowProgress(BaseCallback):
        """The progress line (agents.algorithms.progress): the last 100 episodes' return and success (SB3's
        buffers, filled from the env's Monitor-style infos)."""

        def _on_training_start(self) -> None:
            self.progress = Progress(total, start_step=self.num_timesteps)

        def _report(self, final: bool) -> None:
            self.progress.report(self.num_timesteps, [e["r"] for e in self.model.ep_info_buffer],
                                 self.model.ep_success_buffer, final=final)

        def _on_step(self) -> bool:
            self._report(final=False)
            return True

        def _on_training_end(self) -> None:
            self._report(final=True)

    return ShowProgress()


def _save_history(path: Path, eval_callback) -> None:
    shape = (len(eval_callback.evaluations_timesteps), eval_callback.n_eval_episodes)
    np.savez(path, timesteps=np.array(eval_callback.evaluations_timesteps, dtype=np.int64),
             results=np.array(eval_callback.evaluations_results, dtype=float).reshape(shape),
             ep_lengths=np.array(eval_callback.evaluations_length, dtype=np.int64).reshape(shape),
             successes=np.array(eval_callback.evaluations_successes, dtype=float).reshape(shape))


def _restore_history(saved: bytes, eval_callback, best_mean_reward: float) -> None:
    with np.load(io.BytesIO(saved), allow_pickle=False) as data:
        eval_callback.evaluations_timesteps = [int(t) for t in data["timesteps"]]
        eval_callback.evaluations_results = [list(r) for r in data["results"]]
        eval_callback.evaluations_length = [list(r) for r in data["ep_lengths"]]
        eval_callback.evaluations_successes = [list(r) for r in data["successes"]]
    eval_callback.best_mean_reward = best_mean_reward


def train(algo: str, out: str | Path, env_id: str = ENV_ID, control_mode: str = "pd", seed: int = 0,
          hyperparams: dict | None = None, total_timesteps: int | None = None, progress_bar: bool = False,
          command: str | None = None, resume: bool = False, overwrite: bool = False,
          callbacks: list | None = None) -> Path:
    """Train one run into `out` (with ``resume``: continue the one there; with ``overwrite``:
    replace it), its folder locked for the whole run (agents.files.exclusive); returns `out`.
    ``callbacks``: SB3 callbacks added to the run's own (a hook, e.g. the hyperparameter
    search's rung reports: agents.experiments.search). See the module docstring."""
    if env_id not in ENV_KWARGS:
        raise UserError(f"env_id must be one of {sorted(ENV_KWARGS)}, got {env_id!r}")
    hyper = check_hyperparams(dict(hyperparams) if hyperparams is not None  # before the folder is made or locked
                              else load_hyperparams(algo, env_id, control_mode))
    check_library(algo, hyper.get("library", "sb3"))
    if total_timesteps is not None:
        checks.integer("total_timesteps", total_timesteps, 1)
    with exclusive(Path(out)):
        return _train(algo, out, env_id, control_mode, seed, hyper, total_timesteps, progress_bar, command, resume,
                      overwrite, callbacks or [])


def run_record(algo: str, env_id: str, control_mode: str, seed: int, hyper: dict) -> dict:
    """What an SB3 run is, for agents.files.claim_run_folder."""
    return {"trainer": "sb3", "algo": algo, "env_id": env_id, "control_mode": control_mode, "seed": seed,
            "settings": {k: v for k, v in hyper.items() if k not in RESUMABLE}}


def _train(algo: str, out: str | Path, env_id: str, control_mode: str, seed: int, hyper: dict,
           total_timesteps: int | None, progress_bar: bool, command: str | None, resume: bool,
           overwrite: bool, hooks: list) -> Path:
    require("torch")
    import torch
    require("stable_baselines3")
    from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback

    total_timesteps = int(total_timesteps or hyper["n_timesteps"])
    out = Path(out).resolve()
    if SHIPPED_MODELS.resolve() in (out, *out.parents):
        raise UserError(f"training writes under runs/ or --out, never into the shipped models ({out})")
    continuing = claim_run_folder(out, run_record(algo, env_id, control_mode, seed, hyper), resume, overwrite)
    if continuing and (out / "config.json").exists() and (out / "model.zip").exists():
        return out  # finished before: nothing more to do
    threads = int(hyper.get("torch_threads", DEFAULT_TORCH_THREADS))
    if threads:  # 0: torch's default (a thread per core)
        torch.set_num_threads(threads)
    env_kwargs = {"control_mode": control_mode, **hyper.get("env_kwargs", {})}

    snapshot = out / "snapshot"
    if not (snapshot / "progress.json").exists() and (out / "snapshot.old" / "progress.json").exists():
        snapshot = out / "snapshot.old"  # interrupted while swapping
    resuming = (snapshot / "progress.json").exists()
    # pickle: only this machine's own snapshots (or --trust), loaded from the bytes checked against their manifest
    saved = require_trusted(snapshot, wanted=SNAPSHOT_FILES) if resuming else None
    progress = saved.json("progress.json") if saved is not None else \
        {"num_timesteps": 0, "best_mean_reward": -np.inf, "train_seconds": 0.0}
    normalizer = saved.bytes("vecnormalize.pkl") if saved is not None and "vecnormalize.pkl" in saved else None
    train_env, eval_env = make_envs(env_id, env_kwargs, hyper, seed, normalizer)

    Algorithm = algorithm_class(algo, hyper.get("library", "sb3"))
    if saved is not None:
        model = Algorithm.load(io.BytesIO(saved.bytes("model.zip")), env=train_env, device="cpu",
                               tensorboard_log=str(out / "tb"))
        if "replay_buffer.pkl" in saved:
            model.load_replay_buffer(io.BytesIO(saved.bytes("replay_buffer.pkl")))
    else:
        from gymnasium import spaces

        policy = "MultiInputPolicy" if isinstance(train_env.observation_space, spaces.Dict) else "MlpPolicy"
        model = Algorithm(policy, train_env, seed=seed, device="cpu", verbose=0, tensorboard_log=str(out / "tb"),
                          **algorithm_kwargs(algo, hyper, train_env.action_space.shape[0]))

    per_env = lambda steps: max(1, int(steps) // hyper["n_envs"])  # noqa: E731  callbacks count vector steps
    eval_callback = EvalCallback(eval_env, n_eval_episodes=hyper.get("eval_episodes", 5),
                                 eval_freq=per_env(hyper.get("eval_freq", 25_000)), log_path=str(out / "eval"),
                                 best_model_save_path=None, deterministic=True, verbose=0)
    if saved is not None:
        _restore_history(saved.bytes("evaluations.npz"), eval_callback, progress["best_mean_reward"])
    clock = {"before": progress["train_seconds"], "started": time.perf_counter()}
    snapshots = _snapshot_callback(out, int(hyper.get("snapshot_freq", 50_000)), eval_callback, clock)

    callbacks = [eval_callback, snapshots, _progress_callback(total_timesteps), *hooks]
    if hyper.get("checkpoint_freq"):  # kept models for scara-agents select, with their normalizers
        callbacks.append(CheckpointCallback(per_env(hyper["checkpoint_freq"]), str(out / "checkpoints"),
                                            name_prefix=algo, save_vecnormalize=True))

    remaining = total_timesteps - progress["num_timesteps"]
    if remaining > 0:
        model.learn(total_timesteps=remaining, callback=callbacks, progress_bar=progress_bar,
                    reset_num_timesteps=not resuming, tb_log_name=algo)
    train_seconds = clock["before"] + time.perf_counter() - clock["started"]

    model.save(out / "model.zip")
    if model.get_vec_normalize_env() is not None:
        model.get_vec_normalize_env().save(str(out / "vecnormalize.pkl"))
    (out / "eval").mkdir(exist_ok=True)
    _save_history(out / "eval" / "evaluations.npz", eval_callback)
    config = {"algo": algo, "env_id": env_id, "env_kwargs": env_kwargs, "seed": seed,
              "total_timesteps": total_timesteps, "hyperparams": hyper, "train_seconds": train_seconds,
              "resumed": resuming, "torch_threads": torch.get_num_threads(),
              "checkpoint_rule": "none: the policy at the end of the budget",
              "command": command or f"agents.algorithms.sb3.training.train({algo!r}, {str(out)!r}, {env_id!r}, {control_mode!r}, {seed})"}
    write_json(out / "config.json", config)
    write_digests(out, POLICY_FILES)
    record_trusted(out)
    kept = [p.name for p in (out / "checkpoints").iterdir() if p.is_file() and not p.name.startswith(".")
            and p.name != DIGESTS] if (out / "checkpoints").is_dir() else []
    if kept:  # scara-agents select loads them; no checkpoint: no manifest (one listing nothing would vouch for nothing)
        write_digests(out / "checkpoints", kept)
        record_trusted(out / "checkpoints")
    shutil.rmtree(out / "snapshot", ignore_errors=True)
    shutil.rmtree(out / "snapshot.old", ignore_errors=True)
    return out


VARIANTS = ("dr", "frugal")
"""Blocks "MODE-VARIANT" of ppo_residual.yml: domain randomization, the energy-aware reward."""


def train_residual_ppo(control_mode: str = "pd", randomize_target: bool = False, seed: int = 0,
          total_timesteps: int | None = None, out: str | Path = "runs/ppo_pd",
          hyperparams: dict | None = None, eval_freq: int = 25_000, eval_episodes: int = 10,
          progress_bar: bool = True, env_id: str = ENV_ID, variant: str | None = None,
          resume: bool = False, overwrite: bool = False) -> Path:
    """Train the engineered PPO agent (`train` with ppo_residual.yml's residual set-point);
    writes model.zip, vecnormalize.pkl, config.json, checkpoints/, eval/ and tb/, and
    resumes from its snapshot when run again into the same folder with ``resume``. ``variant`` ("dr",
    "frugal") takes the YAML block "MODE-VARIANT"."""
    if variant is not None and variant not in VARIANTS:
        raise UserError(f"variant must be None or one of {VARIANTS}, got {variant!r}")
    hyper = (load_hyperparams("ppo-residual", env_id, control_mode, variant, randomize_target)
             if hyperparams is None else dict(hyperparams))
    hyper.setdefault("eval_freq", eval_freq)
    hyper.setdefault("eval_episodes", eval_episodes)
    hyper.setdefault("checkpoint_freq", 100_000)
    hyper["env_kwargs"] = {"randomize_target": randomize_target, **hyper.get("env_kwargs", {})}
    total_timesteps = int(total_timesteps or hyper["n_timesteps"])
    command = (f"scara-agents train ppo-residual{'-' + variant if variant else ''} --env-id {env_id} "
               f"--control-mode {control_mode} --seed {seed} --total-timesteps {total_timesteps}"
               + (" --randomize-target" if randomize_target else "") + f" --out {out}")
    return train("ppo", out, env_id, control_mode, seed, hyper, total_timesteps, progress_bar, command, resume,
                 overwrite)
