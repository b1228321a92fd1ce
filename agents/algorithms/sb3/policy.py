"""Saved stable-baselines3 models as policies: any run of `agents.algorithms.sb3.training.train`
and the agents shipped with the package (``agents/models/NAME``, found by name from anywhere).

Their files are pickle: a folder loads only when it is trusted (agents.files.require_trusted:
shipped or published with the package, written by a run on this machine, or ``trust=True``), and
only the files its manifest lists, from the bytes that were checked."""

from __future__ import annotations

import io
import pickle
from pathlib import Path

import numpy as np

from agents.algorithms.sb3.libraries import OFF_POLICY, algorithm_class
from agents.files import require_trusted
from scara_gym.model.checks import UserError
from scara_gym.wrappers import residual_setpoint

SHIPPED_MODELS = Path(__file__).resolve().parents[2] / "models"
MODEL_FILES = ("config.json", "model.zip", "vecnormalize.pkl")
"""the files an SB3 model folder's policy loads: each one that the folder holds must be in its manifest"""




def shipped_models() -> list[str]:
    """Names of the agents shipped with the package (agents/models/NAME)."""
    return sorted(p.parent.name for p in SHIPPED_MODELS.glob("*/model.zip"))


def resolve_model(name_or_path: str | Path) -> Path:
    """A model folder: the name of a shipped model (a plain name: a folder of that name in the working
    folder does not shadow it; give it as ./NAME), else an existing path."""
    if str(name_or_path) in shipped_models():
        return SHIPPED_MODELS / str(name_or_path)
    path = Path(name_or_path)
    if (path / "model.zip").exists():
        return path
    raise FileNotFoundError(f"no PPO model at {str(name_or_path)!r}: give a folder with model.zip "
                            f"or a shipped model name {shipped_models()}")


def load_model(algo: str, library: str, data: bytes):
    """A saved model's bytes (already checked) as the model that acts: on the CPU, and for an
    off-policy one a 1-entry plain replay buffer (acting needs none; a HER buffer would need the env)."""
    replay = {"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1} \
        if algo in OFF_POLICY else None
    return algorithm_class(algo, library).load(io.BytesIO(data), device="cpu", custom_objects=replay)


class SB3Policy:
    """A model saved by `train` (or a shipped one) as an obs -> action policy for one env."""

    def __init__(self, env, model_dir: str | Path, trust: bool = False) -> None:
        model_dir = Path(model_dir)
        if not (model_dir / "model.zip").is_file():
            other = " (a torch PPO run: torchppo:DIR)" if (model_dir / "model.pt").is_file() else ""
            raise FileNotFoundError(f"{model_dir}: no SB3 model.zip{other}")
        # its files, read once and checked against a trusted manifest: what loads is what was checked
        checked = require_trusted(model_dir, trust, MODEL_FILES)
        self.env = env.unwrapped
        config = checked.json("config.json")
        trained_mode = config["env_kwargs"]["control_mode"]
        if trained_mode != self.env.control_mode:
            raise UserError(f"{model_dir} was trained in {trained_mode!r} mode, "
                            f"the environment is in {self.env.control_mode!r} mode")
        algo = config.get("algo", "ppo")
        model = load_model(algo, config["hyperparams"].get("library", "sb3"), checked.bytes("model.zip"))
        normalizer = pickle.loads(checked.bytes("vecnormalize.pkl")) if "vecnormalize.pkl" in checked else None
        self._attach(model, normalizer, config["hyperparams"])
        self.config = config
        self.name = f"{algo} ({model_dir.name})"

    @classmethod
    def of_model(cls, env, model, hyper: dict, name: str = "live model") -> SB3Policy:
        """The policy of a model in training (its VecNormalize's statistics as they are now, its
        block's residual set-point): what a saved run of it would act, without saving it."""
        policy = cls.__new__(cls)
        policy.env, policy.config, policy.name = env.unwrapped, {"hyperparams": hyper}, name
        policy._attach(model, model.get_vec_normalize_env(), hyper)
        return policy

    def _attach(self, model, normalizer, hyper: dict) -> None:
        self.model = model
        self.normalizer = normalizer if normalizer is not None and normalizer.norm_obs else None
        self.mapping = residual_setpoint(self.env, hyper.get("residual_scale"), hyper.get("residual_deadzone", 0.0))

    def reset(self) -> None:
        pass

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if isinstance(obs, dict):  # a goal env's observation: the normalizer knows its keys
            x = obs if self.normalizer is None else self.normalizer.normalize_obs(obs)
            return self.model.predict(x, deterministic=True)[0]
        x = np.asarray(obs, dtype=np.float64)
        if self.normalizer is not None:
            n = self.normalizer
            x = np.clip((x - n.obs_rms.mean) / np.sqrt(n.obs_rms.var + n.epsilon), -n.clip_obs, n.clip_obs)
        action, _ = self.model.predict(x.astype(np.float32), deterministic=True)
        return action if self.mapping is None else self.mapping(obs, action)[0]


class PPOPolicy(SB3Policy):
    """A saved PPO agent (a folder, or a shipped model's name) as an obs -> action policy."""

    def __init__(self, env, model_dir: str | Path, trust: bool = False) -> None:
        model_dir = resolve_model(model_dir)
        super().__init__(env, model_dir, trust)
        self.name = f"ppo ({model_dir.name})"
