"""Behaviour cloning from an offline dataset (Minari's format), in one file.

The offline baseline of the datasets (agents.experiments.datasets): an MLP regresses the
dataset's actions on its observations (mean squared error, tanh output in [-1, 1], observations
standardized with the dataset's mean and spread), trained for a fixed number of Adam steps on
minibatches drawn with the run's seed, as CORL's ``any_percent_bc`` does with the whole dataset.
Nothing is tuned on an evaluation: the run keeps its last weights. `BCPolicy` acts with
them.

With ``residual_scale`` the MLP clones in the residual set-point's space of the engineered agents
(scara_gym.wrappers.residual): its targets are the outputs r the map turns into the recorded
actions (``ResidualSetpoint.agent_actions``), and a recorded set-point on the target (within
`ON_TARGET`: the float32 rounding of the recorded observation and action) is r = 0, the
deadzone's middle. A plain clone cannot succeed here: the 0.001 success band asks its set-point for
a precision of about 4e-4 action units, and no regression of the whole path gets there. A run folder holds model.pt (weights and normalizer, loaded with weights_only),
config.json (this Config, the dataset's id and size, the training time) and SHA256SUMS.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from scara_gym.extras import require

require("torch")
import torch
from torch import nn

from agents.algorithms.bc_config import BCConfig
from agents.algorithms.offline_data import checked_episodes, environment, load
from agents.files import (
    POLICY_FILES,
    WEIGHTS_FILES,
    claim_run_folder,
    exclusive,
    json_record,
    load_torch,
    save_torch,
    verify_digests,
    write_digests,
    write_json,
)
from scara_gym.envs.task import OBSERVATION_LAYOUT
from scara_gym.model.checks import UserError
from scara_gym.wrappers import ResidualSetpoint, residual_setpoint

CLONED = ("bc", "dagger")
"""the runs whose policy is this file's MLP: behaviour cloning's and DAgger's (agents.algorithms.dagger)"""
ON_TARGET = 1e-5
"""[rad, m] a recorded set-point this close to the target is the target (r = 0)"""
Q, TARGET_ERROR = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["target_error"]


def residual_outputs(mapping: ResidualSetpoint, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """The residual outputs r in [-1, 1] that ``mapping`` turns into the recorded ``actions``
    ("pd" mode), with r = 0 where the recorded set-point is the target."""
    r = mapping.agent_actions(obs, actions)
    offset = mapping.env.action_to_setpoint(np.asarray(actions, dtype=float)) - (obs[:, Q] + obs[:, TARGET_ERROR])
    return np.where(np.abs(offset) < ON_TARGET, 0.0, r).astype(np.float32)


def transitions(dataset_id: str, config: BCConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(observations, targets) of every step of a Minari dataset: each recorded action (with
    ``config.residual_scale``: its residual output, residual_outputs) with the observation it was
    taken in. The dataset loads without running code (agents.algorithms.offline_data.load) and an
    episode with values that are not finite or outside their spaces is refused by name."""
    dataset = load(dataset_id)  # never runs the entry point the dataset names
    env = environment(dataset)
    obs, actions = [], []
    for episode in checked_episodes(dataset, env):  # no NaN, nothing outside the spaces
        obs.append(episode.observations[:-1])
        actions.append(episode.actions)
    obs, actions = np.concatenate(obs).astype(np.float32), np.concatenate(actions).astype(np.float32)
    if config is not None and config.residual_scale is not None:
        mapping = residual_setpoint(env.unwrapped, config.residual_scale, config.residual_deadzone)
        actions = residual_outputs(mapping, obs, actions)
    return obs, actions


class Actor(nn.Module):
    """Standardized observation -> MLP -> tanh action."""

    def __init__(self, obs_size: int, action_size: int, hidden: int, layers: int) -> None:
        super().__init__()
        sizes = [obs_size] + [hidden] * layers
        blocks: list[nn.Module] = []
        for a, b in zip(sizes, sizes[1:]):
            blocks += [nn.Linear(a, b), nn.ReLU()]
        self.body = nn.Sequential(*blocks, nn.Linear(sizes[-1], action_size), nn.Tanh())
        self.register_buffer("mean", torch.zeros(obs_size))
        self.register_buffer("scale", torch.ones(obs_size))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.body((obs - self.mean) / self.scale)


def fit(actor: Actor, optimizer, obs: np.ndarray, targets: np.ndarray, steps: int, batch_size: int,
        generator: torch.Generator) -> float:
    """``steps`` Adam steps of the mean squared error on minibatches drawn with ``generator``;
    returns the final loss on all of the data."""
    obs_t, targets_t = torch.as_tensor(obs), torch.as_tensor(targets)
    for _ in range(steps):
        rows = torch.randint(len(obs_t), (batch_size,), generator=generator)
        loss = ((actor(obs_t[rows]) - targets_t[rows]) ** 2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    with torch.no_grad():
        return float(((actor(obs_t) - targets_t) ** 2).mean())


def run_record(config: BCConfig) -> dict:
    """What a run of ``config`` is, for agents.files.claim_run_folder."""
    settings = {k: v for k, v in config.to_dict().items() if k not in ("out", "torch_threads")}
    return {"trainer": "bc", "algo": "bc", "env_id": None, "control_mode": "pd", "seed": config.seed,
            "settings": settings}


def train(config: BCConfig, overwrite: bool = False, resume: bool = False) -> dict:
    """Train and write the run folder; returns its record (config.json). A run is minutes long
    and keeps no checkpoint: ``resume`` finds a finished run and leaves it, an unfinished one is
    trained again."""
    out = Path(config.out)
    started = time.perf_counter()
    finished = resume and (out / "model.pt").exists() and (out / "summary.json").exists()
    # the dataset is loaded and checked before the folder is made: a refused one leaves nothing behind
    data = None if finished else transitions(config.dataset, config)
    with exclusive(out):
        claim_run_folder(out, run_record(config), resume, overwrite)
        if resume and (out / "model.pt").exists() and (out / "summary.json").exists():
            return json_record(out / "config.json")
        if config.torch_threads:
            torch.set_num_threads(config.torch_threads)
        torch.manual_seed(config.seed)
        obs, actions = data if data is not None else transitions(config.dataset, config)
        actor = Actor(obs.shape[1], actions.shape[1], config.hidden_size, config.layers)
        actor.mean.copy_(torch.as_tensor(obs.mean(0)))
        actor.scale.copy_(torch.as_tensor(obs.std(0) + 1e-6))
        optimizer = torch.optim.Adam(actor.parameters(), lr=config.learning_rate)
        generator = torch.Generator().manual_seed(config.seed)
        final_loss = fit(actor, optimizer, obs, actions, config.steps, config.batch_size, generator)
        save_torch({"state_dict": actor.state_dict(), "obs_size": obs.shape[1], "action_size": actions.shape[1],
                    "hidden_size": config.hidden_size, "layers": config.layers}, out / "model.pt")
        summary = {"train_seconds": time.perf_counter() - started, "transitions": len(obs), "final_loss": final_loss}
        write_json(out / "summary.json", summary)
        record = {**config.to_dict(), "algo": "bc", "trainer": "bc", "control_mode": "pd", **summary}
        write_json(out / "config.json", record)
        write_digests(out, POLICY_FILES)
    return record


class ActorPolicy:
    """An Actor as an obs -> env action policy through ``mapping`` (a residual map of
    scara_gym.wrappers.residual; None: the actor's outputs are the env's actions)."""

    def __init__(self, actor: Actor, mapping, name: str) -> None:
        self.actor, self.mapping, self.name = actor, mapping, name

    def reset(self) -> None:
        pass

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            output = self.actor(torch.as_tensor(np.asarray(obs, dtype=np.float32))[None])[0].numpy().astype(np.float64)
        return output if self.mapping is None else self.mapping(obs, output)[0]


class BCPolicy(ActorPolicy):
    """A behaviour-cloning (or DAgger) run as an obs -> action policy."""

    def __init__(self, env, run_dir: str | Path) -> None:
        run_dir = Path(run_dir)
        if not (run_dir / "model.pt").exists():
            raise FileNotFoundError(f"no model.pt in {str(run_dir)!r}: give a folder written by agents.algorithms.bc")
        checked = verify_digests(run_dir, WEIGHTS_FILES)  # read once: what loads is what was checked
        record = checked.json("config.json")
        if record.get("algo") not in CLONED:
            other = " (a torch PPO run: torchppo:DIR)" if record.get("algo") == "torch-ppo" else ""
            raise UserError(f"{run_dir}: not a behaviour-cloning or DAgger run (its config.json says algo "
                            f"{record.get('algo')!r}){other}")
        mode = record.get("control_mode", "pd")
        if env.unwrapped.control_mode != mode:
            raise UserError(f"{run_dir} clones {mode!r} mode actions, the environment is in "
                            f"{env.unwrapped.control_mode!r} mode")
        saved = load_torch(run_dir / "model.pt", data=checked.bytes("model.pt"))
        actor = Actor(saved["obs_size"], saved["action_size"], saved["hidden_size"], saved["layers"])
        actor.load_state_dict(saved["state_dict"])
        actor.eval()
        config = BCConfig(**{k: v for k, v in record.items() if k in BCConfig.__dataclass_fields__})
        super().__init__(actor, residual_setpoint(env.unwrapped, config.residual_scale, config.residual_deadzone,
                                                  record.get("residual_on", "setpoint")),
                         f"{record['algo']} ({run_dir.name})")
