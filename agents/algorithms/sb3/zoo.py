"""A model trained by RL Zoo as a policy: the folder ``python -m rl_zoo3.train --algo ALGO --env
ENV_ID --gym-packages scara_gym --conf-file OUT/rl_zoo.yml -f LOGS`` writes, ``LOGS/ALGO/ENV_ID_N``.

So a recipe the search published in RL Zoo's format (agents.experiments.search.rl_zoo_block) can
be trained with RL Zoo's own command and scored by this project's protocol and comparison, as the
runs trained here are (``scara-agents evaluate zoo:LOGS/ppo/Scara-C11-v2_1 --trust``).

RL Zoo's folder holds its final model (``ENV_ID.zip``), and beside it ``ENV_ID/``: the
hyperparameters it trained with (``config.yml``), its arguments (``args.yml``) and the observation
normalizer (``vecnormalize.pkl``). Its YAML files carry Python's OrderedDict tag; they are read
with YAML's safe loader, that tag taken as the list of pairs it is (nothing else is constructed).
Its model and normalizer are pickle and RL Zoo writes no manifest: the folder loads only when it
is trusted (``--trust``; agents.files.require_trusted).
"""

from __future__ import annotations

import pickle
from pathlib import Path

import gymnasium as gym

from agents.algorithms.sb3.policy import SB3Policy, load_model
from agents.files import require_trusted
from scara_gym.envs.config import EnvConfig
from scara_gym.extras import require
from scara_gym.model.checks import UserError

ZOO_LIBRARIES = {"ppo": "sb3", "sac": "sb3", "td3": "sb3", "tqc": "sb3-contrib"}
"""RL Zoo's algorithms this loader acts with -> the library that holds them here"""
ORDERED_DICT_TAG = "tag:yaml.org,2002:python/object/apply:collections.OrderedDict"


def zoo_yaml(path: Path, data: bytes) -> dict:
    """An RL Zoo YAML file (config.yml, args.yml) as a dict, read by YAML's safe loader."""
    require("yaml")
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def ordered(loader, node):  # [[key, value], ...]: the OrderedDict's items
        return dict(loader.construct_sequence(node.value[0], deep=True)) if node.value else {}

    Loader.add_constructor(ORDERED_DICT_TAG, ordered)
    try:
        value = yaml.load(data, Loader=Loader)  # noqa: S506 (a SafeLoader subclass: it constructs no object)
    except yaml.YAMLError as error:
        raise UserError(f"{path}: not a YAML file RL Zoo writes ({str(error).splitlines()[0]})") from None
    if not isinstance(value, dict):
        raise UserError(f"{path}: not a YAML file RL Zoo writes (it holds {type(value).__name__})")
    return value


def zoo_run(run_dir: Path) -> str:
    """The env id of the RL Zoo folder ``run_dir``: the name of its one subfolder with args.yml."""
    if not run_dir.is_dir():
        raise FileNotFoundError(f"no RL Zoo folder {str(run_dir)!r}")
    found = sorted(d.name for d in run_dir.iterdir() if (d / "args.yml").is_file())
    if len(found) != 1 or not (run_dir / f"{found[0]}.zip").is_file():
        raise FileNotFoundError(f"{run_dir}: not a folder RL Zoo writes (LOGS/ALGO/ENV_ID_N, with ENV_ID.zip and "
                                "ENV_ID/args.yml)")
    return found[0]


class ZooPolicy(SB3Policy):
    """A model RL Zoo trained (module docstring) as an obs -> action policy for one env."""

    def __init__(self, env, run_dir: str | Path, trust: bool = False) -> None:
        run_dir = Path(run_dir)
        env_id = zoo_run(run_dir)
        files = (f"{env_id}.zip", f"{env_id}/config.yml", f"{env_id}/args.yml", f"{env_id}/vecnormalize.pkl")
        checked = require_trusted(run_dir, trust, files)
        arguments = zoo_yaml(run_dir / files[2], checked.bytes(files[2]))
        config = zoo_yaml(run_dir / files[1], checked.bytes(files[1]))
        algo = arguments.get("algo")
        if algo not in ZOO_LIBRARIES:
            raise UserError(f"{run_dir}: RL Zoo's {algo!r} is not one this loader acts with ({sorted(ZOO_LIBRARIES)})")
        self.env = env.unwrapped
        env_kwargs = {**gym.spec(env_id).kwargs, **(config.get("env_kwargs") or {}), **(arguments.get("env_kwargs") or {})}
        trained_mode = env_kwargs.get("control_mode", EnvConfig.control_mode)
        if trained_mode != self.env.control_mode:
            raise UserError(f"{run_dir} was trained in {trained_mode!r} mode, the environment is in "
                            f"{self.env.control_mode!r} mode")
        model = load_model(algo, ZOO_LIBRARIES[algo], checked.bytes(files[0]))
        normalizer = pickle.loads(checked.bytes(files[3])) if files[3] in checked else None
        self._attach(model, normalizer, {})
        self.config = {"algo": algo, "env_id": env_id, "hyperparams": config, "trained_by": "rl_zoo3"}
        self.name = f"{algo} (RL Zoo, {run_dir.name})"
