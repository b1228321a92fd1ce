"""PPO (stable-baselines3) on Scara-C11-v0, readable top to bottom.

The agent acts through a residual set-point: its output r in [-1, 1]^3 becomes the
set-point  target + residual_scale * deadzone(r),  deadzone(r) = sign(r) max(|r| - z, 0)
/ (1 - z)  (the target is read from the observation: q + target error). Every |r| < z
commands the target exactly, which the 0.001 success band needs (a plain linear map
would ask the policy's mean for 4e-4 precision), while the agent can still hold an axis
back by up to residual_scale. In "pd" mode the set-point is the environment's action; in
"voltage" mode the agent evaluates the C11 PD law on the observation once per control
step and commands the voltages (a learned controller with a PD prior).

    python -m agents.train --control-mode pd --seed 0            # writes runs/ppo_pd

Shipped agents are package data (``agents/models/NAME``); ``resolve_model("ppo_pd")`` finds
one by name from anywhere, and training never writes there.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import yaml

from scara_gym import ENV_ID
from scara_gym.envs import OBSERVATION_LAYOUT, ScaraTask

HYPERPARAMS = Path(__file__).with_name("hyperparams") / "ppo.yml"
SHIPPED_MODELS = Path(__file__).with_name("models")
Q, TARGET_ERROR = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["target_error"]


def shipped_models() -> list[str]:
    """Names of the agents shipped with the package (agents/models/NAME)."""
    return sorted(p.parent.name for p in SHIPPED_MODELS.glob("*/model.zip"))


def resolve_model(name_or_path: str | Path) -> Path:
    """A model folder: an existing path, else the name of a shipped model."""
    path = Path(name_or_path)
    if (path / "model.zip").exists():
        return path
    if (SHIPPED_MODELS / str(name_or_path) / "model.zip").exists():
        return SHIPPED_MODELS / str(name_or_path)
    raise FileNotFoundError(f"no PPO model at {str(name_or_path)!r}: give a folder with model.zip "
                            f"or a shipped model name {shipped_models()}")


def load_hyperparams(env_id: str = ENV_ID, control_mode: str = "pd", path: Path = HYPERPARAMS,
                     randomize_target: bool = False) -> dict:
    """The YAML entry env_id -> control mode ("MODE-random" with randomized targets, if present)."""
    table = yaml.safe_load(Path(path).read_text())
    if env_id not in table or control_mode not in table[env_id]:
        raise KeyError(f"no PPO hyperparameters for {env_id!r} / {control_mode!r} in {path}")
    if randomize_target and f"{control_mode}-random" in table[env_id]:
        return dict(table[env_id][f"{control_mode}-random"])
    return dict(table[env_id][control_mode])


class ResidualSetpoint:
    """Maps agent outputs r to environment actions, for a batch of raw observations."""

    def __init__(self, task: ScaraTask, residual_scale, deadzone: float = 0.0) -> None:
        if not 0.0 <= deadzone < 1.0:
            raise ValueError(f"residual_deadzone must be in [0, 1), got {deadzone!r}")
        self.task = task
        self.scale = np.asarray(residual_scale, dtype=float)
        self.deadzone = float(deadzone)

    def __call__(self, obs: np.ndarray, r: np.ndarray) -> np.ndarray:
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        r = np.clip(np.atleast_2d(np.asarray(r, dtype=float)), -1.0, 1.0)
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        shaped = np.sign(r) * np.maximum(np.abs(r) - self.deadzone, 0.0) / (1.0 - self.deadzone)
        setpoint = target + self.scale * shaped
        if self.task.control_mode == "pd":
            return np.clip((setpoint - self.task.setpoint_center) / self.task.setpoint_half, -1.0, 1.0)
        return self.task.pd_action(obs, setpoint)


def make_training_env(env_kwargs: dict, hyper: dict, seed: int):
    from stable_baselines3.common.vec_env import VecEnvWrapper, VecNormalize

    from scara_gym.sb3 import SB3VecEnv

    class Residual(VecEnvWrapper):
        def __init__(self, venv, mapping):
            super().__init__(venv)
            self.mapping = mapping
            self.last_obs = None

        def reset(self):
            self.last_obs = self.venv.reset()
            return self.last_obs

        def step_async(self, actions):
            self.venv.step_async(self.mapping(self.last_obs, actions))

        def step_wait(self):
            obs, rewards, dones, infos = self.venv.step_wait()
            self.last_obs = obs
            return obs, rewards, dones, infos

    # one numba thread: torch's threads take the cores between environment steps (see README)
    venv = SB3VecEnv(num_envs=hyper["n_envs"], num_threads=hyper.get("env_threads", 1), **env_kwargs)
    venv.seed(seed)
    mapping = ResidualSetpoint(venv.venv.task, hyper["residual_scale"], hyper.get("residual_deadzone", 0.0))
    venv = Residual(venv, mapping)  # the adapter reports Monitor-style episode statistics
    return VecNormalize(venv, norm_obs=hyper["norm_obs"], norm_reward=hyper["norm_reward"], gamma=hyper["gamma"]), Residual, mapping


def train(control_mode: str = "pd", randomize_target: bool = False, seed: int = 0,
          total_timesteps: int | None = None, out: str | Path = "runs/ppo_pd",
          hyperparams: dict | None = None, eval_freq: int = 25_000, eval_episodes: int = 10,
          progress_bar: bool = True, env_id: str = ENV_ID) -> Path:
    """Train PPO; writes model.zip, vecnormalize.pkl, config.json, checkpoints/, eval/ and tb/."""
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    hyper = (load_hyperparams(env_id, control_mode, randomize_target=randomize_target)
             if hyperparams is None else dict(hyperparams))
    total_timesteps = int(total_timesteps or hyper["n_timesteps"])
    out = Path(out).resolve()
    if SHIPPED_MODELS.resolve() in (out, *out.parents):
        raise ValueError(f"training writes under runs/ or --out, never into the shipped models ({out})")
    out.mkdir(parents=True, exist_ok=True)
    env_kwargs = {"control_mode": control_mode, "randomize_target": randomize_target,
                  **hyper.get("env_kwargs", {})}

    # 1. training env: the native vector env, residual set-points, episode stats, normalization
    venv, Residual, mapping = make_training_env(env_kwargs, hyper, seed)

    # 2. evaluation env: one Monitor-wrapped gym.make env with the same mapping and (frozen)
    #    normalization statistics, synchronized by EvalCallback
    eval_env = DummyVecEnv([lambda: Monitor(gym.make(env_id, **env_kwargs))])
    eval_env.seed(seed + 10_000)
    eval_env = VecNormalize(Residual(eval_env, mapping), norm_obs=hyper["norm_obs"], norm_reward=False,
                            training=False, gamma=hyper["gamma"])

    # 3. the agent
    model = PPO(
        "MlpPolicy", venv, n_steps=hyper["n_steps"], batch_size=hyper["batch_size"],
        n_epochs=hyper["n_epochs"], gamma=hyper["gamma"], gae_lambda=hyper["gae_lambda"],
        learning_rate=hyper["learning_rate"], clip_range=hyper["clip_range"],
        ent_coef=hyper["ent_coef"], max_grad_norm=hyper["max_grad_norm"],
        policy_kwargs={"net_arch": list(hyper["net_arch"]), "log_std_init": hyper["log_std_init"]},
        tensorboard_log=str(out / "tb"), seed=seed, device="cpu", verbose=0)

    # 4. learn, with checkpoints and periodic deterministic evaluation
    per_env = max(1, eval_freq // hyper["n_envs"])
    callbacks = [
        CheckpointCallback(per_env * 4, str(out / "checkpoints"), name_prefix="ppo",
                           save_vecnormalize=True),
        EvalCallback(eval_env, n_eval_episodes=eval_episodes, eval_freq=per_env,
                     log_path=str(out / "eval"), best_model_save_path=str(out / "best"),
                     deterministic=True, verbose=0),
    ]
    started = time.perf_counter()
    model.learn(total_timesteps=total_timesteps, callback=callbacks, progress_bar=progress_bar)

    # 5. save the model with its normalization statistics and how it was made
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    config = {"env_id": env_id, "env_kwargs": env_kwargs, "seed": seed, "total_timesteps": total_timesteps,
              "hyperparams": hyper, "train_seconds": time.perf_counter() - started,
              "command": f"python -m agents.train --control-mode {control_mode} --seed {seed} "
                         f"--total-timesteps {total_timesteps}"
                         + (" --randomize-target" if randomize_target else "") + f" --out {out}"}
    (out / "config.json").write_text(json.dumps(config, indent=2))
    return out


class PPOPolicy:
    """A saved PPO agent as an obs -> action policy for one environment (agents.policies API)."""

    def __init__(self, env, model_dir: str | Path) -> None:
        import pickle

        from stable_baselines3 import PPO

        model_dir = resolve_model(model_dir)
        self.env = env.unwrapped if hasattr(env, "unwrapped") else env
        config = json.loads((model_dir / "config.json").read_text())
        if config["env_kwargs"]["control_mode"] != self.env.control_mode:
            raise ValueError(f"{model_dir} was trained in {config['env_kwargs']['control_mode']!r} mode, "
                             f"the environment is in {self.env.control_mode!r} mode")
        self.model = PPO.load(model_dir / "model.zip", device="cpu")
        with open(model_dir / "vecnormalize.pkl", "rb") as f:
            normalizer = pickle.load(f)
        self.obs_rms, self.clip_obs, self.epsilon = normalizer.obs_rms, normalizer.clip_obs, normalizer.epsilon
        self.norm_obs = normalizer.norm_obs
        hyper = config["hyperparams"]
        self.mapping = ResidualSetpoint(self.env.task, hyper["residual_scale"], hyper.get("residual_deadzone", 0.0))
        self.name = f"ppo ({model_dir.name})"

    def reset(self) -> None:
        pass

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs, dtype=np.float64)
        if self.norm_obs:
            x = np.clip((x - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon),
                        -self.clip_obs, self.clip_obs)
        r, _ = self.model.predict(x.astype(np.float32), deterministic=True)
        return self.mapping(obs, r)[0]


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(prog="python -m agents.train", description=__doc__.split("\n\n")[0])
    parser.add_argument("--env-id", default=ENV_ID)
    parser.add_argument("--control-mode", choices=("pd", "voltage"), default="pd")
    parser.add_argument("--randomize-target", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--total-timesteps", type=int, default=None, help="default: n_timesteps of the YAML")
    parser.add_argument("--hyperparams", type=Path, default=HYPERPARAMS)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--no-progress-bar", action="store_true")
    for name in ("n_envs", "n_steps", "batch_size"):
        parser.add_argument("--" + name.replace("_", "-"), type=int, default=None,
                            help=f"override the YAML's {name} (e.g. for a quick trial)")
    args = parser.parse_args(argv)
    hyper = load_hyperparams(args.env_id, args.control_mode, args.hyperparams, args.randomize_target)
    for name in ("n_envs", "n_steps", "batch_size"):
        if getattr(args, name) is not None:
            if getattr(args, name) < 1:
                parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
            hyper[name] = getattr(args, name)
    out = args.out or Path("runs") / (f"ppo_{args.control_mode}" + ("_random" if args.randomize_target else ""))
    return train(args.control_mode, args.randomize_target, args.seed, args.total_timesteps, out, hyper,
                 progress_bar=not args.no_progress_bar, env_id=args.env_id)


