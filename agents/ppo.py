"""PPO (stable-baselines3) on Scara-C11-v0, readable top to bottom.

The agent acts through a residual set-point (agents.residual): its output r in [-1, 1]^3 becomes the
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
from pathlib import Path

import yaml

from stable_baselines3.common.vec_env import VecEnvWrapper

from agents.residual import ResidualSetpoint
from agents.training import SHIPPED_MODELS, SB3Policy
from agents.training import train as run_training
from scara_gym import ENV_ID

HYPERPARAMS = Path(__file__).with_name("hyperparams") / "ppo_residual.yml"
__all__ = ["ResidualSetpoint", "ResidualVecEnv", "PPOPolicy", "train", "load_hyperparams"]


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


VARIANTS = ("dr", "frugal")
"""Blocks "MODE-VARIANT" of ppo_residual.yml: domain randomization, the energy-aware reward."""


def load_hyperparams(env_id: str = ENV_ID, control_mode: str = "pd", path: Path = HYPERPARAMS,
                     randomize_target: bool = False, variant: str | None = None) -> dict:
    """The YAML entry env_id -> control mode ("MODE-random" with randomized targets, if present;
    "MODE-VARIANT" for a variant)."""
    table = yaml.safe_load(Path(path).read_text())
    key = control_mode if variant is None else f"{control_mode}-{variant}"
    if env_id not in table or key not in table[env_id]:
        raise KeyError(f"no PPO hyperparameters for {env_id!r} / {key!r} in {path}")
    if randomize_target and f"{key}-random" in table[env_id]:
        return dict(table[env_id][f"{key}-random"])
    return dict(table[env_id][key])


class ResidualVecEnv(VecEnvWrapper):
    """The agent's outputs r become the wrapped VecEnv's actions through a ResidualSetpoint."""

    def __init__(self, venv, mapping: ResidualSetpoint) -> None:
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


def train(control_mode: str = "pd", randomize_target: bool = False, seed: int = 0,
          total_timesteps: int | None = None, out: str | Path = "runs/ppo_pd",
          hyperparams: dict | None = None, eval_freq: int = 25_000, eval_episodes: int = 10,
          progress_bar: bool = True, env_id: str = ENV_ID, variant: str | None = None) -> Path:
    """Train the engineered PPO agent (agents.training.train with the residual set-point);
    writes model.zip, vecnormalize.pkl, config.json, checkpoints/, eval/ and tb/, and
    resumes from its snapshot when run again into the same folder. ``variant`` ("dr",
    "frugal") takes the YAML block "MODE-VARIANT"."""
    if variant is not None and variant not in VARIANTS:
        raise ValueError(f"variant must be None or one of {VARIANTS}, got {variant!r}")
    hyper = (load_hyperparams(env_id, control_mode, randomize_target=randomize_target, variant=variant)
             if hyperparams is None else dict(hyperparams))
    hyper.setdefault("eval_freq", eval_freq)
    hyper.setdefault("eval_episodes", eval_episodes)
    hyper.setdefault("checkpoint_freq", 100_000)
    hyper["env_kwargs"] = {"randomize_target": randomize_target, **hyper.get("env_kwargs", {})}
    total_timesteps = int(total_timesteps or hyper["n_timesteps"])
    command = (f"python -m agents.train --env-id {env_id} --control-mode {control_mode} --seed {seed} "
               f"--total-timesteps {total_timesteps}" + (" --randomize-target" if randomize_target else "")
               + (f" --variant {variant}" if variant else "") + f" --out {out}")
    return run_training("ppo", out, env_id, control_mode, seed, hyper, total_timesteps, progress_bar, command)


class PPOPolicy(SB3Policy):
    """A saved PPO agent (a folder, or a shipped model's name) as an obs -> action policy."""

    def __init__(self, env, model_dir: str | Path) -> None:
        model_dir = resolve_model(model_dir)
        super().__init__(env, model_dir)
        self.name = f"ppo ({model_dir.name})"


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(prog="python -m agents.train", description=__doc__.split("\n\n")[0])
    parser.add_argument("--env-id", default=ENV_ID)
    parser.add_argument("--control-mode", choices=("pd", "voltage"), default="pd")
    parser.add_argument("--randomize-target", action="store_true")
    parser.add_argument("--variant", choices=VARIANTS, default=None,
                        help="dr: physics and wall randomized per episode; frugal: an energy cost in the reward")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--total-timesteps", type=int, default=None, help="default: n_timesteps of the YAML")
    parser.add_argument("--hyperparams", type=Path, default=HYPERPARAMS)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--no-progress-bar", action="store_true")
    for name in ("n_envs", "n_steps", "batch_size"):
        parser.add_argument("--" + name.replace("_", "-"), type=int, default=None,
                            help=f"override the YAML's {name} (e.g. for a quick trial)")
    args = parser.parse_args(argv)
    hyper = load_hyperparams(args.env_id, args.control_mode, args.hyperparams, args.randomize_target, args.variant)
    for name in ("n_envs", "n_steps", "batch_size"):
        if getattr(args, name) is not None:
            if getattr(args, name) < 1:
                parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
            hyper[name] = getattr(args, name)
    out = args.out or Path("runs") / (f"ppo_{args.control_mode}" + ("_random" if args.randomize_target else "")
                                      + (f"_{args.variant}" if args.variant else ""))
    return train(args.control_mode, args.randomize_target, args.seed, args.total_timesteps, out, hyper,
                 progress_bar=not args.no_progress_bar, env_id=args.env_id, variant=args.variant)


