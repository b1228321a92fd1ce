"""Offline datasets in Minari's format: D4RL-style tiers for the C11 task and for randomized targets.

`DATASETS` names every dataset (``scara/<task>/<tier>-vN``: N the version, `DATASET_VERSIONS`: -v0
on ``Scara-C11-v1``, frozen with it, and -v1 on ``Scara-C11-v2``, the protocol's id); `build` writes one
through Minari's own API (``minari.create_dataset_from_buffers``) into Minari's local data
folder (``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``) or ``out``. Nothing needs the
network.

| task | environment (the version's id, "pd" mode) |
|---|---|
| ``c11`` | the C11 target, starts drawn from the protocol's start region (``randomize_start=True``) |
| ``random-targets`` | targets drawn per episode beyond the wall (``randomize_target=True``) |

| tier | episodes of |
|---|---|
| ``expert`` | the best safe policy among `EXPERT_CANDIDATES`, picked on the tuning set (`pick_expert`) |
| ``medium`` | a learned agent part-way through training: the single-file PPO after `MEDIUM_STEPS` steps |
| ``random`` | uniformly random actions in [-1, 1] |
| ``medium-replay`` | every episode that training run collected, in training order (its rollouts, stochastic actions) |
| ``mixed`` | the expert and random actions, alternating episode by episode |
| ``oracle`` | the real-time MPC (``mpc-rti``, agents.policies.mpc_rti): -v1 and later only, `ORACLE_DATASETS` |

The oracle tier is the many-episode expert data of the distillation (docs/agents.md): the
real-time MPC on the protocol's three training distributions, its tasks ``c11``,
``random-targets`` and ``random-shifts`` (physics and wall drawn per episode from the protocol's
"all" ranges; the MPC plans on the nominal model and reads the wall from the observation), and
per step the time to go (``info["time_to_go"]``: the episode's success time minus the step's
time, NaN in an episode that does not succeed). A build may share its episodes between worker
processes (``jobs``): each episode depends on its seed alone (the MPC's warm start is reset
with the episode), so any number of workers writes the same dataset.

Every seeded episode keeps its reset seed: its actions replayed in
the dataset's environment (`environment`) from that seed give its observations, rewards and costs bit
for bit (`replay`). The medium-replay episodes began at the training env's autoresets,
which take no seed of their own: they are not seeded. Per step the infos keep the safety cost
(``info["cost"]``: 1 for a step in which the tip entered the wall), the collision, the success
and the weighted reward terms (they sum to the reward). Seeds: each dataset draws from its own
band below the protocol's tuning seeds (``DATASET_SEED``), so no dataset episode is a tuning or
an evaluation episode. The reference scores (``ref_min_score``: the random actions' mean return,
``ref_max_score``: the expert's) are measured per task on `REFERENCE_SEED`'s band.

Datasets are inside the trust scheme (agents.files): a dataset's metadata names an
``env_spec.entry_point``, which Minari imports and calls (``recover_environment()``, and
``minari.load_dataset`` where the metadata holds no spaces), so the package never lets it: it
loads a dataset with `load` and builds its environment with `environment`, from the
package's own registry by the recorded id, refusing in one line a dataset whose entry point is not
that id's own or whose spaces are not its environment's. A dataset the package builds carries a
manifest (``SHA256SUMS`` beside ``data/``), checked when it loads; and every episode's
observations and actions must be finite and inside the environment's spaces (`check_episode`).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.algorithms.loaders import load_policy
from agents.algorithms.offline_data import (  # noqa: F401  (the datasets' safe loading, used here and re-exported)
    DATASET_FILES,
    check_episode,
    checked_episodes,
    datasets_root,
    environment,
    load,
)
from agents.files import published_runs, require_published_runs, write_digests, write_json
from scara_gym import __version__
from scara_gym.benchmark.episodes import run_episodes
from scara_gym.benchmark.protocol import evaluate, tuning
from scara_gym.envs.task import REWARD_TERMS
from scara_gym.extras import require
from scara_gym.model import checks
from scara_gym.model.checks import UserError

CONTROL_MODE = "pd"
TASKS = {
    "c11": {"randomize_start": True},
    "random-targets": {"randomize_target": True},
    "random-shifts": {"randomize_params": "all"},
}
"""task -> the environment arguments of its datasets (over DATASET_ENV_ID's, "pd" mode)"""
TIERED_TASKS = ("c11", "random-targets")
"""the tasks with every tier of TIERS (random-shifts has the oracle tier only)"""
DATASET_ENV_ID = "Scara-C11-v1"
"""the id the -v0 datasets are built and replayed on (frozen with them)"""
DATASET_VERSIONS = {"v0": DATASET_ENV_ID, "v1": "Scara-C11-v2"}
"""dataset version -> the id its datasets are built and replayed on: a build on a newer id is a new
version, with its own expert picked on that id"""
LATEST_DATASET_VERSION = "v1"
"""the version ``datasets build all`` builds: the protocol's id's"""
TASK_CONDITIONS = {"c11": "c11-starts", "random-targets": "random-targets", "random-shifts": "random-shifts"}
"""task -> the protocol condition whose tuning set picks its expert"""
TIERS = ("expert", "medium", "random", "medium-replay", "mixed")
DATASET_SEED = 60_000_000
"""dataset k of a version (DATASETS' order) resets from DATASET_SEED + k * 10^6 on, -v1's from
VERSION_SEED_OFFSET more (all below the tuning seeds, none in the reference scores' band)"""
VERSION_SEED_OFFSET = {"v0": 0, "v1": 20_000_000}
"""each version's seed bands: -v1's from 80M on, beyond -v0's and the reference band (70M-72M)"""
REFERENCE_SEED = 70_000_000
"""the reference scores' episodes: task k from REFERENCE_SEED + k * 10^6"""
REFERENCE_EPISODES = 100
TUNING_EPISODES = 30
"""the size of the tuning set the expert is picked on"""
MEDIUM_STEPS = 300_000
"""the medium agent's training budget (the engineered PPO runs train 1-4M steps)"""
CODE_PERMALINK = f"scara_gym {__version__}: agents/experiments/datasets.py"
_learned = "{runs}/" + DATASET_ENV_ID + "/pd/{name}/seed{seed}"  # the published runs
EXPERT_CANDIDATES = {
    "c11": ["shield:pd"] + [f"torchppo:{_learned.format(runs='{runs}', name='torch-ppo-residual-fast-starts', seed=s)}"
                            for s in range(5)],
    "random-targets": ["shield:pd"] + [
        f"{prefix}torchppo:{_learned.format(runs='{runs}', name='torch-ppo-residual-random-replay', seed=s)}"
        for prefix in ("", "shield:") for s in range(5)],
}
"""task -> the policy specs (agents.algorithms.loaders.load_policy) its expert is picked from:
PD behind the shield, and the published learned runs that do best on the task (alone, and behind
the shield where they collide); ``{runs}`` is the runs folder"""
PUBLISHED_EXPERTS = {
    "c11": {"policy": "torchppo:{runs}/Scara-C11-v1/pd/torch-ppo-residual-fast-starts/seed4",
            "scores": (-22.73179607251694, 35.56060983430466)},
    "random-targets": {"policy": "shield:pd", "scores": (-22.228404716813028, 34.374758477071474)},
}
"""task -> the expert pick_expert picks from the published runs and its reference_scores (random
actions', the expert's) as this version measures them: what a tier that does not run the expert
(random, medium, medium-replay) records where the published runs are not at hand
(tests/agents/test_datasets.py checks them against the runs). The expert's score is a float32
network's closed loop and differs by CPU in its last digits: the -v0 datasets' published c11 score
(docs/results/datasets.json) is 1.6e-6 lower, as this project's AMD EPYC machines measure it."""
EXPERT_TIERS = ("expert", "mixed")
"""the tiers whose episodes the expert acts in: they need the published runs"""
MEDIUM_FIELDS = {
    "c11": {"residual_scale": (2.5, 2.5, 0.05), "residual_deadzone": 0.5, "randomize_start": True},
    "random-targets": {"residual_scale": (2.5, 2.5, 0.05), "residual_deadzone": 0.5, "randomize_target": True},
}
"""task -> the medium agent's torch PPO Config fields: the engineered residual set-point on the
task's environment and its own reward, so that its rollouts' rewards are the dataset's"""


@dataclass(frozen=True)
class DatasetSpec:
    """One dataset of the set: its task, its tier and its default size."""

    task: str
    tier: str
    episodes: int
    index: int
    version: str = "v0"

    @property
    def name(self) -> str:
        return f"scara/{self.task}/{self.tier}-{self.version}"

    @property
    def env_id(self) -> str:
        """The id the dataset is built and replayed on (its version's)."""
        return DATASET_VERSIONS[self.version]

    @property
    def seed(self) -> int:
        return DATASET_SEED + VERSION_SEED_OFFSET[self.version] + self.index * 10**6


ORACLE_TIER = "oracle"
ORACLE_EXPERT = "mpc-rti"
"""the oracle tier's behaviour (a policy spec of agents.algorithms.loaders): the real-time MPC in "pd" mode"""
ORACLE_EPISODES = {"c11": 2000, "random-targets": 2000, "random-shifts": 2000}
"""task -> the oracle dataset's default size (6,000 episodes in all)"""
ORACLE_INDEX = 10
"""the oracle datasets' seed bands come after the tiered ones' (DatasetSpec.seed: index 10, 11, 12)"""
ORACLE_VERSIONS = ("v1",)
"""the versions with an oracle tier (-v0 is frozen as it was published)"""
ORACLE_DATASETS = tuple(DatasetSpec(task, ORACLE_TIER, count, ORACLE_INDEX + j, version)
                        for version in ORACLE_VERSIONS for j, (task, count) in enumerate(ORACLE_EPISODES.items()))
DATASETS = {s.name: s for s in (*(DatasetSpec(task, tier, 1000, k, version) for version in DATASET_VERSIONS
                                  for k, (task, tier) in enumerate((t, tier) for t in TIERED_TASKS for tier in TIERS)),
                                *ORACLE_DATASETS)}
"""every dataset of the set by its Minari id"""


def get_dataset(name: str) -> DatasetSpec:
    """The dataset ``name`` (ValueError listing the names otherwise)."""
    if name not in DATASETS:
        raise UserError(f"unknown dataset {name!r}; the datasets are {sorted(DATASETS)}")
    return DATASETS[name]


def make_env(task: str, env_id: str = DATASET_ENV_ID) -> gym.Env:
    """The environment of a task's datasets on ``env_id`` (what `environment` builds again)."""
    return gym.make(env_id, control_mode=CONTROL_MODE, **TASKS[task])


class RandomActions:
    """Uniformly random actions in [-1, 1] from one seeded generator (the recorded actions, not
    the generator, are what a replay uses)."""

    name = "random"

    def __init__(self, env, seed: int) -> None:
        self.shape = env.action_space.shape
        self.rng = np.random.default_rng(seed)

    def reset(self) -> None:
        pass

    def __call__(self, obs) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, self.shape)


class Alternating:
    """The mixed tier's behaviour: the policies in turn, one episode each."""

    def __init__(self, *policies) -> None:
        self.policies, self.episode = policies, -1
        self.name = " / ".join(p.name for p in policies)

    def reset(self) -> None:
        self.episode += 1
        self.policies[self.episode % len(self.policies)].reset()

    def __call__(self, obs) -> np.ndarray:
        return self.policies[self.episode % len(self.policies)](obs)


def episode_buffers(env, policy, seeds, time_to_go: bool = False, first_id: int = 0) -> list:
    """One Minari EpisodeBuffer per seed: the policy's episode from ``env.reset(seed=seed)``, with
    the step infos kept (the reset's row of each holds zeros); with ``time_to_go``, also each
    row's time to the episode's success (NaN where it does not succeed). Ids from ``first_id``."""
    require("minari")
    from minari.data_collector import EpisodeBuffer

    buffers = []
    for number, seed in enumerate(seeds, start=first_id):
        obs, _ = env.reset(seed=int(seed))
        policy.reset()
        observations, actions, rewards, terminations, truncations = [obs], [], [], [], []
        infos = _empty_infos()
        while True:
            action = np.asarray(policy(obs), dtype=np.float32)
            obs, reward, terminated, truncated, info = env.step(action)
            observations.append(obs)
            actions.append(action)
            rewards.append(reward)
            terminations.append(terminated)
            truncations.append(truncated)
            _append_info(infos, info)
            if terminated or truncated:
                break
        if time_to_go:
            times = np.asarray(infos["time"])
            infos["time_to_go"] = times[-1] - times if infos["is_success"][-1] else np.full(times.shape, np.nan)
        buffers.append(EpisodeBuffer(id=number, seed=int(seed), observations=np.array(observations),
                                     actions=np.array(actions), rewards=rewards, terminations=terminations,
                                     truncations=truncations, infos=_as_arrays(infos)))
    return buffers


def oracle_buffers(task: str, env_id: str, seeds: list[int], first_id: int = 0) -> list:
    """The oracle tier's episodes of ``seeds`` (episode_buffers with the time to go), in an
    environment and an expert of their own: what one worker process of a build runs."""
    env = make_env(task, env_id)
    return episode_buffers(env, load_policy(ORACLE_EXPERT, env), seeds, time_to_go=True, first_id=first_id)


def parallel_oracle_buffers(task: str, env_id: str, seeds: list[int], jobs: int = 1) -> list:
    """oracle_buffers over ``jobs`` worker processes (contiguous shares of ``seeds``, in order):
    the same episodes as one process's, each depending on its seed alone."""
    jobs = min(checks.integer("jobs", jobs, 1, 256), len(seeds))
    if jobs == 1:
        return oracle_buffers(task, env_id, seeds)
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    bounds = np.linspace(0, len(seeds), jobs + 1).astype(int)
    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        parts = [pool.submit(oracle_buffers, task, env_id, seeds[a:b], int(a)) for a, b in zip(bounds, bounds[1:])]
        return [buffer for part in parts for buffer in part.result()]


def _empty_infos() -> dict:
    """An episode's kept infos, with the reset's row (zeros)."""
    return {"cost": [0.0], "collision": [False], "is_success": [False], "time": [0.0],
            "reward_terms": {term: [0.0] for term in REWARD_TERMS}}


def _append_info(infos: dict, info: dict) -> None:
    infos["cost"].append(float(info["cost"]))
    infos["collision"].append(bool(info["collision"]))
    infos["is_success"].append(bool(info["is_success"]))
    infos["time"].append(float(info["time"]))
    for term in REWARD_TERMS:
        infos["reward_terms"][term].append(float(info["reward_terms"][term]))


def _as_arrays(infos: dict) -> dict:
    return {k: (_as_arrays(v) if isinstance(v, dict) else np.asarray(v)) for k, v in infos.items()}


def pick_expert(task: str, runs: Path, episodes: int = TUNING_EPISODES) -> dict:
    """The task's expert: among EXPERT_CANDIDATES, those without a collision on the tuning set
    of the task's condition (scara_gym.benchmark.protocol.tuning: never an evaluation seed, on
    the protocol's id for every version), the highest success rate, then the shortest mean time
    to target. Returns the record: the spec, and every candidate's figures."""
    condition = tuning(TASK_CONDITIONS[task], episodes)
    figures = []
    for spec in EXPERT_CANDIDATES[task]:
        spec = spec.format(runs=runs)
        result = evaluate(condition, lambda env, s=spec: load_policy(s, env), CONTROL_MODE)
        reach = result["reach_time"][result["success"]]
        figures.append({"policy": spec, "success_rate": float(np.mean(result["success"])),
                        "collision_rate": float(np.mean(result["collisions"])),
                        "mean_time": float(reach.mean()) if reach.size else float("inf")})
    safe = [f for f in figures if f["collision_rate"] == 0.0]
    if not safe:
        raise RuntimeError(f"no expert candidate of {task!r} is collision-free on the tuning set: {figures}")
    best = max(safe, key=lambda f: (f["success_rate"], -f["mean_time"]))
    return {"policy": best["policy"], "rule": "no collision on the tuning set, then the highest success rate, "
            "then the shortest mean time", "tuning_set": condition.name, "tuning_seeds": condition.seeds(),
            "candidates": figures}


def rollout_recorder():
    """A torch PPO hook (agents.algorithms.torch_ppo_hooks.Hook: built here, torch being the
    train extra's) that keeps every episode the training rollouts complete, as EpisodeBuffers
    (the medium-replay tier) in its ``episodes``."""
    require("minari")
    from minari.data_collector import EpisodeBuffer

    from agents.algorithms.torch_ppo_hooks import Hook

    def new(first_obs) -> dict:
        return {"observations": [first_obs], "actions": [], "rewards": [], "terminations": [], "truncations": [],
                "infos": _empty_infos()}

    class RolloutRecorder(Hook):
        def __init__(self) -> None:
            self.episodes: list = []
            self.open: list[dict] = []

        def on_start(self, obs: np.ndarray) -> np.ndarray:
            self.open = [new(row) for row in np.asarray(obs)]
            return obs

        def on_step(self, env_actions, next_obs, reward, terminated, truncated, info) -> None:
            for row, episode in enumerate(self.open):
                ended = bool(terminated[row] or truncated[row])
                episode["observations"].append(info["final_obs"][row] if ended else next_obs[row])
                episode["actions"].append(np.asarray(env_actions[row], dtype=np.float32))
                episode["rewards"].append(float(reward[row]))
                episode["terminations"].append(bool(terminated[row]))
                episode["truncations"].append(bool(truncated[row]))
                _append_info(episode["infos"], {
                    "cost": info["cost"][row], "collision": info["collision"][row],
                    "is_success": info["is_success"][row], "time": info["time"][row],
                    "reward_terms": {term: values[row] for term, values in info["reward_terms"].items()}})
                if ended:
                    self.episodes.append(EpisodeBuffer(
                        id=len(self.episodes), observations=np.array(episode["observations"]),
                        actions=np.array(episode["actions"]), rewards=episode["rewards"],
                        terminations=episode["terminations"], truncations=episode["truncations"],
                        infos=_as_arrays(episode["infos"])))
                    self.open[row] = new(next_obs[row])

    return RolloutRecorder()


def train_medium(task: str, folder: Path, seed: int = 0, env_id: str = DATASET_ENV_ID) -> tuple[Path, list]:
    """The task's medium agent (the single-file PPO for MEDIUM_STEPS steps on ``env_id``, seed
    ``seed``) trained into ``folder``, and every episode its rollouts completed."""
    from agents.algorithms.torch_ppo import Config, train

    recorder = rollout_recorder()
    config = Config(**MEDIUM_FIELDS[task], env_id=env_id, control_mode=CONTROL_MODE, seed=seed,
                    total_timesteps=MEDIUM_STEPS, torch_threads=1, out=str(folder))
    train(config, overwrite=True, hooks=[recorder])
    return folder, recorder.episodes


def reference_scores(task: str, expert: str, env_id: str = DATASET_ENV_ID) -> tuple[float, float]:
    """(random actions' mean return, the expert's) over REFERENCE_EPISODES episodes of the task on ``env_id``."""
    seeds = list(range(REFERENCE_SEED + list(TASKS).index(task) * 10**6,
                       REFERENCE_SEED + list(TASKS).index(task) * 10**6 + REFERENCE_EPISODES))
    env = make_env(task, env_id)
    low = run_episodes(env, RandomActions(env, seeds[0]), seeds)["return"].mean()
    high = run_episodes(env, load_policy(expert, env), seeds)["return"].mean()
    return float(low), float(high)


def build(name: str, episodes: int | None = None, out: Path | None = None, runs: Path | None = None,
          work: Path | None = None, verbose: bool = True, expert: dict | None = None,
          scores: tuple[float, float] | None = None, medium: tuple[Path, list] | None = None, jobs: int = 1):
    """Write the dataset ``name`` (DATASETS) with ``episodes`` episodes (default: its own count;
    medium-replay: the first of the medium run's training episodes, default all) into Minari's
    data folder, or ``out`` (it becomes MINARI_DATASETS_PATH). runs: the published runs the
    expert comes from (default: agents.files.published_runs; without them a tier outside
    EXPERT_TIERS records PUBLISHED_EXPERTS, the others are refused in one line); work: where the medium agent trains (default: a temporary folder);
    expert: pick_expert's record and scores: reference_scores' (measured here where None; the
    reference max score is the expert's, so every tier needs it); medium: train_medium's result
    for the medium tiers (trained here where None); jobs: the oracle tier's worker processes
    (parallel_oracle_buffers). Returns the MinariDataset."""
    spec = get_dataset(name)
    count = spec.episodes if episodes is None else checks.integer("episodes", episodes, 1, 10**6)
    if out is not None:
        os.environ["MINARI_DATASETS_PATH"] = str(Path(out).resolve())
    _refuse_existing(name)  # before any work
    started = time.perf_counter()
    if expert is None:  # before any episode: a missing runs folder is said at once
        expert, scores = _expert(spec, runs, scores)
    env = make_env(spec.task, spec.env_id)
    seeds = list(range(spec.seed, spec.seed + count))
    low, high = scores or reference_scores(spec.task, expert["policy"], spec.env_id)
    record: dict = {"package": "scara_gym", "version": __version__, "env_id": spec.env_id,
                    "env_kwargs": {"control_mode": CONTROL_MODE, **TASKS[spec.task]}, "task": spec.task,
                    "tier": spec.tier, "first_seed": None if spec.tier == "medium-replay" else seeds[0],
                    "expert": expert}
    with tempfile.TemporaryDirectory() as scratch:
        if spec.tier == ORACLE_TIER:
            policy = load_policy(expert["policy"], env)  # its name; the workers build their own
        elif spec.tier == "random":
            policy = RandomActions(env, spec.seed)
        elif spec.tier == "expert":
            policy = load_policy(expert["policy"], env)
        elif spec.tier == "mixed":
            policy = Alternating(load_policy(expert["policy"], env), RandomActions(env, spec.seed))
        else:  # medium, medium-replay: one training run
            folder, rollouts = medium or train_medium(spec.task, Path(work or scratch) / f"{spec.task}-medium",
                                                      env_id=spec.env_id)
            record["medium_run"] = {**{k: list(v) if isinstance(v, tuple) else v
                                       for k, v in MEDIUM_FIELDS[spec.task].items()},
                                    "total_timesteps": MEDIUM_STEPS, "seed": 0}
            policy = load_policy(f"torchppo:{folder}", env)
        record["behaviour"] = "torch-ppo rollouts (stochastic)" if spec.tier == "medium-replay" else policy.name
        if spec.tier == "medium-replay":
            buffers = rollouts[:count] if episodes is not None else rollouts
        elif spec.tier == ORACLE_TIER:
            buffers = parallel_oracle_buffers(spec.task, spec.env_id, seeds, jobs)
        else:
            buffers = episode_buffers(env, policy, seeds)
        description = json.dumps(record)
        dataset = _create_atomically(name, dict(
            buffer=buffers, env=env, eval_env=env, algorithm_name=f"{spec.tier}: {record['behaviour']}",
            author="scara_gym", author_email="scara_gym's issue tracker", code_permalink=CODE_PERMALINK,
            ref_min_score=low, ref_max_score=high, num_episodes_average_score=REFERENCE_EPISODES,
            description=description, data_format="hdf5", requirements=[f"scara_gym=={__version__}"]))
    if verbose:
        print(f"{name}: {dataset.total_episodes} episodes, {dataset.total_steps} steps, "
              f"{dataset.storage.get_size():.1f} MB, {time.perf_counter() - started:.0f} s", flush=True)
    return dataset


def _expert(spec: DatasetSpec, runs: Path | None, scores: tuple[float, float] | None) -> tuple[dict, tuple | None]:
    """(pick_expert's record, the reference scores or None to measure them) for ``spec``: picked
    among the published runs where they are at hand, else PUBLISHED_EXPERTS' record and scores for
    a tier that does not run the expert; UserError naming what is missing otherwise. The oracle
    tier's expert is the real-time MPC: it needs no runs."""
    if spec.tier == ORACLE_TIER:
        return {"policy": ORACLE_EXPERT, "rule": "the oracle tier's expert: the real-time MPC (agents.policies."
                "mpc_rti) in the \"pd\" mode, with its defaults"}, scores
    if runs is not None:  # named by the user: there, or refused
        return pick_expert(spec.task, require_published_runs(runs)), scores
    runs = published_runs()
    if runs is not None and runs.is_dir():
        return pick_expert(spec.task, runs), scores
    if spec.tier in EXPERT_TIERS or spec.version != "v0":  # -v0's expert and scores are recorded, not a newer one's
        require_published_runs()  # one line: the runs are missing, and how to get them
    published = PUBLISHED_EXPERTS[spec.task]
    return ({"policy": published["policy"].format(runs="results/runs"), "rule": "recorded: the expert "
             "pick_expert picked among the published runs (results/runs) and its reference scores, as published "
             "with the -v0 datasets; the runs were not at hand"}, scores or published["scores"])


def _refuse_existing(name: str) -> None:
    final = datasets_root() / name
    if final.exists():
        raise UserError(f"dataset {name} exists already in {datasets_root()}; remove {final} to build it again")


def _create_atomically(name: str, arguments: dict):
    """minari.create_dataset_from_buffers(name, **arguments), written in a staging folder beside
    the dataset's place and renamed into it whole: a crash leaves no half dataset under its id."""
    require("minari")
    import minari
    from minari.namespace import create_namespace, list_local_namespaces

    root = datasets_root()
    final = root / name
    _refuse_existing(name)
    root.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=root, prefix=".partial-") as staging:
        os.environ["MINARI_DATASETS_PATH"] = staging
        try:
            minari.create_dataset_from_buffers(dataset_id=name, **arguments)
        finally:
            os.environ["MINARI_DATASETS_PATH"] = str(root)
        parts = name.split("/")
        for depth in range(1, len(parts)):  # the namespaces scara and scara/TASK, in the real folder
            namespace = "/".join(parts[:depth])
            if namespace not in list_local_namespaces():
                create_namespace(namespace)
        write_digests(Path(staging) / name, DATASET_FILES)  # its manifest, as a run folder's, before it is in place
        final.parent.mkdir(parents=True, exist_ok=True)
        os.replace(Path(staging) / name, final)
    return load(name)


def replay(dataset, episodes: int | None = None) -> int:
    """Replay the seeded episodes of a MinariDataset: each one's actions in its environment
    (`environment`, from the package's registry) from its recorded seed; AssertionError at
    the first observation, reward, termination or cost that differs in any bit, ValueError at an
    episode with values that are not finite or outside their spaces. Returns how many were replayed."""
    env = environment(dataset)
    metadata = list(dataset.storage.get_episode_metadata(range(dataset.total_episodes)))
    replayed = 0
    for episode, meta in zip(checked_episodes(dataset, env), metadata):
        if meta.get("seed") is None or (episodes is not None and replayed >= episodes):
            continue
        obs, _ = env.reset(seed=int(meta["seed"]))
        assert np.array_equal(obs, episode.observations[0]), f"episode {episode.id}: the first observation differs"
        for step, action in enumerate(episode.actions):
            obs, reward, terminated, truncated, info = env.step(action)
            same = (np.array_equal(obs, episode.observations[step + 1]) and reward == episode.rewards[step]
                    and terminated == episode.terminations[step] and truncated == episode.truncations[step]
                    and info["cost"] == episode.infos["cost"][step + 1])
            assert same, f"episode {episode.id}, step {step}: the replay differs from the dataset"
        replayed += 1
    return replayed


def build_all(episodes: int | None = None, out: Path | None = None, runs: Path | None = None,
              work: Path | None = None, summary: Path | None = None,
              version: str = LATEST_DATASET_VERSION, tiers: tuple[str, ...] | None = None,
              jobs: int = 1) -> list[dict]:
    """Every dataset of DATASETS of ``version`` (of ``tiers`` where given; each task's expert picked
    once, on the version's id); rows of name, episodes, steps, size [MB] and build time [s],
    written as JSON to ``summary`` where given. A dataset already in the folder is kept as it is
    (its row says so): an interrupted build goes on where it stopped. jobs: the oracle tier's
    worker processes."""
    checks.choice("version", version, tuple(DATASET_VERSIONS))
    every_tier = (*TIERS, ORACLE_TIER)
    for tier in tiers or ():
        checks.choice("tiers", tier, every_tier)
    if out is not None:
        os.environ["MINARI_DATASETS_PATH"] = str(Path(out).resolve())
    chosen = [(n, s) for n, s in DATASETS.items() if s.version == version and s.tier in (tiers or every_tier)]
    rows, experts, scores, mediums = [], {}, {}, {}
    if any(s.tier != ORACLE_TIER for _, s in chosen):
        runs = require_published_runs(runs)  # the expert tiers need them
    with tempfile.TemporaryDirectory() as scratch:
        for name, spec in chosen:
            started = time.perf_counter()
            if (datasets_root() / name).exists():
                rows.append({**_row(load(name), None), "kept": "built before; kept as it is"})
                continue
            key = (spec.task, spec.tier == ORACLE_TIER)  # the oracle tier's expert is its own
            if key not in experts:
                experts[key] = _expert(spec, None, None)[0] if spec.tier == ORACLE_TIER else pick_expert(spec.task, runs)
                scores[key] = reference_scores(spec.task, experts[key]["policy"], spec.env_id)
            if spec.tier in ("medium", "medium-replay") and spec.task not in mediums:
                mediums[spec.task] = train_medium(spec.task, Path(work or scratch) / f"{spec.task}-medium",
                                                  env_id=spec.env_id)
            dataset = build(name, episodes, out, runs, work, expert=experts[key], scores=scores[key],
                            medium=mediums.get(spec.task), jobs=jobs)
            rows.append(_row(dataset, time.perf_counter() - started))
            if summary is not None:
                write_json(summary, {"datasets": rows, "experts": {f"{task}{' (oracle)' if oracle else ''}": e
                                                                   for (task, oracle), e in experts.items()}})
    return rows


def _row(dataset, seconds: float | None) -> dict:
    metadata = dataset.storage.metadata
    return {"name": dataset.id, "episodes": dataset.total_episodes, "steps": dataset.total_steps,
            "size_mb": round(dataset.storage.get_size(), 2), "seconds": None if seconds is None else round(seconds, 1),
            "ref_min_score": metadata["ref_min_score"], "ref_max_score": metadata["ref_max_score"],
            "behaviour": metadata["algorithm_name"]}

