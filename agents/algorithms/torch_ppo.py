"""PPO in one file, CleanRL style: torch only, no stable-baselines3 in its loop.

It trains on the native vector env, on the CPU (numpy arrays in, torch tensors made once per
step) or on its CUDA backend (``device="cuda"``: the env, the rollout buffer, the network and
the updates all stay on the GPU). Read top to bottom: the config, the running normalizers,
the agent, Adam, the loss and its gradient written out (small networks on a CPU are bound by
the count of tensor operations: autograd's graph and torch.optim's bookkeeping cost more
than the arithmetic, and tests hold both to torch's), the rollout and the update. The research
add-ons (reference resets, demonstrations, target replay, the shield) are hooks beside it
(`agents.algorithms.torch_ppo_hooks`).

    scara-agents torch-ppo --total-timesteps 2000000 --out runs/torch_ppo
    scara-agents torch-ppo --device cuda --num-envs 4096 --num-steps 32 --out runs/torch_ppo_gpu
    scara-agents evaluate --policies torchppo:runs/torch_ppo

A run folder holds ``config.json``, ``model.pt`` (the policy and its observation normalizer,
what ``TorchPPOPolicy`` loads), ``checkpoint.pt`` (everything to resume: ``--resume``) and
TensorBoard logs under ``tb/``.
"""

from __future__ import annotations

import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from scara_gym.extras import require

require("torch")
import torch
from torch import nn

from agents.algorithms.progress import Progress
from agents.algorithms.torch_ppo_config import Config
from agents.algorithms.torch_ppo_hooks import Hook, hooks_for
from agents.files import (
    POLICY_FILES,
    WEIGHTS_FILES,
    claim_run_folder,
    exclusive,
    load_torch,
    save_torch,
    verify_digests,
    write_digests,
    write_json,
)
from scara_gym.benchmark.protocol import SENSOR_NOISE
from scara_gym.envs.cuda_vector import load_backend
from scara_gym.model.checks import UserError
from scara_gym.wrappers import Shield, residual_setpoint

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


def make_env(config: Config):
    weights = config.reward_weights
    return gym.make_vec(config.env_id, num_envs=config.num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode="SameStep", control_mode=config.control_mode,
                        randomize_target=config.randomize_target, device=config.device,
                        **({"randomize_params": config.randomize_params} if config.randomize_params else {}),
                        **({"randomize_start": True} if config.randomize_start else {}),
                        **({"sensor_noise": {k: config.sensor_noise * v for k, v in SENSOR_NOISE.items()}}
                           if config.sensor_noise else {}),
                        **({"reward_weights": weights} if weights else {}),
                        **({"num_threads": config.env_threads} if config.device == "cpu" else {}))


def tensor(x, device) -> torch.Tensor:
    """A step output as a tensor on the device (the CUDA env's are already)."""
    return x if isinstance(x, torch.Tensor) else torch.from_numpy(np.asarray(x)).to(device)


RESUMABLE = ("out", "total_timesteps", "checkpoint_every", "device", "torch_threads", "env_threads", "compile")
"""Config fields a resumed run may change (its budget, where and how fast it runs); the others
are the run's settings, which a run folder keeps (agents.files.claim_run_folder)"""


def run_record(config: Config) -> dict:
    """What a run of ``config`` is, for agents.files.claim_run_folder."""
    settings = {k: v for k, v in config.to_dict().items() if k not in RESUMABLE}
    return {"trainer": "torch-ppo", "algo": "torch-ppo", "env_id": config.env_id, "control_mode": config.control_mode,
            "seed": config.seed, "settings": settings}


def train(config: Config, resume: bool = False, hooks: list[Hook] | None = None, overwrite: bool = False) -> dict:
    """Train, checkpointing every config.checkpoint_every updates; returns the run's summary.
    resume: continue the run in the folder from its checkpoint where it has one (else start
    afresh); overwrite: train a run the folder holds again from scratch; with neither, a folder
    that holds a run is refused, and so is one that holds another run or one of a newer version
    (agents.files.claim_run_folder). The folder is locked for the whole run (agents.files.exclusive).
    hooks: the research add-ons the loop calls (default: those config's add-on fields ask for,
    agents.algorithms.torch_ppo_hooks.hooks_for)."""
    out = Path(config.out)
    if config.device == "cuda":  # a machine without the GPU is told so before the run folder is made
        try:
            load_backend()
        except (ImportError, RuntimeError) as error:
            raise UserError(str(error)) from None
    with exclusive(out):
        claim_run_folder(out, run_record(config), resume, overwrite)
        return _train(config, resume, hooks)


def _train(config: Config, resume: bool, hooks: list[Hook] | None) -> dict:
    """The loop: per update, a rollout, its advantages, the epochs of minibatch steps, then the
    logs and a checkpoint (each its own function below, read in that order)."""
    require("torch")
    from torch.utils.tensorboard import SummaryWriter

    out = Path(config.out)
    if config.torch_threads:
        torch.set_num_threads(config.torch_threads)
    torch.manual_seed(config.seed)
    envs = make_env(config)
    # the CUDA env on numba's simulator returns CPU tensors: train where its tensors are
    device = getattr(envs.unwrapped, "device", torch.device(config.device))
    mapping = residual_setpoint(envs.unwrapped, config.residual_scale, config.residual_deadzone, config.residual_on)
    if mapping is not None and device.type != "cpu":
        raise UserError("residual_scale: the residual set-point maps numpy observations; train on device='cpu'")
    hooks = hooks_for(config, envs, mapping) if hooks is None else list(hooks)
    learner = _start(config, envs, device, hooks, resume)
    write_json(out / "config.json", config.to_dict())
    writer = SummaryWriter(str(out / "tb"))
    num_updates = max(1, config.total_timesteps // config.batch_size)
    rollout = Rollout(config, envs, device, learner.start_update)
    for hook in hooks:
        rollout.obs = hook.on_start(rollout.obs)
    rollout.obs = tensor(rollout.obs, device)
    started = time.perf_counter()
    progress = Progress(num_updates * config.batch_size, start_step=learner.global_step)
    for update in range(learner.start_update, num_updates + 1):
        if config.anneal_lr:
            learner.optimizer.lr = config.learning_rate * (1.0 - (update - 1.0) / num_updates)
        collect(rollout, learner, envs, mapping, hooks, config)
        for hook in hooks:
            hook.on_rollout_end()
        advantages, returns = gae(learner.agent, rollout, config)
        losses = ppo_update(learner, rollout, advantages, returns, hooks, update, config)
        elapsed = learner.train_seconds + time.perf_counter() - started
        _log(writer, learner, rollout, losses, hooks, config, started)
        if update % config.checkpoint_every == 0 or update == num_updates:
            save(learner.agent, out)
            save_torch({"agent": learner.agent.state_dict(), "optimizer": learner.optimizer.state_dict(),
                        "return_rms": learner.return_rms.state_dict(), "update": update,
                        "global_step": learner.global_step, "train_seconds": elapsed,
                        "hooks": [hook.state_dict() for hook in hooks]}, out / "checkpoint.pt")
        # the last 100 episodes' return and success, at most every 10 s and at the end
        progress.report(learner.global_step, rollout.finished["return"][-100:], rollout.finished["success"][-100:],
                        final=update == num_updates)
    writer.close()
    envs.close()
    return _finish(config, learner, started)


class Learner:
    """What training changes and a checkpoint keeps: the agent, Adam on its one flat parameter
    tensor, the return's running scale, and the count of updates, steps and seconds so far."""

    def __init__(self, config: Config, obs_size: int, action_size: int, device) -> None:
        self.agent = Agent(obs_size, action_size, config.hidden_size, config.clip_obs).to(device)
        self.names, parameters = zip(*self.agent.named_parameters())
        self.optimizer = Adam([share_one_tensor(parameters)], lr=config.learning_rate, eps=1e-5)
        self.return_rms = RunningMeanStd().to(device)
        self.start_update, self.global_step, self.train_seconds = 1, 0, 0.0
        # the minibatch gradient, compiled on request (fuses the small tensor operations further,
        # LeanRL's recipe; ~30 s once)
        self.gradients = torch.compile(ppo_gradients) if config.compile else ppo_gradients


def _start(config: Config, envs, device, hooks: list[Hook], resume: bool) -> Learner:
    """A new learner, from the run's checkpoint (resume), a finished run's weights (init_from)
    or its initialization and the hooks' ``before_training``."""
    obs_size, action_size = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    learner = Learner(config, obs_size, action_size, device)
    checkpoint = Path(config.out) / "checkpoint.pt"
    if resume and checkpoint.exists():
        state = load_torch(checkpoint, map_location=device)
        learner.agent.load_state_dict(state["agent"])
        learner.optimizer.load_state_dict(state["optimizer"])
        learner.return_rms.load_state_dict(state["return_rms"])
        learner.start_update = state["update"] + 1
        learner.global_step, learner.train_seconds = state["global_step"], state["train_seconds"]
        for hook, kept in zip(hooks, state.get("hooks", [])):  # checkpoints before hooks kept state: none
            hook.load_state_dict(kept)
    elif config.init_from:
        load_weights(learner.agent, Path(config.init_from))
    if learner.start_update == 1 and not config.init_from:
        with torch.no_grad():
            learner.agent.actor_logstd.fill_(config.init_log_std)
        for hook in hooks:
            hook.before_training(learner.agent)
    return learner


class Rollout:
    """The rollout's buffers (num_steps x num_envs) and what carries over from one rollout to
    the next: the last observation and done flags, the running returns and the finished
    episodes' outcomes."""

    def __init__(self, config: Config, envs, device, start_update: int) -> None:
        n, steps = config.num_envs, config.num_steps
        obs_size, action_size = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
        self.device = device
        self.obs_buf = torch.zeros((steps, n, obs_size), device=device)
        self.actions = torch.zeros((steps, n, action_size), device=device)
        self.logprobs, self.rewards, self.dones, self.values = (torch.zeros((steps, n), device=device)
                                                                for _ in range(4))
        self.discounted = torch.zeros(n, dtype=torch.float64, device=device)  # the return the reward scale tracks
        self.episode_return = torch.zeros(n, dtype=torch.float64, device=device)
        self.finished = {"return": [], "success": [], "collision": []}
        self.obs, _ = envs.reset(seed=config.seed + 1000 * (start_update - 1))  # resumed runs start new episodes
        self.done = torch.zeros(n, device=device)


def collect(rollout: Rollout, learner: Learner, envs, mapping, hooks: list[Hook], config: Config) -> None:
    """One rollout: num_steps steps of every env with the agent's sampled actions (clipped,
    mapped through the residual set-point, filtered by the hooks), into ``rollout``'s buffers."""
    agent, device = learner.agent, rollout.device
    for step in range(config.num_steps):
        learner.global_step += config.num_envs
        with torch.no_grad():
            agent.obs_rms.update(rollout.obs)
            x = agent.normalize(rollout.obs)
            action, logprob, _, value = agent.act(x)
        rollout.obs_buf[step], rollout.actions[step], rollout.logprobs[step] = x, action, logprob
        rollout.values[step], rollout.dones[step] = value, rollout.done
        clipped = action.clamp(-1.0, 1.0)
        env_action = clipped if config.device == "cuda" else clipped.numpy()
        if mapping is not None:  # the agent's r becomes a set-point around the target
            env_action = mapping(rollout.obs.numpy(), env_action)
        for hook in hooks:
            env_action = hook.filter_actions(envs.unwrapped, env_action)
        next_obs, reward, terminated, truncated, info = envs.step(env_action)
        for hook in hooks:
            hook.on_step(env_action, next_obs, reward, terminated, truncated, info)
        reward = tensor(reward, device)
        terminated, truncated = tensor(terminated, device), tensor(truncated, device)
        rollout.rewards[step] = _scaled_reward(rollout, learner, reward, terminated, truncated, info, hooks, config)
        ended = terminated | truncated
        if bool(ended.any()):
            next_obs = _episodes_end(rollout, ended, next_obs, info, hooks)
        rollout.obs, rollout.done = tensor(next_obs, device), ended.to(torch.float32)


def _scaled_reward(rollout: Rollout, learner: Learner, reward, terminated, truncated, info, hooks: list[Hook],
                   config: Config):
    """A step's reward as PPO learns it: summed into the episodes' returns, scaled by the running
    std of the discounted return (normalize_reward), and a time limit bootstrapped with the value
    of the final observation."""
    rollout.episode_return += reward
    for hook in hooks:  # the objective's changes (a cost's penalty); the logged return is the env's
        reward = hook.shape_reward(reward, info)
    if config.normalize_reward:
        rollout.discounted = rollout.discounted * config.gamma + reward  # zeroed where an episode ends
        learner.return_rms.update(rollout.discounted)
        reward = reward / torch.sqrt(learner.return_rms.var + 1e-8)
    reward = reward.to(torch.float32)
    if bool(truncated.any()):
        final = tensor(info["final_obs"], rollout.device)
        with torch.no_grad():
            final_value = learner.agent.value(learner.agent.normalize(final))
        reward = torch.where(truncated & ~terminated, reward + config.gamma * final_value, reward)
    return reward


def _episodes_end(rollout: Rollout, ended, next_obs, info, hooks: list[Hook]):
    """The ended episodes' outcomes kept and their running returns zeroed; the hooks may change
    the next episodes' first observations (returned)."""
    rows = ended.nonzero().squeeze(-1)
    rollout.finished["return"] += rollout.episode_return[rows].tolist()
    rollout.finished["success"] += tensor(info["is_success"], rollout.device)[rows].tolist()
    rollout.finished["collision"] += (tensor(info["collisions"], rollout.device)[rows] > 0).tolist()
    rollout.episode_return[rows] = 0.0
    rollout.discounted[rows] = 0.0
    for hook in hooks:
        next_obs = hook.on_episodes_end(next_obs, rows.tolist(), info)
    return next_obs


@torch.no_grad()
def gae(agent: Agent, rollout: Rollout, config: Config) -> tuple[torch.Tensor, torch.Tensor]:
    """(advantages, returns) of a rollout: generalized advantage estimation, bootstrapped with the
    value of the observation after its last step."""
    steps, values, dones = config.num_steps, rollout.values, rollout.dones
    next_value = agent.value(agent.normalize(rollout.obs))
    advantages = torch.zeros_like(rollout.rewards)
    last = torch.zeros(config.num_envs, device=rollout.device)
    for t in reversed(range(steps)):
        next_nonterminal = 1.0 - (rollout.done if t == steps - 1 else dones[t + 1])
        following = next_value if t == steps - 1 else values[t + 1]
        delta = rollout.rewards[t] + config.gamma * following * next_nonterminal - values[t]
        last = delta + config.gamma * config.gae_lambda * next_nonterminal * last
        advantages[t] = last
    return advantages, advantages + values


def ppo_update(learner: Learner, rollout: Rollout, advantages, returns, hooks: list[Hook], update: int,
               config: Config) -> tuple:
    """update_epochs passes over the rollout in shuffled minibatches, one Adam step each; returns
    the last epoch's (policy loss, value loss, clip fractions), what the logs show."""
    obs_size, action_size = rollout.obs_buf.shape[-1], rollout.actions.shape[-1]
    b_obs, b_actions = rollout.obs_buf.reshape(-1, obs_size), rollout.actions.reshape(-1, action_size)
    b_logprobs, b_advantages = rollout.logprobs.reshape(-1), advantages.reshape(-1)
    b_returns = returns.reshape(-1)
    clip_fractions = []  # the losses and clip fractions logged are the last epoch's
    for epoch in range(config.update_epochs):
        order = torch.randperm(config.batch_size, device=rollout.device)
        last_epoch = epoch == config.update_epochs - 1
        for begin in range(0, config.batch_size, config.minibatch_size):
            mb = order[begin:begin + config.minibatch_size]
            stats = minibatch_step(learner, (b_obs[mb], b_actions[mb], b_logprobs[mb], b_advantages[mb],
                                             b_returns[mb]), hooks, update, config, with_stats=last_epoch)
            if last_epoch:
                policy_loss, value_loss, clip_fraction = stats
                clip_fractions.append(clip_fraction)
    return policy_loss, value_loss, clip_fractions


def minibatch_step(learner: Learner, minibatch: tuple, hooks: list[Hook], update: int, config: Config,
                   with_stats: bool = False):
    """One Adam step on PPO's loss over a minibatch (obs, actions, old log probs, advantages,
    returns), with the gradient written out (ppo_gradients): on a CPU these tiny networks are
    bound by the count of tensor operations, and autograd's graph and the bookkeeping of
    clip_grad_norm_ and torch.optim cost more than the arithmetic. Returns the minibatch's stats
    (with_stats) or None."""
    agent, names = learner.agent, learner.names
    by_name, stats = learner.gradients(agent, *minibatch, config, with_stats)
    for hook in hooks:
        extra = hook.loss_gradients(agent, update)
        if extra is not None:
            by_name = {name: by_name[name] + extra[name] for name in names}
    grad = torch.cat([by_name[name].reshape(-1) for name in names])  # laid out as the flat parameters
    grad *= (config.max_grad_norm / (grad.norm() + 1e-6)).clamp(max=1.0)  # clip_grad_norm_'s rule
    learner.optimizer.step([grad])
    return stats


def _log(writer, learner: Learner, rollout: Rollout, losses: tuple, hooks: list[Hook], config: Config,
         started: float) -> None:
    """An update's scalars on TensorBoard: speed, losses, the hooks' and the finished episodes'."""
    global_step = learner.global_step
    policy_loss, value_loss, clip_fractions = losses
    writer.add_scalar("charts/steps_per_second", (global_step - (learner.start_update - 1) * config.batch_size)
                      / max(time.perf_counter() - started, 1e-9), global_step)
    writer.add_scalar("losses/policy", policy_loss.item(), global_step)
    writer.add_scalar("losses/value", value_loss.item(), global_step)
    writer.add_scalar("losses/clip_fraction", torch.stack(clip_fractions).mean().item(), global_step)
    for hook in hooks:
        hook.log(writer, global_step, config.num_steps * config.num_envs)
    finished = rollout.finished
    if finished["return"]:
        writer.add_scalar("charts/episode_return", float(np.mean(finished["return"])), global_step)
        writer.add_scalar("charts/success_rate", float(np.mean(finished["success"])), global_step)
        writer.add_scalar("charts/collision_rate", float(np.mean(finished["collision"])), global_step)


def _finish(config: Config, learner: Learner, started: float) -> dict:
    """The run's summary, written with its record (config.json, as the SB3 trainer writes it: what
    the comparison reads) and the digests of its policy files."""
    out = Path(config.out)
    elapsed = learner.train_seconds + time.perf_counter() - started
    summary = {"global_step": learner.global_step, "train_seconds": elapsed,
               "steps_per_second": (learner.global_step - (learner.start_update - 1) * config.batch_size)
               / max(time.perf_counter() - started, 1e-9)}
    write_json(out / "summary.json", summary)
    write_json(out / "config.json", {**config.to_dict(), "algo": "torch-ppo", **summary})
    write_digests(out, POLICY_FILES)
    return summary


def save(agent: Agent, out: Path) -> None:
    """model.pt: what TorchPPOPolicy needs (weights with the normalizer, sizes)."""
    save_torch({"state_dict": {k: v.cpu() for k, v in agent.state_dict().items()},
                "obs_size": agent.obs_rms.mean.shape[0], "action_size": agent.actor_logstd.shape[0],
                "hidden_size": agent.weights[0].shape[-1], "clip_obs": agent.clip_obs}, out / "model.pt")


def load_weights(agent: Agent, run_dir: Path) -> None:
    """Start ``agent`` from a finished run's policy, value function and observation normalizer
    (Config.init_from); the optimizer and the reward scale start afresh."""
    if not (run_dir / "model.pt").exists():
        raise FileNotFoundError(f"init_from: no model.pt in {str(run_dir)!r}; give a folder written by scara-agents torch-ppo")
    checked = verify_digests(run_dir, WEIGHTS_FILES)  # read once: what loads is what was checked
    saved = load_torch(run_dir / "model.pt", data=checked.bytes("model.pt"))
    mine = (agent.obs_rms.mean.shape[0], agent.actor_logstd.shape[0], agent.weights[0].shape[-1])
    theirs = (saved["obs_size"], saved["action_size"], saved["hidden_size"])
    if mine != theirs:
        raise UserError(f"init_from: {str(run_dir)!r} has (observation, action, hidden) sizes {theirs}, "
                        f"this run {mine}")
    agent.load_state_dict(saved["state_dict"])  # copies in place: the parameters stay views of one tensor


class TorchPPOPolicy:
    """A run of this file as an obs -> action policy (the mean action)."""

    def __init__(self, env, run_dir: str | Path) -> None:
        run_dir = Path(run_dir)
        if not (run_dir / "model.pt").exists():
            raise FileNotFoundError(f"no model.pt in {str(run_dir)!r}: give a folder written by scara-agents torch-ppo")
        checked = verify_digests(run_dir, WEIGHTS_FILES)  # read once: what loads is what was checked
        run_config = Config.from_dict(checked.json("config.json"))
        unwrapped = env.unwrapped
        if run_config.control_mode != unwrapped.control_mode:
            raise UserError(f"{run_dir} was trained in {run_config.control_mode!r} mode, "
                            f"the environment is in {unwrapped.control_mode!r} mode")
        saved = load_torch(run_dir / "model.pt", data=checked.bytes("model.pt"))
        self.agent = Agent(saved["obs_size"], saved["action_size"], saved["hidden_size"], saved["clip_obs"])
        self.agent.load_state_dict(saved["state_dict"])
        self.agent.eval()
        self.mapping = residual_setpoint(unwrapped, run_config.residual_scale, run_config.residual_deadzone,
                                         run_config.residual_on)
        # a run trained behind the shield acts behind it (its model: the nominal parameters)
        self.shield = Shield(env, None) if run_config.shield else None
        self.name = f"torch-ppo ({run_dir.name})"

    def reset(self) -> None:
        pass

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = self.agent.normalize(torch.as_tensor(np.asarray(obs))[None])
            action = self.agent.heads(x)[0][0].clamp(-1.0, 1.0).numpy().astype(np.float64)
        action = action if self.mapping is None else self.mapping(obs, action)[0]
        return action if self.shield is None else self.shield.filter(self.shield.env, 0, action)[0]
