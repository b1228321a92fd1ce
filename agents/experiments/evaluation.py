"""The one evaluation engine: policies from their specs, their episodes as per-episode arrays,
learned runs' evaluations cached, and the plain evaluation table of ``scara-agents evaluate``.

Policies come from their specs (``pd``, ``shield:pd``, ``torchppo:DIR``, a bare run folder, ...)
by agents.algorithms.loaders.load_policy, the one table from a spec's kind to its loader.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from agents.algorithms.loaders import load_policy, run_spec
from agents.experiments.runs import is_finished
from agents.files import POLICY_FILES, load_arrays, save_arrays
from agents.policies import mpc as mpc_module, mpc_rti as mpc_rti_module
from agents.policies.mpc import MPCConfig, MPCPolicy, solve_time_summary
from agents.policies.mpc_rti import RTIConfig, RTIMPCPolicy
from scara_gym import __version__
from scara_gym.benchmark.episodes import BAND_NAMES, band_keys
from scara_gym.benchmark.protocol import ENV_ID, Condition, evaluate as evaluate_condition, get_condition
from scara_gym.model import symbolic as symbolic_module
from scara_gym.model.checks import UserError

SHIELD_KEY = b"scara_gym.wrappers.Shield with a committed backup, 3 steps at rest, a flushed line, defaults"
"""what a shielded evaluation's cache key says of the shield (changed with the shield's rules)"""


make_policy = load_policy
"""the policy of a spec for an env: agents.algorithms.loaders.load_policy (this name kept for its callers)"""


TASK_KWARGS = ("goal_tolerance",)
"""environment arguments that define the task a run trains for (not its reward or its physics):
an evaluation that uses a run's own reports them beside the benchmark's"""


def evaluation_key(run_dir: Path, condition: Condition, mode: str, episodes: int | None,
                   shield: bool = False) -> str:
    """What a learned run's evaluation depends on: its policy's files, the condition (and the
    environment it builds), the episodes, the package version and whether a shield acts."""
    digest = hashlib.sha256()
    for name in POLICY_FILES:
        if (Path(run_dir) / name).exists():
            digest.update(name.encode() + (Path(run_dir) / name).read_bytes())
    if shield:
        digest.update(SHIELD_KEY)
    digest.update(json.dumps([dataclasses.asdict(condition), mode, condition.seeds(episodes), ENV_ID,
                              __version__], sort_keys=True, default=str).encode())
    return digest.hexdigest()[:32]


def learned_episodes(run_dir: Path, condition: Condition, mode: str, episodes: int | None = None,
                     cache: Path | None = None, shield: bool = False) -> dict:
    """A finished run's episodes in a protocol condition (scara_gym.benchmark.protocol.evaluate;
    behind scara_gym.wrappers.Shield with ``shield``), from ``cache`` where it holds them (else
    kept there)."""

    def run() -> dict:
        with OneTorchThread(lambda env: load_policy(run_spec(run_dir, shield), env)) as factory:
            result = evaluate_condition(condition, factory, mode, episodes)
        result.pop("condition")
        return result

    if cache is None:
        return run()
    return _kept(Path(cache) / f"{evaluation_key(run_dir, condition, mode, episodes, shield)}.npz", run)


BAND_KEYS = [band_keys(name) for name in BAND_NAMES]
"""(success, time to the band) per band scored (scara_gym.benchmark.episodes.BANDS), the C11 band's first"""
ENTRY_KINDS = {"success": "b", "collisions": "b", "collision_counts": "iu", "reach_time": "f", "energy": "f",
               "peak_current_fraction": "f", "return": "f", "seeds": "iu",
               **{key: kind for success, reach in BAND_KEYS[1:] for key, kind in ((success, "b"), (reach, "f"))}}
"""the per-episode arrays every kept evaluation holds, with the numpy kinds they may have (an evaluation
kept before the looser bands were scored lacks theirs: it is evaluated again)"""


def entry_problem(arrays: dict[str, np.ndarray]) -> str | None:
    """What makes ``arrays`` no evaluation this package kept (None: nothing): a per-episode array
    missing, of another kind or length, a value that is not finite (a time to a band: NaN exactly
    where the episode did not reach it), no trace, or any array that is not numbers."""
    missing = sorted(set(ENTRY_KINDS) - set(arrays))
    if missing:
        return f"no {missing}"
    episodes = len(arrays["seeds"])
    for key, kinds in ENTRY_KINDS.items():
        if arrays[key].dtype.kind not in kinds or arrays[key].shape != (episodes,):
            return f"{key} is not {episodes} values of kind {kinds!r}"
    if any(a.dtype.kind not in "biuf" for a in arrays.values()):
        return "an array that is not numbers"
    times = {reach for _, reach in BAND_KEYS}
    finite = {k: np.isfinite(a).all() for k, a in arrays.items() if a.dtype.kind == "f" and k not in times}
    if not all(finite.values()):
        return f"{sorted(k for k, ok in finite.items() if not ok)} hold values that are not finite"
    for success, reach in BAND_KEYS:
        if not np.array_equal(np.isfinite(arrays[reach]), arrays[success]):
            return f"{reach} is not finite exactly where the episode " + (
                "succeeded" if success == "success" else "reached the band")
    if "traces_0" not in arrays:
        return "no trace"
    return None


def _kept(path: Path, run) -> dict:
    """The evaluation kept at ``path``, else ``run()``'s, kept there whole or not at all (a
    stopped comparison leaves no half entry). An entry that is not one this package kept
    (truncated, keys missing, text or values that are not finite: `entry_problem`) is
    evaluated again and replaced, with a line on stderr saying why."""
    if path.exists():
        try:
            arrays = load_arrays(path)
            problem = entry_problem(arrays)
        except ValueError as error:
            problem = str(error)
        if problem is None:
            return _from_arrays(arrays)
        print(f"{path}: not a kept evaluation ({problem}); evaluated again", file=sys.stderr, flush=True)
    result = run()
    save_arrays(path, _to_arrays(result))
    return result


def cached_evaluation(cache: Path | None, prefix: str, sources, description, run) -> dict:
    """``run()``'s result (an evaluation's per-episode arrays), from ``cache/PREFIX-KEY.npz``
    where it is kept, else kept there: KEY digests the source of the ``sources`` modules, the
    JSON of ``description`` (what is evaluated, the condition, the seeds) and the environment
    id and package version (which stand for the environments' code, as for learned runs)."""
    if cache is None:
        return run()
    digest = hashlib.sha256()
    for module in sources:
        digest.update(Path(module.__file__).read_bytes())
    digest.update(json.dumps([description, ENV_ID, __version__], sort_keys=True, default=str).encode())
    return _kept(Path(cache) / f"{prefix}-{digest.hexdigest()[:32]}.npz", run)


def condition_description(condition: Condition, episodes: int | None) -> list:
    """What a cache key says of a condition: all its fields and the seeds evaluated. A condition
    without corners leaves that field out, so the evaluations cached before it existed stay valid."""
    fields = dataclasses.asdict(condition)
    if fields["corners"] is None:
        del fields["corners"]
    return [fields, condition.seeds(episodes)]


MPC_SOURCES = (mpc_module, symbolic_module)
"""the modules whose source an MPC evaluation's cache key digests (beside its configuration)"""


def mpc_episodes(condition: Condition, episodes: int | None = None, cache: Path | None = None,
                 config: MPCConfig | None = None, mode: str = "voltage") -> dict:
    """The MPC's episodes in a protocol condition, with every solve's time ("solve_times" [s])
    and their summary ("solve_time"), from ``cache`` where it holds them (cached_evaluation: the
    MPC's and the symbolic model's source, its configuration, the control mode, the condition
    and seeds). config: the MPC's (None: its defaults); mode: the environment's control mode
    ("voltage": the MPC commands voltages, "pd": set-points)."""
    config = MPCConfig() if config is None else config
    return _controller_episodes("mpc", MPC_SOURCES, lambda env: MPCPolicy(env, config), dataclasses.asdict(config),
                                condition, episodes, cache, mode)


RTI_SOURCES = (mpc_module, mpc_rti_module, symbolic_module)
"""the modules whose source a real-time MPC evaluation's cache key digests (beside its configuration)"""


def rti_episodes(condition: Condition, episodes: int | None = None, cache: Path | None = None,
                 config: RTIConfig | None = None, mode: str = "voltage") -> dict:
    """mpc_episodes for the real-time MPC (agents.policies.mpc_rti: one SQP step per control
    step on HPIPM), its solve times those of its whole step; cached under its own sources and
    configuration."""
    config = RTIConfig() if config is None else config
    return _controller_episodes("mpc-rti", RTI_SOURCES, lambda env: RTIMPCPolicy(env, config),
                                dataclasses.asdict(config), condition, episodes, cache, mode)


def _controller_episodes(prefix: str, sources, make, settings: dict, condition: Condition, episodes: int | None,
                         cache: Path | None, mode: str) -> dict:
    """An optimizing controller's episodes (the MPC's, the real-time MPC's) with its solve times,
    cached under ``prefix``, ``sources`` and its ``settings``."""
    policies: list[MPCPolicy] = []

    def run() -> dict:
        def factory(env):
            policies.append(make(env))
            return policies[-1]

        result = evaluate_condition(condition, factory, mode, episodes)
        result.pop("condition")
        result["solve_times"] = np.asarray(policies[0].solve_times)
        result["solver_failures"] = np.asarray(policies[0].failures)
        return result

    description = [prefix, settings, mode, *condition_description(condition, episodes)]
    result = cached_evaluation(cache, prefix, sources, description, run)
    result["solve_time"] = {**solve_time_summary(result["solve_times"]), "failures": int(result["solver_failures"])}
    return result


DECISION_EPISODES = 3
"""the evaluation episodes of a condition (its first seeds) a policy's compute per decision is timed over"""


class OneTorchThread:
    """A policy factory whose networks act on one torch thread, torch's own setting given back on
    leaving (a context manager around the episodes). A decision is a batch-1 forward pass through a
    few small layers: a second thread only adds its hand-off, and while other processes hold the
    cores it waits for a time slice. On these 2-core machines beside three training jobs, torch's
    default of a thread per core made each of torch-ppo's 64-wide layers take 6 ms (cProfile: 68 of
    an evaluation's 88 s in torch.baddbmm). The env steps on one thread too. torch is set once the
    factory's loader has imported it; a policy without a network never imports it."""

    def __init__(self, factory) -> None:
        self.factory, self.saved = factory, None

    def __call__(self, env):
        policy = self.factory(env)
        torch = sys.modules.get("torch")
        if torch is not None and self.saved is None:
            self.saved = torch.get_num_threads()
            torch.set_num_threads(1)
        return policy

    def __enter__(self) -> OneTorchThread:
        return self

    def __exit__(self, *exc) -> None:
        if self.saved is not None:
            sys.modules["torch"].set_num_threads(self.saved)
            self.saved = None


class _TimedPolicy:
    """A policy whose every decision's wall time is kept (the call obs -> action, whatever it does:
    a network's forward pass, a shield's backup check, an MPC's solve)."""

    def __init__(self, policy) -> None:
        self.policy, self.seconds = policy, []

    def reset(self) -> None:
        if callable(getattr(self.policy, "reset", None)):
            self.policy.reset()

    def __call__(self, obs):
        started = time.perf_counter_ns()
        action = self.policy(obs)
        self.seconds.append((time.perf_counter_ns() - started) * 1e-9)
        return action


def decision_time(condition: Condition, policy_factory, mode: str, episodes: int = DECISION_EPISODES) -> dict:
    """A policy's compute per control step in a condition: the median and 95th percentile [s] of
    the wall time of each of its decisions over the condition's first ``episodes`` evaluation
    episodes, torch on one thread. Never cached: a property of the machine it is measured on,
    measured again by each comparison; on a loaded machine the scheduler's time slices (about
    15 ms) land in the 95th percentile, so the published figures come from an idle one."""
    timed: list[_TimedPolicy] = []

    def factory(env):
        timed.append(_TimedPolicy(policy_factory(env)))
        return timed[-1]

    with OneTorchThread(factory) as one_thread:
        evaluate_condition(condition, one_thread, mode, min(episodes, condition.episodes), record=0)
    seconds = np.array([s for t in timed for s in t.seconds])
    return {"median": float(np.median(seconds)), "p95": float(np.percentile(seconds, 95)),
            "decisions": int(seconds.size)}


def _to_arrays(result: dict) -> dict[str, np.ndarray]:
    """an evaluation's result as plain arrays (its traces numbered; "trace" is traces_0)."""
    arrays = {k: v for k, v in result.items() if k not in ("trace", "traces")}
    arrays.update({f"traces_{i}": trace for i, trace in enumerate(result["traces"])})
    return arrays


def _from_arrays(arrays: dict[str, np.ndarray]) -> dict:
    result = {k: v for k, v in arrays.items() if not k.startswith("traces_")}
    result["traces"] = [arrays[f"traces_{i}"] for i in range(sum(k.startswith("traces_") for k in arrays))]
    result["trace"] = result["traces"][0]
    return result


def learned_runs(runs_root: Path) -> dict[tuple[str, str], list[Path]]:
    """(algorithm, control mode) -> finished run folders, seed order, under
    ``RUNS/TRAINED_ON/MODE/NAME/seedN``. Every run is scored on the protocol's id whatever it was
    trained on (the runs published before 0.4.0 were trained on Scara-C11-v1, the same physics
    within v1's accuracy); where a run name has runs trained on several ids, those trained on the
    protocol's id are taken, and with none of them the choice is refused."""
    by_id: dict[tuple[str, str], dict[str, list[Path]]] = {}
    for config in sorted(Path(runs_root).glob("*/*/*/seed*/config.json")):
        run = config.parent
        if is_finished(run):  # SB3's model.zip, or the torch PPO's model.pt
            trained_on = run.parent.parent.parent.name
            by_id.setdefault((run.parent.name, run.parent.parent.name), {}).setdefault(trained_on, []).append(run)
    groups = {}
    for key, runs in by_id.items():
        if len(runs) > 1 and ENV_ID not in runs:
            raise UserError(f"{runs_root}: the runs of {key[0]} ({key[1]}) were trained on {sorted(runs)}; keep "
                            f"one id's, or train them on {ENV_ID}")
        groups[key] = sorted(runs.get(ENV_ID) or next(iter(runs.values())),
                             key=lambda p: int(p.name.removeprefix("seed")))
    return groups


COLUMNS = ("policy", "episodes", "success rate", "collision rate", "mean time to target [s]",
           "worst time to target [s]", "energy [J]", "peak current [Imax]", "return")
"""the columns of the plain evaluation table"""


def summary_row(name: str, result: dict) -> dict:
    """The plain evaluation table's row of one policy's per-episode arrays."""
    reach = result["reach_time"][result["success"]]
    return {
        "policy": name, "episodes": len(result["success"]),
        "success rate": float(np.mean(result["success"])), "collision rate": float(np.mean(result["collisions"])),
        "mean time to target [s]": reach.mean() if reach.size else np.nan,
        "worst time to target [s]": reach.max() if reach.size else np.nan,
        "energy [J]": float(np.mean(result["energy"])),
        "peak current [Imax]": float(np.max(result["peak_current_fraction"])),
        "return": float(np.mean(result["return"])),
        "seeds": result["seeds"].tolist() if "seeds" in result else None,
        "outcomes": [{"success": bool(s), "collisions": int(c),
                      "reach_time": None if np.isnan(t) else float(t)}
                     for s, c, t in zip(result["success"], result["collision_counts"], result["reach_time"])],
    }


def evaluate(policies: list[str], control_mode: str = "pd", condition: str = "c11", episodes: int | None = None,
             record: int = 3, env_id: str = ENV_ID, seed: int | None = None) -> tuple[list[dict], dict]:
    """Summary rows and recorded traces (first ``record`` episodes) per policy spec, in a
    condition of the protocol (scara_gym.benchmark.protocol) on ``env_id``; seed: the first
    episode's seed instead of the condition's (its distribution on other seeds)."""
    condition = get_condition(condition)
    if seed is not None:
        condition = condition.with_seed(seed)
    rows, traces = [], {}
    for spec in policies:
        names = []

        def factory(env, spec=spec, names=names):
            policy = make_policy(spec, env)
            names.append(policy.name)
            return policy

        with OneTorchThread(factory) as one_thread:
            result = evaluate_condition(condition, one_thread, control_mode, episodes, env_id, record=record)
        traces[names[0]] = result["traces"]
        rows.append(summary_row(names[0], result))
    return rows, traces
