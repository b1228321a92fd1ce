"""PPO in one file, CleanRL style: torch only, no stable-baselines3 in its loop.

It trains on the native vector env, on the CPU (numpy arrays in, torch tensors made once per
step) or on its CUDA backend (``--device cuda``: the env, the rollout buffer, the network and
the updates all stay on the GPU). Read top to bottom: the config, the running normalizers,
the agent, Adam, the loss and its gradient written out (small networks on a CPU are bound by
the count of tensor operations: autograd's graph and torch.optim's bookkeeping cost more
than the arithmetic, and tests hold both to torch's), the rollout and the update.

    python -m agents.torch_ppo --env-id Scara-C11-v1 --total-timesteps 2000000 --out runs/torch_ppo
    python -m agents.torch_ppo --device cuda --num-envs 4096 --num-steps 32 --out runs/torch_ppo_gpu
    python -m agents.evaluate --policies torchppo:runs/torch_ppo --env-id Scara-C11-v1

``--shield`` trains and evaluates the agent behind agents.shield's model-predictive shield
(shielded RL: the environment applies the shield's action, the agent's own is stored; CPU).

A run folder holds ``config.json``, ``model.pt`` (the policy and its observation normalizer,
what ``TorchPPOPolicy`` loads), ``checkpoint.pt`` (everything to resume: ``--resume``) and
TensorBoard logs under ``tb/``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from torch import nn

import scara_gym  # noqa: F401  (registers the ids)


@dataclass
class Config:
    env_id: str = "Scara-C11-v1"
    control_mode: str = "pd"
    randomize_target: bool = False
    randomize_params: str = ""     # domain randomization per episode: a preset of scara_gym.envs.randomization ("all")
    reward_weights: str = ""       # env reward weights to change, "energy=0.05,time=20" ("": the env's)
    residual_scale: str = ""       # "2.5,2.5,0.05": act through agents.residual's set-point around the target
    residual_deadzone: float = 0.2 # (an engineered agent, not plain PPO; "": the env's actions as they are)
    device: str = "cpu"            # where the env runs and the agent trains: "cpu" or "cuda"
    seed: int = 0
    num_envs: int = 16
    num_steps: int = 128           # rollout length per env; a batch is num_envs * num_steps
    total_timesteps: int = 1_000_000
    learning_rate: float = 3e-4
    anneal_lr: bool = True
    gamma: float = 0.99
    gae_lambda: float = 0.95
    num_minibatches: int = 32
    update_epochs: int = 10
    clip_coef: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden_size: int = 64
    normalize_reward: bool = True  # scale rewards by the running std of the discounted return
    clip_obs: float = 10.0
    env_threads: int = 1           # numba threads of the CPU env (torch takes the cores between steps)
    torch_threads: int = 0         # 0: torch's default
    compile: bool = False          # torch.compile the minibatch gradient
    checkpoint_every: int = 10     # updates between checkpoints
    init_from: str = ""            # a finished run of this file to start from (its model.pt), e.g. to fine-tune
    demo_resets: float = 0.0       # share of training episodes that start on the optimal reference's path (DemoResets)
    demo_wall_margin: float = 1e-3 # m, the wall margin of that reference (a shipped solution of agents.optimal)
    target_replay: float = 0.0     # share of training episodes given a target the agent recently failed (TargetReplay)
    shield: bool = False           # act behind agents.shield's Shield, in training and evaluation (shielded RL)
    demo_bc: float = 0.0           # weight of the behaviour-cloning term on the optimal reference's steps (DemoCloning)
    demo_bc_decay: float = 1.0     # that weight's factor per update (DAPG's decay)
    demo_bc_pretrain: int = 0      # Adam steps on the cloning term alone before the first rollout
    init_log_std: float = 0.0      # the policy's initial log standard deviation
    out: str = "runs/torch_ppo"

    @property
    def batch_size(self) -> int:
        return self.num_envs * self.num_steps

    @property
    def minibatch_size(self) -> int:
        return self.batch_size // self.num_minibatches


LOG_SQRT_2PI = 0.5 * float(np.log(2 * np.pi))


class RunningMeanStd(nn.Module):
    """Running mean and variance (parallel algorithm), kept as buffers so they save with the model."""

    def __init__(self, shape=()) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(shape, dtype=torch.float64))
        self.register_buffer("var", torch.ones(shape, dtype=torch.float64))
        self.register_buffer("count", torch.tensor(1e-4, dtype=torch.float64))

    def update(self, x: torch.Tensor) -> None:
        x = x.to(torch.float64)
        batch_mean, batch_var, batch_count = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta = batch_mean - self.mean
        total = self.count + batch_count
        self.mean += delta * batch_count / total
        self.var.copy_((self.var * self.count + batch_var * batch_count
                        + delta ** 2 * self.count * batch_count / total) / total)
        self.count.copy_(total)


class Agent(nn.Module):
    """Actor and critic: two tanh MLPs of the same shape on normalized observations, evaluated as
    one batched MLP (``torch.baddbmm`` on weights stacked [actor, critic]), which halves the
    small tensor operations that bound PPO's speed on a CPU; a state-independent log std."""

    def __init__(self, obs_size: int, action_size: int, hidden: int, clip_obs: float) -> None:
        super().__init__()
        self.obs_rms = RunningMeanStd((obs_size,))
        self.clip_obs = clip_obs
        sizes = [obs_size, hidden, hidden, action_size]  # the critic reads column 0 of the last layer
        self.weights, self.biases = nn.ParameterList(), nn.ParameterList()
        for k, (fan_in, fan_out) in enumerate(zip(sizes[:-1], sizes[1:])):
            last = k == len(sizes) - 2
            weight = torch.empty(2, fan_in, fan_out)
            for head, gain in enumerate((0.01, 1.0) if last else (np.sqrt(2), np.sqrt(2))):
                weight[head] = nn.init.orthogonal_(torch.empty(fan_out, fan_in), gain).T
            self.weights.append(nn.Parameter(weight))
            self.biases.append(nn.Parameter(torch.zeros(2, 1, fan_out)))
        self.actor_logstd = nn.Parameter(torch.zeros(action_size))

    def normalize(self, obs: torch.Tensor) -> torch.Tensor:
        x = (obs.to(torch.float64) - self.obs_rms.mean) / torch.sqrt(self.obs_rms.var + 1e-8)
        return x.clamp(-self.clip_obs, self.clip_obs).to(torch.float32)

    def layers(self, x: torch.Tensor) -> list[torch.Tensor]:
        """The batched MLP's input (x for both heads), hidden activations and output, shaped
        (2, batch, width): [actor, critic]."""
        h = [x.expand(2, *x.shape)]
        for k, (weight, bias) in enumerate(zip(self.weights, self.biases)):
            z = torch.baddbmm(bias, h[-1], weight)
            h.append(torch.tanh(z) if k < len(self.weights) - 1 else z)
        return h

    def heads(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(action mean, value) of normalized observations x."""
        out = self.layers(x)[-1]
        return out[0], out[1, :, 0]

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.heads(x)[1]

    def act(self, x: torch.Tensor, action: torch.Tensor | None = None):
        """(action, log prob, entropy, value) of normalized observations x: the diagonal Gaussian
        written out (torch.distributions costs more than these few small tensors)."""
        mean, value = self.heads(x)
        log_std = self.actor_logstd.expand_as(mean)
        std = log_std.exp()
        if action is None:
            action = mean + std * torch.randn_like(mean)
        log_prob = (-0.5 * ((action - mean) / std) ** 2 - log_std - LOG_SQRT_2PI).sum(-1)
        entropy = (log_std + 0.5 + LOG_SQRT_2PI).sum(-1)
        return action, log_prob, entropy, value


def share_one_tensor(parameters) -> torch.Tensor:
    """Rebinds the parameters as views of one flat tensor and returns it: the gradient clip and
    each step of Adam are then one tensor operation instead of one per parameter."""
    flat = torch.cat([p.detach().reshape(-1) for p in parameters])
    offset = 0
    for p in parameters:
        p.data = flat[offset:offset + p.numel()].view_as(p)
        offset += p.numel()
    return flat


class Adam:
    """Adam (Kingma and Ba; torch.optim.Adam's arithmetic, tests hold it to it) on a list of
    tensors in foreach form: torch.optim's step spends more on bookkeeping than on these small
    tensors."""

    def __init__(self, params: list[torch.Tensor], lr: float, eps: float = 1e-8, betas=(0.9, 0.999)) -> None:
        self.params, self.lr, self.eps, self.betas = params, lr, eps, betas
        self.exp_avg = [torch.zeros_like(p) for p in params]
        self.exp_avg_sq = [torch.zeros_like(p) for p in params]
        self.steps = 0

    @torch.no_grad()
    def step(self, grads: list[torch.Tensor]) -> None:
        beta1, beta2 = self.betas
        self.steps += 1
        torch._foreach_lerp_(self.exp_avg, grads, 1 - beta1)
        torch._foreach_mul_(self.exp_avg_sq, beta2)
        torch._foreach_addcmul_(self.exp_avg_sq, grads, grads, 1 - beta2)
        denominator = torch._foreach_sqrt(self.exp_avg_sq)
        torch._foreach_div_(denominator, (1 - beta2 ** self.steps) ** 0.5)
        torch._foreach_add_(denominator, self.eps)
        torch._foreach_addcdiv_(self.params, self.exp_avg, denominator, -self.lr / (1 - beta1 ** self.steps))

    def state_dict(self) -> dict:
        return {"exp_avg": self.exp_avg, "exp_avg_sq": self.exp_avg_sq, "steps": self.steps, "lr": self.lr}

    def load_state_dict(self, state: dict) -> None:
        for mine, saved in ((self.exp_avg, state["exp_avg"]), (self.exp_avg_sq, state["exp_avg_sq"])):
            torch._foreach_copy_(mine, saved)
        self.steps, self.lr = state["steps"], state["lr"]


def ppo_loss(agent: Agent, x, actions, old_logprobs, advantages, returns, config: Config):
    """PPO's clipped objective, the value loss and the entropy bonus on one minibatch (the
    definition; training takes its gradient from ppo_gradients)."""
    _, logprob, entropy, value = agent.act(x, actions)
    ratio = (logprob - old_logprobs).exp()
    advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    policy_loss = torch.max(-advantages * ratio,
                            -advantages * ratio.clamp(1 - config.clip_coef, 1 + config.clip_coef)).mean()
    value_loss = 0.5 * ((value - returns) ** 2).mean()
    return policy_loss - config.ent_coef * entropy.mean() + config.vf_coef * value_loss


@torch.no_grad()
def ppo_gradients(agent: Agent, x, actions, old_logprobs, advantages, returns, config: Config,
                  with_stats: bool = False):
    """The gradient of ppo_loss by the chain rule through the loss and the batched MLP (tests
    hold it to autograd's): ({parameter name: gradient}, stats), stats (policy loss, value loss,
    clip fraction) as tensors with_stats, else None."""
    batch = x.shape[0]
    h0, a1, a2, out = agent.layers(x)  # forward, keeping the activations
    _, w2, w3 = agent.weights
    mean, value = out[0], out[1, :, 0]
    log_std = agent.actor_logstd
    std = log_std.exp()
    z = (actions - mean) / std  # the action in standard units
    logprob = (-0.5 * z ** 2 - log_std - LOG_SQRT_2PI).sum(-1)
    ratio = (logprob - old_logprobs).exp()
    advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    unclipped_loss = -advantages * ratio
    clipped_loss = -advantages * ratio.clamp(1 - config.clip_coef, 1 + config.clip_coef)
    value_error = value - returns
    # backward. d loss / d log prob = -A r / B where the unclipped term is the larger; the two are
    # equal only inside the clip range (or where A = 0), where torch.max and clamp pass the whole
    # gradient too
    d_logprob = torch.where(unclipped_loss >= clipped_loss, unclipped_loss / batch, 0.0)
    d_mean = d_logprob[:, None] * z / std
    d_value = config.vf_coef / batch * value_error
    d_out = torch.stack([d_mean, torch.nn.functional.pad(d_value[:, None], (0, d_mean.shape[1] - 1))])
    d_log_std = (d_logprob[:, None] * (z ** 2 - 1.0)).sum(0) - config.ent_coef
    d_w3, d_b3 = torch.bmm(a2.transpose(1, 2), d_out), d_out.sum(1, keepdim=True)
    d_z2 = torch.bmm(d_out, w3.transpose(1, 2)) * (1.0 - a2 ** 2)
    d_w2, d_b2 = torch.bmm(a1.transpose(1, 2), d_z2), d_z2.sum(1, keepdim=True)
    d_z1 = torch.bmm(d_z2, w2.transpose(1, 2)) * (1.0 - a1 ** 2)
    d_w1, d_b1 = torch.bmm(h0.transpose(1, 2), d_z1), d_z1.sum(1, keepdim=True)
    grads = {"weights.0": d_w1, "weights.1": d_w2, "weights.2": d_w3, "biases.0": d_b1, "biases.1": d_b2,
             "biases.2": d_b3, "actor_logstd": d_log_std}
    if not with_stats:
        return grads, None
    policy_loss = torch.max(unclipped_loss, clipped_loss).mean()
    clip_fraction = ((ratio - 1.0).abs() > config.clip_coef).float().mean()
    return grads, (policy_loss, 0.5 * (value_error ** 2).mean(), clip_fraction)


def reward_weights(text: str) -> dict:
    """ "energy=0.05,time=20" -> {"energy": 0.05, "time": 20.0} (the env checks the names)."""
    weights = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, _, value = item.partition("=")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"reward_weights: expected name=number items separated by commas, got {item!r}") from None
    return weights


def residual_mapping(config: Config, task):
    """The residual set-point the agent acts through (agents.residual), or None."""
    if not config.residual_scale:
        return None
    from agents.residual import ResidualSetpoint

    try:
        scale = [float(x) for x in config.residual_scale.split(",")]
    except ValueError:
        raise ValueError(f"residual_scale: expected 3 numbers separated by commas, got {config.residual_scale!r}") \
            from None
    return ResidualSetpoint(task, scale, config.residual_deadzone)


class DemoResets:
    """Reference state initialization (DeepMimic's RSI, Peng et al. 2018): each training episode
    starts, with probability ``config.demo_resets``, from a state the optimal reference
    (agents.optimal) passes through at a uniformly drawn control step, instead of at rest.
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
        from agents.optimal import reference_snapshots

        self.task = envs.unwrapped.task
        self.snapshots = reference_snapshots(config.env_id, params=self.task.params,
                                             wall_margin=config.demo_wall_margin)
        self.probability = config.demo_resets
        self.rng = np.random.default_rng(config.seed)

    def __call__(self, obs: np.ndarray, rows) -> np.ndarray:
        """obs with the robots of ``rows`` (just reset) moved to reference states where drawn."""
        for i in rows:
            if self.rng.random() < self.probability:
                self.task.restore(int(i), self.snapshots[self.rng.integers(len(self.snapshots))])
                obs[i] = self.task.obs[i]
        return obs


class DemoCloning:
    """Demonstration-augmented policy gradient (DAPG, Rajeswaran et al. 2018): the optimal
    reference's steps on the C11 target (agents.optimal.reference_demonstration, the reference
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
        if (mapping is None or config.control_mode != "voltage" or config.randomize_target or config.randomize_params
                or config.device != "cpu"):
            raise ValueError("demo_bc: the demonstration is the C11 target's voltages with the nominal parameters, "
                             "in the residual set-point's outputs; use it with control_mode='voltage' and "
                             "residual_scale, without randomize_target and randomize_params, on the CPU")
        from agents.optimal import reference_demonstration

        task = envs.unwrapped.task
        observations, actions = reference_demonstration(config.env_id, params=task.params,
                                                        wall_margin=config.demo_wall_margin)
        self.obs = torch.as_tensor(observations.astype(np.float32))
        self.actions = torch.as_tensor(mapping.agent_actions(observations, actions), dtype=torch.float32)
        self.config = config

    def weight(self, update: int) -> float:
        return self.config.demo_bc * self.config.demo_bc_decay ** (update - 1)

    def gradients(self, agent: Agent, weight: float) -> dict:
        """{parameter name: gradient} of the cloning term at ``weight`` (autograd: one small batch)."""
        with torch.enable_grad():
            mean = agent.heads(agent.normalize(self.obs))[0]
            loss = weight * ((mean - self.actions) ** 2).sum(-1).mean()
            names, parameters = zip(*agent.named_parameters())
            grads = torch.autograd.grad(loss, parameters, allow_unused=True)
        return {name: torch.zeros_like(p) if g is None else g for name, p, g in zip(names, parameters, grads)}

    def pretrain(self, agent: Agent, steps: int, learning_rate: float) -> float:
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


class TargetReplay:
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
        self.task = envs.unwrapped.task
        self.probability, self.capacity = config.target_replay, capacity
        self.rng = np.random.default_rng(config.seed)
        self.failed: list[np.ndarray] = []
        self.targets = self.task.robot_params["target"].copy()  # each robot's current episode's
        self.replayed: list[np.ndarray | None] = [None] * len(self.targets)

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
                self.task.reset_robot(i, self.rng, {"target": target})
                obs[i] = self.task.obs[i]
                self.replayed[i] = target
            self.targets[i] = self.task.robot_params["target"][i]
        return obs


def make_shield(config: Config):
    """agents.shield's Shield for the robots of this run's environment (model: the nominal
    parameters), or None. In training the agent's own action is stored and the shielded one
    is applied, the shield being part of the environment as the agent sees it."""
    if not config.shield:
        return None
    if config.device != "cpu":
        raise ValueError("shield: the shield's model runs on the CPU; train with device='cpu'")
    from agents.shield import Shield

    return Shield(gym.make(config.env_id, control_mode=config.control_mode), None)


def make_env(config: Config):
    weights = reward_weights(config.reward_weights)
    return gym.make_vec(config.env_id, num_envs=config.num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode="SameStep", control_mode=config.control_mode,
                        randomize_target=config.randomize_target, device=config.device,
                        **({"randomize_params": config.randomize_params} if config.randomize_params else {}),
                        **({"reward_weights": weights} if weights else {}),
                        **({"num_threads": config.env_threads} if config.device == "cpu" else {}))


def tensor(x, device) -> torch.Tensor:
    """A step output as a tensor on the device (the CUDA env's are already)."""
    return x if isinstance(x, torch.Tensor) else torch.from_numpy(np.asarray(x)).to(device)


def train(config: Config, resume: bool = False) -> dict:
    """Train, checkpointing every config.checkpoint_every updates; returns the run's summary."""
    from torch.utils.tensorboard import SummaryWriter

    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    if config.torch_threads:
        torch.set_num_threads(config.torch_threads)
    torch.manual_seed(config.seed)
    device = torch.device(config.device)
    envs = make_env(config)
    # the CUDA env on numba's simulator returns CPU tensors: train where its tensors are
    device = getattr(envs.unwrapped, "device", device)
    obs_size, action_size = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    mapping = residual_mapping(config, envs.unwrapped.task)
    if mapping is not None and device.type != "cpu":
        raise ValueError("residual_scale: the residual set-point maps numpy observations; train on device='cpu'")
    agent = Agent(obs_size, action_size, config.hidden_size, config.clip_obs).to(device)
    names, parameters = zip(*agent.named_parameters())
    flat = share_one_tensor(parameters)
    optimizer = Adam([flat], lr=config.learning_rate, eps=1e-5)
    return_rms = RunningMeanStd().to(device)
    num_updates = max(1, config.total_timesteps // config.batch_size)
    start_update, global_step, train_seconds = 1, 0, 0.0
    checkpoint = out / "checkpoint.pt"
    if resume and checkpoint.exists():
        state = torch.load(checkpoint, map_location=device, weights_only=False)
        agent.load_state_dict(state["agent"])
        optimizer.load_state_dict(state["optimizer"])
        return_rms.load_state_dict(state["return_rms"])
        start_update, global_step, train_seconds = state["update"] + 1, state["global_step"], state["train_seconds"]
    elif config.init_from:
        load_weights(agent, Path(config.init_from))
    cloning = DemoCloning(envs, config, mapping) if (config.demo_bc or config.demo_bc_pretrain) else None
    if start_update == 1 and not config.init_from:
        with torch.no_grad():
            agent.actor_logstd.fill_(config.init_log_std)
        if cloning is not None and config.demo_bc_pretrain:
            print(f"behaviour cloning: loss {cloning.pretrain(agent, config.demo_bc_pretrain, 1e-3):.2e} after "
                  f"{config.demo_bc_pretrain} steps", flush=True)
    (out / "config.json").write_text(json.dumps(dataclasses.asdict(config), indent=2))
    writer = SummaryWriter(str(out / "tb"))

    def minibatch_update(obs, actions, old_logprobs, advantages, returns, with_stats=False):
        """One Adam step on PPO's loss over a minibatch, with the gradient written out
        (ppo_gradients): on a CPU these tiny networks are bound by the count of tensor
        operations, and autograd's graph and the bookkeeping of clip_grad_norm_ and torch.optim
        cost more than the arithmetic."""
        by_name, stats = ppo_gradients_(agent, obs, actions, old_logprobs, advantages, returns, config, with_stats)
        if cloning_weight:
            cloned = cloning.gradients(agent, cloning_weight)
            by_name = {name: by_name[name] + cloned[name] for name in names}
        grad = torch.cat([by_name[name].reshape(-1) for name in names])  # laid out as flat
        grad *= (config.max_grad_norm / (grad.norm() + 1e-6)).clamp(max=1.0)  # clip_grad_norm_'s rule
        optimizer.step([grad])
        return stats

    if config.compile:  # fuses the small tensor operations further (LeanRL's recipe); ~30 s once
        ppo_gradients_ = torch.compile(ppo_gradients)
    else:
        ppo_gradients_ = ppo_gradients

    n, steps = config.num_envs, config.num_steps
    obs_buf = torch.zeros((steps, n, obs_size), device=device)
    actions_buf = torch.zeros((steps, n, action_size), device=device)
    logprobs, rewards, dones, values = (torch.zeros((steps, n), device=device) for _ in range(4))
    discounted = torch.zeros(n, dtype=torch.float64, device=device)  # the return the reward scale tracks
    episode_return = torch.zeros(n, dtype=torch.float64, device=device)
    finished = {"return": [], "success": [], "collision": []}

    obs, _ = envs.reset(seed=config.seed + 1000 * (start_update - 1))  # resumed runs start new episodes
    demo_resets = DemoResets(envs, config) if config.demo_resets else None
    if demo_resets is not None:
        obs = demo_resets(obs, range(n))
    target_replay = TargetReplay(envs, config) if config.target_replay else None
    shield = make_shield(config)
    interventions = 0
    obs = tensor(obs, device)
    done = torch.zeros(n, device=device)
    started = time.perf_counter()
    for update in range(start_update, num_updates + 1):
        if config.anneal_lr:
            optimizer.lr = config.learning_rate * (1.0 - (update - 1.0) / num_updates)
        cloning_weight = cloning.weight(update) if cloning is not None else 0.0
        # -- rollout ---------------------------------------------------------------------
        for step in range(steps):
            global_step += n
            with torch.no_grad():
                agent.obs_rms.update(obs)
                x = agent.normalize(obs)
                action, logprob, _, value = agent.act(x)
            obs_buf[step], actions_buf[step], logprobs[step], values[step], dones[step] = x, action, logprob, value, done
            clipped = action.clamp(-1.0, 1.0)
            env_action = clipped if config.device == "cuda" else clipped.numpy()
            if mapping is not None:  # the agent's r becomes a set-point around the target
                env_action = mapping(obs.numpy(), env_action)
            if shield is not None:
                env_action = np.array(env_action, dtype=np.float64)
                for i in range(n):
                    env_action[i], replaced = shield.filter(envs.unwrapped.task, i, env_action[i])
                    interventions += replaced
            next_obs, reward, terminated, truncated, info = envs.step(env_action)
            reward = tensor(reward, device)
            terminated, truncated = tensor(terminated, device), tensor(truncated, device)
            episode_return += reward
            if config.normalize_reward:
                discounted = discounted * config.gamma + reward  # zeroed where an episode ends
                return_rms.update(discounted)
                reward = reward / torch.sqrt(return_rms.var + 1e-8)
            reward = reward.to(torch.float32)
            if bool(truncated.any()):  # bootstrap a time limit with the value of the final observation
                final = tensor(info["final_obs"], device)
                with torch.no_grad():
                    final_value = agent.value(agent.normalize(final))
                reward = torch.where(truncated & ~terminated, reward + config.gamma * final_value, reward)
            rewards[step] = reward
            ended = terminated | truncated
            if bool(ended.any()):
                rows = ended.nonzero().squeeze(-1)
                finished["return"] += episode_return[rows].tolist()
                finished["success"] += tensor(info["is_success"], device)[rows].tolist()
                finished["collision"] += (tensor(info["collisions"], device)[rows] > 0).tolist()
                episode_return[rows] = 0.0
                discounted[rows] = 0.0
                if demo_resets is not None:
                    next_obs = demo_resets(next_obs, rows.tolist())
                if target_replay is not None:
                    next_obs = target_replay(next_obs, rows.tolist(), info["is_success"], info["collisions"] > 0)
            obs, done = tensor(next_obs, device), ended.to(torch.float32)

        # -- advantages (GAE) ------------------------------------------------------------
        with torch.no_grad():
            next_value = agent.value(agent.normalize(obs))
            advantages = torch.zeros_like(rewards)
            last = torch.zeros(n, device=device)
            for t in reversed(range(steps)):
                next_nonterminal = 1.0 - (done if t == steps - 1 else dones[t + 1])
                following = next_value if t == steps - 1 else values[t + 1]
                delta = rewards[t] + config.gamma * following * next_nonterminal - values[t]
                last = delta + config.gamma * config.gae_lambda * next_nonterminal * last
                advantages[t] = last
            returns = advantages + values

        # -- update ----------------------------------------------------------------------
        b_obs, b_actions = obs_buf.reshape(-1, obs_size), actions_buf.reshape(-1, action_size)
        b_logprobs, b_advantages = logprobs.reshape(-1), advantages.reshape(-1)
        b_returns = returns.reshape(-1)
        clip_fractions = []  # the losses and clip fractions logged are the last epoch's
        for epoch in range(config.update_epochs):
            order = torch.randperm(config.batch_size, device=device)
            last_epoch = epoch == config.update_epochs - 1
            for begin in range(0, config.batch_size, config.minibatch_size):
                mb = order[begin:begin + config.minibatch_size]
                stats = minibatch_update(b_obs[mb], b_actions[mb], b_logprobs[mb], b_advantages[mb], b_returns[mb],
                                         with_stats=last_epoch)
                if last_epoch:
                    policy_loss, value_loss, clip_fraction = stats
                    clip_fractions.append(clip_fraction)

        # -- logs and checkpoints ------------------------------------------------------------
        elapsed = train_seconds + time.perf_counter() - started
        writer.add_scalar("charts/steps_per_second", (global_step - (start_update - 1) * config.batch_size)
                          / max(time.perf_counter() - started, 1e-9), global_step)
        writer.add_scalar("losses/policy", policy_loss.item(), global_step)
        writer.add_scalar("losses/value", value_loss.item(), global_step)
        writer.add_scalar("losses/clip_fraction", torch.stack(clip_fractions).mean().item(), global_step)
        if shield is not None:
            writer.add_scalar("charts/shield_interventions", interventions / (steps * n), global_step)
            interventions = 0
        if finished["return"]:
            writer.add_scalar("charts/episode_return", float(np.mean(finished["return"])), global_step)
            writer.add_scalar("charts/success_rate", float(np.mean(finished["success"])), global_step)
            writer.add_scalar("charts/collision_rate", float(np.mean(finished["collision"])), global_step)
        if update % config.checkpoint_every == 0 or update == num_updates:
            save(agent, out)
            torch.save({"agent": agent.state_dict(), "optimizer": optimizer.state_dict(),
                        "return_rms": return_rms.state_dict(), "update": update, "global_step": global_step,
                        "train_seconds": elapsed}, checkpoint)
            recent = {k: v[-100:] for k, v in finished.items()}
            print(f"update {update}/{num_updates}  steps {global_step}  "
                  f"success {np.mean(recent['success']) if recent['success'] else float('nan'):.2f}  "
                  f"{global_step / max(elapsed, 1e-9):.0f} steps/s", flush=True)
    writer.close()
    envs.close()
    elapsed = train_seconds + time.perf_counter() - started
    summary = {"global_step": global_step, "train_seconds": elapsed,
               "steps_per_second": (global_step - (start_update - 1) * config.batch_size)
               / max(time.perf_counter() - started, 1e-9)}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    # the run's record, as agents.training writes it: what the comparison reads
    (out / "config.json").write_text(json.dumps({**dataclasses.asdict(config), "algo": "torch-ppo", **summary},
                                                indent=2))
    return summary


def save(agent: Agent, out: Path) -> None:
    """model.pt: what TorchPPOPolicy needs (weights with the normalizer, sizes)."""
    torch.save({"state_dict": {k: v.cpu() for k, v in agent.state_dict().items()},
                "obs_size": agent.obs_rms.mean.shape[0], "action_size": agent.actor_logstd.shape[0],
                "hidden_size": agent.weights[0].shape[-1], "clip_obs": agent.clip_obs}, out / "model.pt")


def load_weights(agent: Agent, run_dir: Path) -> None:
    """Start ``agent`` from a finished run's policy, value function and observation normalizer
    (Config.init_from); the optimizer and the reward scale start afresh."""
    if not (run_dir / "model.pt").exists():
        raise FileNotFoundError(f"init_from: no model.pt in {str(run_dir)!r}; give a folder written by agents.torch_ppo")
    saved = torch.load(run_dir / "model.pt", map_location="cpu", weights_only=False)
    mine = (agent.obs_rms.mean.shape[0], agent.actor_logstd.shape[0], agent.weights[0].shape[-1])
    theirs = (saved["obs_size"], saved["action_size"], saved["hidden_size"])
    if mine != theirs:
        raise ValueError(f"init_from: {str(run_dir)!r} has (observation, action, hidden) sizes {theirs}, "
                         f"this run {mine}")
    agent.load_state_dict(saved["state_dict"])  # copies in place: the parameters stay views of one tensor


class TorchPPOPolicy:
    """A run of this file as an obs -> action policy (the mean action) for agents.evaluate."""

    def __init__(self, env, run_dir: str | Path) -> None:
        run_dir = Path(run_dir)
        if not (run_dir / "model.pt").exists():
            raise FileNotFoundError(f"no model.pt in {str(run_dir)!r}: give a folder written by agents.torch_ppo")
        config = json.loads((run_dir / "config.json").read_text())
        unwrapped = env.unwrapped if hasattr(env, "unwrapped") else env
        if config["control_mode"] != unwrapped.control_mode:
            raise ValueError(f"{run_dir} was trained in {config['control_mode']!r} mode, "
                             f"the environment is in {unwrapped.control_mode!r} mode")
        saved = torch.load(run_dir / "model.pt", map_location="cpu", weights_only=False)
        self.agent = Agent(saved["obs_size"], saved["action_size"], saved["hidden_size"], saved["clip_obs"])
        self.agent.load_state_dict(saved["state_dict"])
        self.agent.eval()
        known = {f.name for f in dataclasses.fields(Config)}
        run_config = Config(**{k: v for k, v in config.items() if k in known})
        self.mapping = residual_mapping(run_config, unwrapped.task)
        # a run trained behind the shield acts behind it (its model: the nominal parameters)
        self.shield = None
        if run_config.shield:
            from agents.shield import Shield
            self.shield = Shield(env, None)
        self.name = f"torch-ppo ({run_dir.name})"

    def reset(self) -> None:
        pass

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = self.agent.normalize(torch.as_tensor(np.asarray(obs))[None])
            action = self.agent.heads(x)[0][0].clamp(-1.0, 1.0).numpy().astype(np.float64)
        action = action if self.mapping is None else self.mapping(obs, action)[0]
        return action if self.shield is None else self.shield.filter(self.shield.env.task, 0, action)[0]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for field in dataclasses.fields(Config):
        flag = "--" + field.name.replace("_", "-")
        if field.type in ("bool", bool):
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=field.default)
        else:
            kind = {"int": int, "float": float, "str": str}[str(field.type)]
            parser.add_argument(flag, type=kind, default=field.default)
    parser.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.pt")
    args = vars(parser.parse_args(argv))
    resume = args.pop("resume")
    print(json.dumps(train(Config(**args), resume=resume), indent=2))


if __name__ == "__main__":
    main()
