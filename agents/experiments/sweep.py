"""Seeds x hyperparameter grids on Ray Tune, results as comparison tables (``scara-agents sweep``).

    scara-agents sweep --run sac --env-id Scara-C11-Goal-v0 --seeds 0 1 2 3 4 \\
        --grid learning_rate=0.0003,0.001 --condition random-targets --out runs/sweeps/her
    scara-agents sweep --run torch-ppo --seeds 0 1 2 --grid ent_coef=0,0.01 --address ray://head:10001

Every trial is one training run of a registered run (agents.experiments.registry) with the grid
point's overrides (names of its YAML block, or of the torch PPO Config), then an evaluation of
the trained policy over ``episodes`` episodes of one protocol condition's *tuning set*
(scara_gym.benchmark.protocol.tuning: the condition's distribution on tuning seeds, never its
evaluation seeds, since a sweep chooses). Ray
Tune schedules the trials: on a local Ray runtime started for the sweep (nothing to set up; one
CPU per trial by default) or on an existing cluster (``address``). A trial that fails is
reported and retried up to ``max_failures`` times; its run folder (``OUT/runs/TAG/seedN``)
holds the training snapshots, so a retry resumes where the failed attempt stopped, and a
finished run is not trained again (so a sweep can be re-run to fill in what is missing).

Writes ``OUT/sweep.json`` (the comparison's entry format, one entry per grid point, every seed
listed) and ``OUT/sweep.md`` (the comparison's table), plus Ray's own records under
``OUT/ray``. Publishing then copies each finished trial's run (model and history only) to
``DEST/ENV_ID/MODE/NAME/seedN`` (``NAME_TAG`` for a grid point other than the default), where
the comparison finds it. Ray is an install extra: ``pip install "scara_gym[sweep]"``.
"""

from __future__ import annotations

import itertools
import json
import re
import signal
import time
from pathlib import Path

import numpy as np

from agents.algorithms.loaders import load_policy, run_spec
from agents.algorithms.sb3.hyperparams import check_hyperparams
from agents.algorithms.torch_ppo_config import Config
from agents.experiments.evaluation import BAND_KEYS, TASK_KWARGS
from agents.experiments.registry import spec
from agents.experiments.report import condition_tables
from agents.experiments.runs import hyperparams_of, is_finished, publish, run_dir, train_run
from agents.experiments.statistics import entry
from agents.files import json_record, save_arrays
from scara_gym.benchmark.protocol import evaluate, get_condition, tuning
from scara_gym.extras import require
from scara_gym.model.checks import UserError


def parse_grid(items: list[str]) -> dict[str, list]:
    """``name=v1,v2`` items -> {name: [values]}; values are YAML scalars (numbers, true, null)."""
    require("yaml")
    import yaml

    grid = {}
    for item in items:
        name, sep, values = item.partition("=")
        if not sep or not name or not values:
            raise UserError(f"--grid takes NAME=V1,V2,..., got {item!r}")
        grid[name] = [yaml.safe_load(v) for v in values.split(",")]
    return grid


def grid_points(grid: dict[str, list]) -> list[dict]:
    """Every combination of the grid's values (one empty point for an empty grid)."""
    names = sorted(grid)
    return [dict(zip(names, values)) for values in itertools.product(*(grid[n] for n in names))]


def tag(point: dict) -> str:
    """A folder-safe name of a grid point: 'default' or 'lr=0.001_batch_size=64'."""
    return "_".join(f"{k}={v}" for k, v in sorted(point.items())) or "default"


def point_hyperparams(algo: str, env_id: str, control_mode: str, point: dict) -> dict:
    """The run's hyperparameters with a grid point's overrides; a name they lack is an error, and so
    is a name or value that is not a plain word or number (they become folder names: tag)."""
    for name, value in point.items():
        if not PLAIN_NAME.fullmatch(str(name)) or not PLAIN_VALUE.fullmatch(str(value)):
            raise UserError(f"--grid: {name}={value!r} is not a plain name and value (letters, digits, "
                            "'_', '.', '+', '-', not starting with '.'); grid points become folder names")
    hyper = hyperparams_of(algo, env_id, control_mode)
    unknown = sorted(set(point) - set(hyper))
    if unknown:
        raise UserError(f"--grid names {unknown} that {algo}'s hyperparameters for {env_id}/{control_mode} do not "
                        f"have; they are {sorted(hyper)}")
    merged = {**hyper, **point}
    if spec(algo).trainer == "torch-ppo":  # the values checked too, before any trial starts
        Config.from_dict({**merged, "env_id": env_id, "control_mode": control_mode})
    else:
        check_hyperparams(dict(merged))
    return merged


PLAIN_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
PLAIN_VALUE = re.compile(r"[A-Za-z0-9_+-][A-Za-z0-9_.+-]*")
EPISODE_ARRAYS = ("success", "collisions", "reach_time", "energy", "return", *(k for pair in BAND_KEYS[1:] for k in pair))
"""the per-episode arrays a trial keeps: the comparison entry's, every band's success and time among them"""


def task_kwargs(hyper: dict) -> dict:
    """The task-defining environment arguments a run trains with (evaluation.TASK_KWARGS)."""
    return {k: v for k, v in hyper.get("env_kwargs", {}).items() if k in TASK_KWARGS}


def train_and_evaluate(algo: str, env_id: str, control_mode: str, seed: int, overrides: dict, out: Path,
                       condition: str, episodes: int, total_timesteps: int | None = None) -> dict:
    """One trial: train (or resume, or find finished) the run in ``out``, evaluate it; returns
    the per-episode arrays of the comparison plus the training seconds. A run that trains for
    another task than the benchmark's (task_kwargs: e.g. a looser goal_tolerance) is evaluated
    in its own task and in the benchmark's, the latter's arrays prefixed "benchmark_"."""
    hyper = point_hyperparams(algo, env_id, control_mode, overrides)
    train_run(algo, out, seed, env_id, control_mode, total_timesteps, hyperparams=hyper, resume=True)
    task = task_kwargs(hyper)
    result = {"train_seconds": json_record(out / "config.json")["train_seconds"]}
    tuning_set = tuning(condition)  # a sweep chooses: it never sees an evaluation seed
    for prefix, kwargs in (("", task), ("benchmark_", {})) if task else (("", {}),):
        runs = evaluate(tuning_set, lambda env: load_policy(run_spec(out), env), control_mode, episodes, env_id,
                        env_kwargs=kwargs)
        result.update({prefix + key: runs[key] for key in EPISODE_ARRAYS})
    return result


def _trial(config: dict) -> None:
    """The Ray Tune trainable: one (grid point, seed), its arrays saved beside its run."""
    require("ray")
    from ray import tune

    config = config["trial"]
    out = Path(config["out"])
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "attempts.log", "a") as log:  # one line per attempt: retries are visible
        log.write(f"{time.time():.0f}\n")
    result = train_and_evaluate(config["algo"], config["env_id"], config["control_mode"], config["seed"],
                                config["point"], out, config["condition"], config["episodes"],
                                config["total_timesteps"])
    save_arrays(out / "evaluation.npz", result)  # whole or not at all: a retry finds it or not
    reach = result["reach_time"]
    tune.report({"success_rate": float(np.mean(result["success"])),
                 "collision_rate": float(np.mean(result["collisions"])),
                 "time_mean": float(np.nanmean(reach)) if np.isfinite(reach).any() else float("nan"),
                 "energy_mean": float(np.mean(result["energy"])), "train_seconds": result["train_seconds"]})


LOOPBACK = "127.0.0.1"
"""the interface a local Ray runtime started by a sweep binds to"""


def _interrupt(signum, frame):
    """SIGTERM during a sweep: raised as KeyboardInterrupt, so that the Ray runtime it started stops."""
    raise KeyboardInterrupt(f"signal {signum}")


def run_sweep(algo: str, env_id: str, control_mode: str, seeds: list[int], grid: dict[str, list], out: Path,
              condition: str = "c11", episodes: int = 100, total_timesteps: int | None = None,
              address: str | None = None, cpus_per_trial: float = 1.0, max_failures: int = 2,
              num_cpus: int | None = None, max_concurrent: int | None = None) -> list[dict]:
    """Every (grid point, seed) as a Ray Tune trial; returns the comparison entries (and writes
    sweep.json and sweep.md under ``out``). Failed trials (after their retries) are listed in
    the entries' notes and in sweep.json's "failed"."""
    require("ray")
    import ray
    from ray import tune

    spec(algo)
    get_condition(condition)  # raises naming the protocol's conditions
    out = Path(out).resolve()
    points = grid_points(grid)
    for point in points:  # bad names fail here, before any trial starts
        point_hyperparams(algo, env_id, control_mode, point)
    trials = [{"algo": algo, "env_id": env_id, "control_mode": control_mode, "seed": seed, "point": point,
               "out": str(out / "runs" / tag(point) / f"seed{seed}"), "condition": condition,
               "episodes": episodes, "total_timesteps": total_timesteps}
              for point in points for seed in seeds]
    package_root = str(Path(__file__).resolve().parents[2])
    started_here = not ray.is_initialized()
    if started_here:  # a local runtime listens on the loopback interface only
        local = {"_node_ip_address": LOOPBACK, "runtime_env": {"env_vars": {"PYTHONPATH": package_root}},
                 "num_cpus": num_cpus} if address is None else {}
        ray.init(address=address, include_dashboard=False, log_to_driver=False, **local)
    previous_handler = signal.signal(signal.SIGTERM, _interrupt) if started_here else None
    try:
        tuner = tune.Tuner(
            tune.with_resources(_trial, {"cpu": cpus_per_trial}),
            param_space={"trial": tune.grid_search(trials)},
            tune_config=tune.TuneConfig(max_concurrent_trials=max_concurrent),
            run_config=tune.RunConfig(name="ray", storage_path=str(out), verbose=0,
                                      failure_config=tune.FailureConfig(max_failures=max_failures)))
        results = tuner.fit()
    finally:
        if started_here:  # on normal exit, an error, SIGINT (KeyboardInterrupt) or SIGTERM (_interrupt)
            signal.signal(signal.SIGTERM, previous_handler)
            ray.shutdown()
    failed = []
    for result in results:
        if result.error is not None:
            trial = result.config["trial"]
            attempts = Path(trial["out"]) / "attempts.log"
            failed.append({"point": trial["point"], "seed": trial["seed"],
                           "attempts": len(attempts.read_text().split()) if attempts.exists() else None,
                           "error": re.sub(r"\x1b\[[0-9;]*m", "", str(result.error))})
    entries = []
    for point in points:
        task = task_kwargs(point_hyperparams(algo, env_id, control_mode, point))
        seeds_done, runs, benchmark, seconds = [], [], [], []
        for seed in seeds:
            path = out / "runs" / tag(point) / f"seed{seed}" / "evaluation.npz"
            if path.exists() and not any(f["point"] == point and f["seed"] == seed for f in failed):
                with np.load(path) as data:
                    runs.append({k: data[k] for k in EPISODE_ARRAYS})
                    if task:
                        benchmark.append({k: data["benchmark_" + k] for k in EPISODE_ARRAYS})
                    seconds.append(float(data["train_seconds"]))
                seeds_done.append(seed)
        missing = [s for s in seeds if s not in seeds_done]
        note = f"failed seeds: {missing}" if missing else ""
        if not runs:
            continue
        own = ", ".join(f"{k}={v}" for k, v in task.items())
        name = f"{algo} {tag(point)}" + (f" ({own}: its own task)" if task else "")
        entries.append({**entry(name, "learned", algo, control_mode, condition, runs, seeds_done, note=note,
                                train_seconds=seconds, env_id=env_id), "hyperparameters": point, "task": task})
        if task:
            entries.append({**entry(f"{algo} {tag(point)} (the benchmark's task)", "learned", algo, control_mode,
                                    condition, benchmark, seeds_done, note=f"trained with {own}",
                                    train_seconds=seconds, env_id=env_id), "hyperparameters": point, "task": {}})
    (out / "sweep.json").write_text(json.dumps({"algo": algo, "env_id": env_id, "grid": grid, "seeds": seeds,
                                               "condition": condition, "policies": entries, "failed": failed},
                                               indent=2))
    (out / "sweep.md").write_text(markdown(entries, failed))
    return entries


def markdown(entries: list[dict], failed: list[dict]) -> str:
    text = condition_tables(entries)
    if failed:
        text += "\nFailed trials (after their retries):\n\n" + "\n".join(
            f"- {tag(f['point'])} seed {f['seed']} ({f['attempts']} attempts): "
            f"{f['error'].splitlines()[-1] if f['error'] else ''}"
            for f in failed) + "\n"
    return text


def publish_trials(algo: str, env_id: str, control_mode: str, seeds: list[int], grid: dict[str, list], out: Path,
                   dest: Path) -> list[Path]:
    """Copy every finished trial's run to ``dest/ENV_ID/MODE/NAME/seedN`` (``NAME_TAG`` for a grid
    point other than the default), where the comparison finds it."""
    published = []
    for point in grid_points(grid):
        name = algo if not point else f"{algo}_{tag(point)}"
        for seed in seeds:
            run = Path(out) / "runs" / tag(point) / f"seed{seed}"
            if is_finished(run):
                published.append(publish(run, run_dir(dest, env_id, control_mode, name, seed)))
                print("published:", published[-1])
    return published
