"""The one hyperparameter loader: RL-Zoo-style YAML per algorithm, keyed by env id then control mode.

``hyperparams/ALGO.yml`` holds, per registered env id, one block per control mode ("pd",
"voltage") and per variant ("MODE-VARIANT", e.g. "pd-dr"); with targets drawn per episode a
block "KEY-random" is taken where the file has one.
"""

from __future__ import annotations

from pathlib import Path

from scara_gym.registration import TRAINING_ENV_ID

HYPERPARAMS = Path(__file__).with_name("hyperparams")
FILES = {"ppo": "ppo.yml", "sac": "sac.yml", "td3": "td3.yml", "ppo-residual": "ppo_residual.yml"}
"""hyperparameter file of each SB3 recipe (ppo-residual: PPO acting through the residual set-point)"""


def load_hyperparams(recipe: str, env_id: str = TRAINING_ENV_ID, control_mode: str = "pd",
                     variant: str | None = None, randomize_target: bool = False, path: Path | None = None) -> dict:
    """The block env_id -> control_mode (or "MODE-VARIANT"; "...-random" with randomize_target
    where present) of the recipe's YAML file (or of ``path``)."""
    import yaml

    if recipe not in FILES:
        raise ValueError(f"recipe must be one of {sorted(FILES)}, got {recipe!r}")
    path = Path(path) if path is not None else HYPERPARAMS / FILES[recipe]
    table = yaml.safe_load(path.read_text())
    key = control_mode if variant is None else f"{control_mode}-{variant}"
    if env_id not in table or key not in table[env_id]:
        known = {k: sorted(v) for k, v in table.items()}
        raise KeyError(f"no {recipe} hyperparameters for {env_id!r} / {key!r} in {path}; it has {known}")
    if randomize_target and f"{key}-random" in table[env_id]:
        key = f"{key}-random"
    return dict(table[env_id][key])
