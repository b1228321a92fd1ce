"""The one hyperparameter loader: RL-Zoo-style YAML per algorithm, keyed by env id then control mode.

``hyperparams/ALGO.yml`` holds, per registered env id, one block per control mode ("pd",
"voltage") and per variant ("MODE-VARIANT", e.g. "pd-dr"); with targets drawn per episode a
block "KEY-random" is taken where the file has one.
"""

from __future__ import annotations

from pathlib import Path

from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.envs.task import MAX_ROBOTS
from scara_gym.extras import require
from scara_gym.model import checks
from scara_gym.model.checks import UserError, UserKeyError

INTEGERS = {"n_timesteps": 1, "n_envs": 1, "env_threads": 1, "torch_threads": 0, "n_steps": 1, "batch_size": 1,
            "n_epochs": 1, "buffer_size": 1, "learning_starts": 0, "gradient_steps": 1, "eval_freq": 1,
            "eval_episodes": 1, "snapshot_freq": 1, "checkpoint_freq": 1, "policy_delay": 1, "n_sampled_goal": 1,
            "top_quantiles_to_drop_per_net": 0, "sde_sample_freq": -1}
"""integer hyperparameters and their least value"""


def numba_threads() -> int:
    """numba's threads on this machine: the most a vector env's env_threads may be."""
    import numba

    return numba.config.NUMBA_NUM_THREADS


UPPER = {"n_envs": lambda: MAX_ROBOTS, "env_threads": numba_threads}
"""integer hyperparameters with a largest value: the vector env's robots, numba's threads on this machine
(named here, not as the env's internal num_robots and num_threads)"""
REALS = {"learning_rate": (0.0, 1.0, True), "gamma": (0.0, 1.0, True), "gae_lambda": (0.0, 1.0, True),
         "tau": (0.0, 1.0, True), "clip_range": (0.0, 10.0, True), "vf_coef": (0.0, 1e6, False),
         "max_grad_norm": (0.0, 1e6, True), "noise_std": (0.0, 10.0, False), "log_std_init": (-20.0, 5.0, False),
         "target_policy_noise": (0.0, 10.0, False), "target_noise_clip": (0.0, 10.0, False),
         "residual_deadzone": (0.0, 1.0, False)}
"""real hyperparameters: (low, high, low open)"""

HYPERPARAMS = Path(__file__).with_name("hyperparams")
FILES = {"ppo": "ppo.yml", "sac": "sac.yml", "td3": "td3.yml", "tqc": "tqc.yml", "ppo-residual": "ppo_residual.yml"}
"""hyperparameter file of each SB3 recipe (ppo-residual: PPO acting through the residual set-point)"""


def load_hyperparams(recipe: str, env_id: str = ENV_ID, control_mode: str = "pd",
                     variant: str | None = None, randomize_target: bool = False, path: Path | None = None) -> dict:
    """The block env_id -> control_mode (or "MODE-VARIANT"; "...-random" with randomize_target
    where present) of the recipe's YAML file (or of ``path``)."""
    require("yaml")
    import yaml

    if recipe not in FILES:
        raise UserError(f"recipe must be one of {sorted(FILES)}, got {recipe!r}")
    path = Path(path) if path is not None else HYPERPARAMS / FILES[recipe]
    table = yaml.safe_load(path.read_text())
    key = control_mode if variant is None else f"{control_mode}-{variant}"
    if env_id not in table or key not in table[env_id]:
        known = {k: sorted(v) for k, v in table.items()}
        raise UserKeyError(f"no {recipe} hyperparameters for {env_id!r} / {key!r} in {path}; it has {known}")
    if randomize_target and f"{key}-random" in table[env_id]:
        key = f"{key}-random"
    return dict(table[env_id][key])


def check_hyperparams(hyper: dict) -> dict:
    """A block's values checked before anything starts (budgets and sizes >= their least value,
    finite rates in range, networks of positive widths); a mistake names the entry."""
    for name, low in INTEGERS.items():
        if name in hyper:
            checks.integer(name, hyper[name], low, UPPER.get(name, lambda: None)())
    for name, (low, high, low_open) in REALS.items():
        if name in hyper:
            checks.real(name, hyper[name], low, high, low_open=low_open)
    if "train_freq" in hyper and not isinstance(hyper["train_freq"], list):
        checks.integer("train_freq", hyper["train_freq"], 1)
    ent = hyper.get("ent_coef")
    if ent is not None and not (isinstance(ent, str) and ent.startswith("auto")):
        checks.real("ent_coef", ent, 0.0, 1e6)
    arch = hyper.get("net_arch")
    if arch is not None and (not isinstance(arch, list) or not arch
                             or not all(isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in arch)):
        raise UserError(f"net_arch must be a list of layer widths >= 1, got {arch!r}")
    return hyper
