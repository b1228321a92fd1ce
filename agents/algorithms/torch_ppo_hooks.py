"""The single-file PPO's research add-ons, as hooks beside the algorithm.

`agents.algorithms.torch_ppo.train` is plain PPO; it calls each `Hook` at five
points (the first observations, each step's results, episodes that end, the actions sent to the
environment, the minibatch gradient) and knows nothing of what they do. `hooks_for` builds the hooks a
`Config`'s add-on fields ask for:

- ``demo_resets``: reference state initialization on the optimal reference's path (DemoResets);
- ``demo_bc``: behaviour cloning of the optimal reference's steps, DAPG (DemoCloning);
- ``target_replay``: failed-target replay for drawn targets (TargetReplay);
- ``shield``: shielded RL behind `scara_gym.wrappers.Shield` (ShieldedActions);
- ``cost_limit``: PPO-Lagrangian on the collision cost ``info["cost"]`` (Lagrangian).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from scara_gym.extras import require

require("torch")
import torch

from agents.algorithms.torch_ppo_config import Config
from agents.policies.optimal import reference_demonstration, reference_snapshots
from scara_gym.wrappers import Shield


class Hook:
    """A research add-on of the training loop; every method leaves training as it is by default."""

    def before_training(self, agent) -> None:
        """Once, before the first rollout of a run that starts afresh (not resumed, not fine-tuned)."""

    def on_start(self, obs: np.ndarray) -> np.ndarray:
        """The first observations of the vector env (a numpy batch); returns them, changed or not."""
        return obs

    def on_episodes_end(self, obs: np.ndarray, rows: list[int], info: dict) -> np.ndarray:
        """After a step where the robots ``rows`` ended their episodes (autoreset: obs are their new
        episodes' first); info is the step's. Returns obs, changed or not."""
        return obs

    def on_step(self, env_actions, next_obs, reward, terminated, truncated, info) -> None:
        """After every vector step, with what the environment returned (numpy on the CPU env;
        SameStep autoreset: the ended rows' final observations are in info["final_obs"])."""

    def filter_actions(self, envs, env_actions: np.ndarray) -> np.ndarray:
        """The actions the environment applies, from the ones the agent chose (mapped); ``envs``:
        the unwrapped vector env."""
        return env_actions

    def shape_reward(self, reward, info: dict):
        """The reward PPO learns from (a tensor, one per robot), from the environment's; the
        episodes' logged returns stay the environment's."""
        return reward

    def on_rollout_end(self) -> None:
        """After each rollout, before its advantages."""

    def loss_gradients(self, agent, update: int) -> dict | None:
        """{parameter name: gradient} to add to PPO's on each minibatch of ``update``, or None."""
        return None

    def log(self, writer, global_step: int, samples: int) -> None:
        """Scalars for TensorBoard after an update of ``samples`` environment steps."""

    def state_dict(self) -> dict:
        """What a checkpoint keeps of the hook (numbers and lists only), so that a resumed run goes on from it."""
        return {}

    def load_state_dict(self, state: dict) -> None:
        """Continue from a checkpoint's ``state_dict()``."""


class DemoResets(Hook):
    """Reference state initialization (DeepMimic's RSI, Peng et al. 2018): each training episode
    starts, with probability ``config.demo_resets``, from a state the optimal reference
    (agents.policies.optimal) passes through at a uniformly drawn control step, instead of at rest.
    Only the states are borrowed, not the reference's actions: the agent still learns what to do
    there from the reward, but it meets the critical band with axis 3 at the widened voltage,
    which the minimum-time path uses and exploration from rest rarely finds. The reference with
    the default 1 mm wall margin passes the wall so closely that from its states in the band an
    imperfect policy cannot avoid a collision; ``demo_wall_margin`` picks a reference that keeps
    more. Evaluation always starts at rest. Needs the C11 start and target and fixed parameters."""

    def __init__(self, envs, config: Config) -> None:
        if not 0.0 <= config.demo_resets <= 1.0:
            raise ValueError(f"demo_resets must be in [0, 1], got {config.demo_resets!r}")
        if config.randomize_target or config.randomize_params or config.device != "cpu":
            raise ValueError("demo_resets: the reference path is the C11 target's with the nominal parameters, "
                             "on the CPU env; use it without randomize_target, randomize_params and device='cuda'")
        self.envs = envs.unwrapped
        self.snapshots = reference_snapshots(config.env_id, params=self.envs.params,
                                             wall_margin=config.demo_wall_margin)
        self.probability = config.demo_resets
        self.rng = np.random.default_rng(config.seed)

    def on_start(self, obs: np.ndarray) -> np.ndarray:
        return self(obs, range(len(obs)))

    def on_episodes_end(self, obs: np.ndarray, rows: list[int], info: dict) -> np.ndarray:
        return self(obs, rows)

    def __call__(self, obs: np.ndarray, rows) -> np.ndarray:
        """obs with the robots of ``rows`` (just reset) moved to reference states where drawn."""
        for i in rows:
            if self.rng.random() < self.probability:
                self.envs.restore(int(i), self.snapshots[self.rng.integers(len(self.snapshots))])
                obs[i] = self.envs.noise_free_observation(int(i))
        return obs


class DemoCloning(Hook):
    """Demonstration-augmented policy gradient (DAPG, Rajeswaran et al. 2018): the optimal
    reference's steps on the C11 target (agents.policies.optimal.reference_demonstration, the reference
    with ``demo_wall_margin``), turned into the agent's own outputs by the residual set-point's
    inverse (ResidualSetpoint.agent_actions), give a behaviour-cloning term
    ``weight * mean ||mean action - demo action||^2`` added to PPO's loss, its weight
    ``demo_bc * demo_bc_decay ** (update - 1)``; ``demo_bc_pretrain`` Adam steps on it alone
    start the policy there (its observation normalizer from the demonstration's states). The
    agent learns from the reward where the reference's path does not reach: the band it leaves
    by a hair, the states a policy that is not exact visits."""

    def __init__(self, envs, config: Config, mapping) -> None:
        if config.demo_bc < 0 or not 0.0 < config.demo_bc_decay <= 1.0 or config.demo_bc_pretrain < 0:
            raise ValueError(f"demo_bc must be >= 0, demo_bc_decay in (0, 1], demo_bc_pretrain >= 0; got "
                             f"{config.demo_bc!r}, {config.demo_bc_decay!r}, {config.demo_bc_pretrain!r}")
        if (mapping is None or config.residual_on != "setpoint" or config.control_mode != "voltage"
                or config.randomize_target or config.randomize_params or config.device != "cpu"):
            raise ValueError("demo_bc: the demonstration is the C11 target's voltages with the nominal parameters, "
                             "in the residual set-point's outputs; use it with control_mode='voltage' and "
                             "residual_scale, without randomize_target and randomize_params, on the CPU")
        observations, actions = reference_demonstration(config.env_id, params=envs.unwrapped.params,
                                                        wall_margin=config.demo_wall_margin)
        self.obs = torch.as_tensor(observations.astype(np.float32))
        self.actions = torch.as_tensor(mapping.agent_actions(observations, actions), dtype=torch.float32)
        self.config = config

    def weight(self, update: int) -> float:
        return self.config.demo_bc * self.config.demo_bc_decay ** (update - 1)

    def before_training(self, agent) -> None:
        if self.config.demo_bc_pretrain:
            loss = self.pretrain(agent, self.config.demo_bc_pretrain, 1e-3)
            print(f"behaviour cloning: loss {loss:.2e} after {self.config.demo_bc_pretrain} steps", flush=True)

    def loss_gradients(self, agent, update: int) -> dict | None:
        weight = self.weight(update)
        return self.gradients(agent, weight) if weight else None

    def gradients(self, agent, weight: float) -> dict:
        """{parameter name: gradient} of the cloning term at ``weight`` (autograd: one small batch)."""
        with torch.enable_grad():
            mean = agent.heads(agent.normalize(self.obs))[0]
            loss = weight * ((mean - self.actions) ** 2).sum(-1).mean()
            names, parameters = zip(*agent.named_parameters())
            grads = torch.autograd.grad(loss, parameters, allow_unused=True)
        return {name: torch.zeros_like(p) if g is None else g for name, p, g in zip(names, parameters, grads)}

    def pretrain(self, agent, steps: int, learning_rate: float) -> float:
        """``steps`` Adam steps on the cloning term alone (weight 1), the observation normalizer
        set to the demonstration's states first; returns the last loss."""
        agent.obs_rms.mean.copy_(self.obs.double().mean(0))
        agent.obs_rms.var.copy_(self.obs.double().var(0) + 1e-4)
        agent.obs_rms.count.fill_(len(self.obs))
        optimizer = torch.optim.Adam(agent.parameters(), lr=learning_rate)
        loss = torch.tensor(float("nan"))
        for _ in range(steps):
            mean = agent.heads(agent.normalize(self.obs))[0]
            loss = ((mean - self.actions) ** 2).sum(-1).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        return float(loss.detach())


class TargetReplay(Hook):
    """Failed-target replay for targets drawn per episode (a plain form of prioritized level
    replay, Jiang et al. 2021): the targets of training episodes that ended without success or
    with a collision are kept (the newest ``capacity``), and each new episode gets one of them,
    drawn uniformly, with probability ``config.target_replay`` instead of a fresh draw. A kept
    target leaves once an episode on it succeeds without a collision. Rare corners of the
    target range where the agent stops short or collides thus come back until it masters them;
    training targets only, so the evaluation's targets never enter."""

    def __init__(self, envs, config: Config, capacity: int = 256) -> None:
        if not 0.0 <= config.target_replay <= 1.0:
            raise ValueError(f"target_replay must be in [0, 1], got {config.target_replay!r}")
        if not config.randomize_target or config.device != "cpu":
            raise ValueError("target_replay: replays drawn targets; use it with randomize_target=True on the CPU env")
        self.envs = envs.unwrapped
        self.probability, self.capacity = config.target_replay, capacity
        self.rng = np.random.default_rng(config.seed)
        self.failed: list[np.ndarray] = []
        self.targets = self.envs.targets  # each robot's current episode's (a copy)
        self.replayed: list[np.ndarray | None] = [None] * len(self.targets)

    def on_episodes_end(self, obs: np.ndarray, rows: list[int], info: dict) -> np.ndarray:
        return self(obs, rows, info["is_success"], info["collisions"] > 0)

    def __call__(self, obs: np.ndarray, rows, success, collided) -> np.ndarray:
        """Book the episodes of ``rows`` that just ended (success, collided: per robot), then give
        each of those robots' new episode a failed target where drawn."""
        for i in rows:
            i = int(i)
            solved = bool(success[i]) and not bool(collided[i])
            if solved and self.replayed[i] is not None:
                self.failed = [t for t in self.failed if t is not self.replayed[i]]
            elif not solved and self.replayed[i] is None:
                self.failed = (self.failed + [self.targets[i].copy()])[-self.capacity:]
            self.replayed[i] = None
            if self.failed and self.rng.random() < self.probability:
                target = self.failed[self.rng.integers(len(self.failed))]
                self.envs.reset_robot(i, {"target": target}, rng=self.rng)
                obs[i] = self.envs.noise_free_observation(i)
                self.replayed[i] = target
            self.targets[i] = self.envs.targets[i]
        return obs


class ShieldedActions(Hook):
    """Shielded RL: every robot's action goes through `scara_gym.wrappers.Shield` (its model:
    the nominal parameters) before the environment applies it; the agent's own action is the one
    stored, the shield being part of the environment as the agent sees it. CPU only."""

    def __init__(self, config: Config) -> None:
        if config.device != "cpu":
            raise ValueError("shield: the shield's model runs on the CPU; train with device='cpu'")
        self.shield = Shield(gym.make(config.env_id, control_mode=config.control_mode), None)
        self.interventions = 0

    def filter_actions(self, envs, env_actions):
        env_actions = np.array(env_actions, dtype=np.float64)
        for i in range(len(env_actions)):
            env_actions[i], replaced = self.shield.filter(envs, i, env_actions[i])
            self.interventions += replaced
        return env_actions

    def log(self, writer, global_step: int, samples: int) -> None:
        writer.add_scalar("charts/shield_interventions", self.interventions / samples, global_step)
        self.interventions = 0


class Lagrangian(Hook):
    """PPO-Lagrangian on the collision cost: PPO maximizes the reward minus lambda x the step's
    cost (``info["cost"]``: 1 for a step that collided), and lambda follows projected dual ascent
    on the constraint "mean episode cost <= cost_limit": after each rollout,
    lambda <- max(0, lambda + lagrange_lr x (mean cost of the episodes that ended in it - cost_limit)).
    This is the penalty form of the Lagrangian relaxation (RCPO, Tessler et al. 2019: one critic
    on the penalized return, the multiplier on a slower timescale); the "PPO-Lagrangian" of Ray et
    al. 2019 weighs a separate cost critic's advantages instead. With cost_limit 0 the multiplier
    rises while any training episode collides and never falls. The multiplier is kept in the
    checkpoint; the logs show it and the episode cost."""

    def __init__(self, config: Config) -> None:
        if config.cost_limit is None:
            raise ValueError("Lagrangian: cost_limit must be set (the episode cost allowed, e.g. 0)")
        self.limit, self.step_size = float(config.cost_limit), float(config.lagrange_lr)
        self.multiplier = float(config.lagrange_init)
        self.episode_cost: np.ndarray | None = None
        self.cost: np.ndarray | None = None  # the last step's, per robot
        self.finished: list[float] = []  # the episode costs of this rollout
        self.mean_cost = float("nan")  # of the last rollout's finished episodes

    def on_step(self, env_actions, next_obs, reward, terminated, truncated, info) -> None:
        self.cost = np.asarray(info["cost"], dtype=np.float64)
        self.episode_cost = self.cost.copy() if self.episode_cost is None else self.episode_cost + self.cost
        ended = np.asarray(terminated) | np.asarray(truncated)
        if ended.any():
            self.finished += self.episode_cost[ended].tolist()
            self.episode_cost[ended] = 0.0

    def shape_reward(self, reward, info: dict):
        cost = torch.as_tensor(self.cost, dtype=reward.dtype, device=reward.device)
        return reward - self.multiplier * cost

    def on_rollout_end(self) -> None:
        if self.finished:  # a rollout where no episode ended leaves the multiplier as it is
            self.mean_cost = float(np.mean(self.finished))
            self.multiplier = max(0.0, self.multiplier + self.step_size * (self.mean_cost - self.limit))
            self.finished = []

    def log(self, writer, global_step: int, samples: int) -> None:
        writer.add_scalar("charts/lagrange_multiplier", self.multiplier, global_step)
        writer.add_scalar("charts/episode_cost", self.mean_cost, global_step)

    def state_dict(self) -> dict:
        return {"multiplier": self.multiplier}

    def load_state_dict(self, state: dict) -> None:
        self.multiplier = float(state["multiplier"])


def hooks_for(config: Config, envs, mapping) -> list[Hook]:
    """The hooks that ``config``'s add-on fields ask for, in the order the loop calls them."""
    hooks: list[Hook] = []
    if config.demo_bc or config.demo_bc_pretrain:
        hooks.append(DemoCloning(envs, config, mapping))
    if config.demo_resets:
        hooks.append(DemoResets(envs, config))
    if config.target_replay:
        hooks.append(TargetReplay(envs, config))
    if config.shield:
        hooks.append(ShieldedActions(config))
    if config.cost_limit is not None:
        hooks.append(Lagrangian(config))
    return hooks
