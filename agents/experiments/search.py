"""Hyperparameter search for the standard algorithms: Optuna's sampler through Ray Tune, with ASHA.

    scara-agents search ppo-c11-starts --trials 20 --max-steps 2000000 --out runs/search/ppo-c11-starts

One search per registered SB3 run (agents.experiments.registry): every trial trains the run's
YAML block with a point of `SPACES` (Optuna's TPE sampler proposes it, through Ray Tune's
``OptunaSearch``), and at every rung (``grace_steps``, twice that, ... up to ``max_steps``)
scores the model in training on ``episodes`` episodes of the *tuning set* of the condition the
run trains on (scara_gym.benchmark.protocol.tuning: never an evaluation seed). ASHA (Ray Tune's
``ASHAScheduler``, reduction factor 2) stops the trials in the lower half of a rung. The same
written rule picks the best trial for every algorithm: the highest `objective` at the
largest rung it reached, among the trials that reached the largest rung any trial reached.

Writes ``OUT/search.json`` (every trial: its point, its hyperparameters, every rung's figures,
how it ended), ``OUT/search.md`` (one row per trial) and the best trial's block twice: in the
project's format (``OUT/best.yml``, a YAML block for agents/algorithms/sb3/hyperparams) and in
RL Zoo's (``OUT/rl_zoo.yml``, for ``python -m rl_zoo3.train --algo ALGO --env ENV_ID
--gym-packages scara_gym --conf-file OUT/rl_zoo.yml``). Optuna and Ray are the ``sweep`` extra.

Resuming: ``OUT/search.json`` is rewritten at every rung and every trial's end, so it is the
search's state, small enough to keep with the results and carried to another machine. A search
run into an ``OUT`` that holds one resumes from it: the recorded trials are proposed again first
(Optuna's enqueued points), and a trial that had ended (completed, stopped by ASHA, or failed)
only reports its recorded rungs again, with no training, so that the sampler and ASHA see the
search's history; a trial that was still running (``"ended": "running"``) trains again, from its
snapshot where ``OUT/trials`` still holds one (its recorded rungs up to the snapshot reported
again), from the start otherwise. The record keeps the recorded rungs of the trials it replays.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from agents.algorithms.sb3.hyperparams import check_hyperparams
from agents.algorithms.sb3.policy import SB3Policy
from agents.algorithms.sb3.training import train as train_sb3
from agents.experiments.registry import spec
from agents.experiments.report import markdown_table
from agents.experiments.runs import hyperparams_of
from agents.files import write_atomic, write_json
from scara_gym.benchmark.episodes import BAND_NAMES, band_keys
from scara_gym.benchmark.protocol import ENV_ID, evaluate, tuning
from scara_gym.extras import require
from scara_gym.model.checks import UserError

TIME_WEIGHT = 0.01
"""the objective's weight on the IQM time to the C11 band [1/s]: a tie-breaker (at most 0.03)"""
TIME_LIMIT = 3.0

SPACES = {
    "ppo": {
        "gamma_complement": ("loguniform", 1e-3, 5e-2),   # gamma = 1 - this: horizons of 0.2 s to 10 s at 100 Hz
        "learning_rate": ("loguniform", 1e-5, 3e-3),
        "net_arch": ("choice", ["64x64", "128x128", "256x256"]),
        "norm_reward": ("choice", [True, False]),         # the reward's scale: normalized by its running std, or not
        "ent_coef": ("loguniform", 1e-8, 1e-2),
        "use_sde": ("choice", [False, True]),             # gSDE: exploration noise correlated over steps
        "log_std_init": ("uniform", -3.0, 0.0),           # the initial exploration scale (log std)
        "n_steps": ("choice", [64, 128, 256, 512]),
        "batch_size": ("choice", [256, 512, 1024, 2048]),
        "n_epochs": ("choice", [5, 10, 20]),
        "gae_lambda": ("choice", [0.9, 0.95, 0.98]),
        "clip_range": ("choice", [0.1, 0.2, 0.3]),
    },
    "sac": {
        "gamma_complement": ("loguniform", 1e-3, 5e-2),
        "learning_rate": ("loguniform", 1e-5, 3e-3),
        "net_arch": ("choice", ["64x64", "128x128", "256x256"]),
        "norm_reward": ("choice", [True, False]),
        "ent_coef": ("choice", ["auto", "auto_0.1", "auto_0.01", "auto_0.001"]),  # the temperature's start
        "use_sde": ("choice", [False, True]),
        "log_std_init": ("uniform", -3.0, 0.0),           # with gSDE only (SB3's SAC has no other)
        "batch_size": ("choice", [128, 256, 512]),
        "tau": ("choice", [0.005, 0.01, 0.02]),
        "learning_starts": ("choice", [1000, 5000, 10000]),
    },
    "tqc": {  # SAC's space and the quantiles each critic drops (TQC's control of overestimation)
        "gamma_complement": ("loguniform", 1e-3, 5e-2),
        "learning_rate": ("loguniform", 1e-5, 3e-3),
        "net_arch": ("choice", ["64x64", "128x128", "256x256"]),
        "norm_reward": ("choice", [True, False]),
        "ent_coef": ("choice", ["auto", "auto_0.1", "auto_0.01", "auto_0.001"]),
        "use_sde": ("choice", [False, True]),
        "log_std_init": ("uniform", -3.0, 0.0),
        "batch_size": ("choice", [128, 256, 512]),
        "tau": ("choice", [0.005, 0.01, 0.02]),
        "learning_starts": ("choice", [1000, 5000, 10000]),
        "top_quantiles_to_drop_per_net": ("choice", [0, 2, 5]),
    },
    "td3": {
        "gamma_complement": ("loguniform", 1e-3, 5e-2),
        "learning_rate": ("loguniform", 1e-5, 3e-3),
        "net_arch": ("choice", ["64x64", "128x128", "256x256"]),
        "norm_reward": ("choice", [True, False]),
        "noise_type": ("choice", ["normal", "ornstein-uhlenbeck"]),  # white or correlated exploration noise
        "noise_std": ("loguniform", 0.02, 0.5),
        "batch_size": ("choice", [128, 256, 512]),
        "tau": ("choice", [0.005, 0.01, 0.02]),
        "learning_starts": ("choice", [1000, 5000, 10000]),
    },
}
"""SB3 algorithm -> what a search varies: name -> ("loguniform" | "uniform", low, high) or
("choice", values). Names of the algorithm's YAML block, but: gamma_complement (1 - gamma, so that
long horizons are searched as finely as short ones), net_arch as "WxW", norm_reward (the block's
normalize.norm_reward)."""
GSDE = {"use_sde": ("choice", [True]), "sde_sample_freq": ("choice", [-1, 4, 16])}
"""what a run tagged "gsde" searches instead: gSDE kept on, how often its noise map is resampled
(-1: once per rollout) searched beside its initial log std"""


def space_of(registered) -> dict:
    """The space a registered run's search varies: its algorithm's, with GSDE for a "gsde" run."""
    space = dict(SPACES[registered.sb3_algorithm])
    if "gsde" in registered.tags:
        space.update(GSDE)
    return space


def decode(point: dict) -> dict:
    """A search point as entries of a hyperparameter block."""
    block = {k: v for k, v in point.items() if k not in ("gamma_complement", "net_arch", "norm_reward")}
    if "gamma_complement" in point:
        block["gamma"] = 1.0 - float(point["gamma_complement"])
    if "net_arch" in point:
        block["net_arch"] = [int(w) for w in str(point["net_arch"]).split("x")]
    return block


def trial_hyperparams(run: str, env_id: str, control_mode: str, point: dict, base: dict | None = None) -> dict:
    """The run's block (or ``base``) with a search point's values, checked."""
    hyper = dict(hyperparams_of(run, env_id, control_mode) if base is None else base)
    hyper.update(decode(point))
    if "norm_reward" in point:
        hyper["normalize"] = {**hyper.get("normalize", {"norm_obs": True}), "norm_reward": bool(point["norm_reward"])}
    return check_hyperparams(hyper)


def objective(result: dict) -> float:
    """The search's score of a rung's episodes: the mean over the bands (1e-3, 1e-2, 5e-2 rad) of
    the rate of episodes that reach the band without a collision, minus TIME_WEIGHT times the IQM
    time to the C11 band (the time limit where missed). In [-0.03, 1]; the looser bands give
    credit to a policy that moves to the target before it learns to settle there."""
    clean = ~np.asarray(result["collisions"], dtype=bool)
    rates = [float(np.mean(np.asarray(result[band_keys(b)[0]], dtype=bool) & clean)) for b in BAND_NAMES]
    times = np.sort(np.where(np.isnan(result["reach_time"]), TIME_LIMIT, result["reach_time"]))
    quarter = len(times) // 4
    return float(np.mean(rates)) - TIME_WEIGHT * float(np.mean(times[quarter:len(times) - quarter]))


def rungs(grace_steps: int, max_steps: int) -> list[int]:
    """The steps at which a trial is scored: grace_steps doubled until max_steps (which closes the list)."""
    out, steps = [], int(grace_steps)
    while steps < max_steps:
        out.append(steps)
        steps *= 2
    return [*out, int(max_steps)]


def rung_callback(at: list[int], condition, episodes: int, hyper: dict, control_mode: str, report,
                  recorded: list[dict] = ()):
    """An SB3 callback that scores the model in training at each of the steps ``at`` on the
    tuning set ``condition`` and hands {"steps", "objective", band figures} to ``report``. A trial
    resumed from its snapshot skips the rungs at or before the snapshot's steps: they were scored
    before the interruption, and a second score, of a later model, would stand in for them. Of
    those, the ones in ``recorded`` (a resumed search's record) are reported again as recorded."""
    require("stable_baselines3")
    from stable_baselines3.common.callbacks import BaseCallback

    class RungReport(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.pending = list(at)

        def _on_training_start(self) -> None:
            for row in recorded:
                if row["steps"] <= self.model.num_timesteps:
                    report(dict(row))
            self.pending = [steps for steps in self.pending if steps > self.model.num_timesteps]

        def _on_step(self) -> bool:
            if self.pending and self.num_timesteps >= self.pending[0]:
                self.pending.pop(0)
                result = evaluate(condition, lambda env: SB3Policy.of_model(env, self.model, hyper), control_mode,
                                  episodes, record=0)
                report(rung_figures(self.num_timesteps, result))
            return True

    return RungReport()


def rung_figures(steps: int, result: dict) -> dict:
    figures = {"steps": int(steps), "objective": objective(result),
               "collision_rate": float(np.mean(np.asarray(result["collisions"]) > 0))}
    for band in BAND_NAMES:
        figures[f"success_{band}"] = float(np.mean(result[band_keys(band)[0]]))
    return figures


def point_key(point: dict) -> str:
    """A search point as a string, the same for the same values: how a resumed search finds a
    recorded trial among the points Ray hands its trials, and the name of its training folder."""
    return json.dumps({k: point[k] for k in sorted(point)}, default=str)


def _trial(config: dict) -> None:
    """Ray Tune's trainable: one trial trained to max_steps, scored at every rung; or, for a
    trial the resumed record says had ended, its recorded rungs reported again."""
    require("ray")
    from ray import tune

    setup = config["setup"]
    recorded = setup["recorded"].get(point_key(config["point"]))
    if recorded is not None and recorded["ended"] != "running":
        for row in recorded["rungs"]:
            tune.report(dict(row))
        if recorded["ended"] == "error":
            raise RuntimeError(f"trial {recorded['trial']} ended in an error in the resumed search")
        return
    hyper = trial_hyperparams(setup["run"], setup["env_id"], setup["control_mode"], config["point"], setup["base"])
    folder = hashlib.sha256(point_key(config["point"]).encode()).hexdigest()[:16]
    run = spec(setup["run"])
    condition = tuning(run.trained_on or "c11-starts", setup["episodes"])
    callback = rung_callback(rungs(setup["grace_steps"], setup["max_steps"]), condition, setup["episodes"], hyper,
                             setup["control_mode"], tune.report, recorded["rungs"] if recorded else ())
    train_sb3(run.sb3_algorithm, Path(setup["out"]) / "trials" / folder, setup["env_id"], setup["control_mode"],
              setup["seed"], hyper, setup["max_steps"], resume=True, callbacks=[callback])


def _ray_space(space: dict) -> dict:
    from ray import tune

    kinds = {"loguniform": lambda lo, hi: tune.loguniform(lo, hi), "uniform": lambda lo, hi: tune.uniform(lo, hi)}
    return {name: tune.choice(args[0]) if kind == "choice" else kinds[kind](*args)
            for name, (kind, *args) in space.items()}


def _prior_record(path: Path, setup: dict, space: dict) -> dict | None:
    """The record a search resumes from, checked to be of the same search."""
    if not path.is_file():
        return None
    prior = json.loads(path.read_text())
    mine = {"run": setup["run"], "env_id": setup["env_id"], "control_mode": setup["control_mode"],
            "max_steps": setup["max_steps"], "rungs": rungs(setup["grace_steps"], setup["max_steps"]),
            "space": {k: list(v) for k, v in space.items()}}
    for name, value in mine.items():
        if prior.get(name) != value:
            raise UserError(f"{path} records another search ({name} {prior.get(name)!r}, this one {value!r}); "
                            f"give another --out, or the same settings to resume it")
    if not prior["condition"].endswith(f", {setup['episodes']} episodes a rung"):
        raise UserError(f"{path} records another search ({prior['condition']}); resume it with the same --episodes")
    return prior


def run_search(run: str, out: Path, trials: int = 20, max_steps: int = 1_000_000, grace_steps: int = 125_000,
               episodes: int = 20, env_id: str = ENV_ID, control_mode: str = "pd", seed: int = 0,
               num_cpus: int | None = None, base: dict | None = None) -> dict:
    """Search ``trials`` points of the registered SB3 run ``run``'s algorithm, resuming from
    OUT/search.json where it holds a record of the same search (module docstring); returns the
    record written to OUT/search.json. ``base``: the block the points change (default: the run's
    own; a test gives a tiny one)."""
    require("optuna")
    require("ray")
    import ray
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler
    from ray.tune.search.optuna import OptunaSearch

    registered = spec(run)
    if registered.trainer != "sb3" or registered.sb3_algorithm not in SPACES:
        raise UserError(f"search takes a registered SB3 run of {sorted(SPACES)}; {run} is not one")
    space = space_of(registered)
    out = Path(out).resolve()
    base = dict(hyperparams_of(run, env_id, control_mode) if base is None else base)
    base.setdefault("snapshot_freq", max(1, max_steps // 4))
    setup = {"run": run, "env_id": env_id, "control_mode": control_mode, "seed": seed, "episodes": episodes,
             "max_steps": max_steps, "grace_steps": grace_steps, "out": str(out), "base": base}
    trial_hyperparams(run, env_id, control_mode, {}, base)  # the base block checked before Ray starts
    prior = _prior_record(out / "search.json", setup, space)
    recorded = [] if prior is None else prior["trials"]
    if len(recorded) > trials:
        raise UserError(f"--trials must be at least the {len(recorded)} trials {out / 'search.json'} records, "
                        f"got {trials}")
    setup["recorded"] = {point_key(t["point"]): t for t in recorded}
    log = SearchLog(run, registered, setup, space, trials, out, recorded)
    if not ray.is_initialized():
        # a Ray instance of its own ("local"): two searches side by side must not share one, whose
        # CPU count the first one set
        ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
    attempt = 1 + sum(1 for _ in (out / "ray").glob("search-*")) if (out / "ray").is_dir() else 1
    scheduler = ASHAScheduler(time_attr="steps", max_t=max_steps, grace_period=grace_steps, reduction_factor=2)
    # the seed moved on by the trials recorded: the same seed would draw the recorded random points again
    searcher = OptunaSearch(seed=seed + len(recorded), points_to_evaluate=[{f"point/{k}": v for k, v in t["point"].items()}
                                                           for t in recorded] or None)
    tuner = tune.Tuner(tune.with_resources(_trial, {"cpu": 1}),
                       param_space={"point": _ray_space(space), "setup": setup},
                       tune_config=tune.TuneConfig(metric="objective", mode="max", search_alg=searcher,
                                                   scheduler=scheduler, num_samples=trials),
                       run_config=tune.RunConfig(name=f"search-{attempt}", storage_path=str(out / "ray"),
                                                 callbacks=[log.ray_callback()],
                                                 failure_config=tune.FailureConfig(max_failures=1)))
    tuner.fit()
    return log.write()


RUNG_KEYS = ("steps", "objective", "collision_rate", *(f"success_{band}" for band in BAND_NAMES))


class SearchLog:
    """The search's record as it goes: every trial in the order Ray started it, its rungs as they
    are reported, how it ended; OUT/search.json and OUT/search.md rewritten at each event, so
    that a search killed at any instant leaves the record of every rung it scored. Trials of a
    resumed record keep their recorded rungs."""

    def __init__(self, run: str, registered, setup: dict, space: dict, trials_asked: int, out: Path,
                 recorded: list[dict] = ()) -> None:
        self.run, self.registered, self.setup, self.space = run, registered, setup, space
        self.trials_asked, self.out = trials_asked, out
        self.recorded = {point_key(t["point"]): t for t in recorded}
        self.trials: dict[str, dict] = {}

    def started(self, trial_id: str, name: str, point: dict) -> None:
        if trial_id in self.trials:  # Ray retrying a failed trial (FailureConfig): it keeps the rungs it scored
            return
        prior = self.recorded.get(point_key(point))
        if prior is not None and prior["ended"] != "running":
            self.trials[trial_id] = {**prior, "replayed": True}
        else:
            self.trials[trial_id] = {"trial": prior["trial"] if prior else name, "point": point, "rungs": [],
                                     "steps": 0, "ended": "running"}
        self.write()

    def rung(self, trial_id: str, result: dict) -> None:
        entry = self.trials.get(trial_id)
        if entry is None or entry.get("replayed") or "objective" not in result:
            return
        row = {k: (None if isinstance(result.get(k), float) and math.isnan(result[k]) else result.get(k))
               for k in RUNG_KEYS}
        entry["rungs"] = [r for r in entry["rungs"] if r["steps"] < row["steps"]] + [row]
        entry["steps"] = row["steps"]
        self.write()

    def ended(self, trial_id: str, error: bool = False) -> None:
        entry = self.trials.get(trial_id)
        if entry is None or entry.get("replayed"):
            return
        entry["ended"] = "error" if error else (
            "completed" if entry["steps"] >= self.setup["max_steps"] else "stopped by ASHA")
        self.write()

    def write(self) -> dict:
        entries = [{k: v for k, v in t.items() if k != "replayed"} for t in self.trials.values()]
        record = search_record(self.run, self.registered, self.setup, self.space, entries, self.trials_asked)
        self.out.mkdir(parents=True, exist_ok=True)
        write_json(self.out / "search.json", record)
        write_atomic(self.out / "search.md", search_markdown(record))
        if record["best"] is not None:  # the rule's choice so far, in both formats
            best = record["trials"][record["best"]]["hyperparams"]
            env_id, mode = self.setup["env_id"], self.setup["control_mode"]
            write_yaml(self.out / "best.yml", {env_id: {f"{mode}-tuned": best}})
            write_yaml(self.out / "rl_zoo.yml", {env_id: rl_zoo_block(self.registered.sb3_algorithm, best, env_id)})
        return record

    def ray_callback(self):
        """The Ray Tune callback that feeds this log."""
        from ray.tune import Callback

        log = self

        class Feed(Callback):
            def on_trial_start(self, iteration, trials, trial, **info):
                log.started(trial.trial_id, Path(str(getattr(trial, "path", None) or trial.trial_id)).name,
                            trial.config["point"])

            def on_trial_result(self, iteration, trials, trial, result, **info):
                log.rung(trial.trial_id, result)

            def on_trial_complete(self, iteration, trials, trial, **info):
                log.ended(trial.trial_id)

            def on_trial_error(self, iteration, trials, trial, **info):
                log.ended(trial.trial_id, error=True)

        return Feed()


def search_record(run: str, registered, setup: dict, space: dict, entries: list[dict], trials_asked: int) -> dict:
    """Every trial the search started (``entries``: trial, point, rungs, steps, ended) and the
    written rule's choice among the ended ones. A search interrupted or killed is recorded with
    the trials it started, its "trials_run" below "trials_asked", and the trials it was still
    training marked "running"."""
    trials = [{"trial": t["trial"], "point": t["point"],
               "hyperparams": trial_hyperparams(run, setup["env_id"], setup["control_mode"], t["point"], setup["base"]),
               "rungs": t["rungs"], "steps": t["steps"], "ended": t["ended"]} for t in entries]
    ended = [t for t in trials if t["ended"] in ("completed", "stopped by ASHA")]
    reached = max((t["steps"] for t in ended), default=0)
    finalists = [i for i, t in enumerate(trials) if t in ended and t["steps"] == reached and t["rungs"]]
    best = max(finalists, key=lambda i: trials[i]["rungs"][-1]["objective"]) if finalists else None
    return {"run": run, "algorithm": registered.sb3_algorithm, "env_id": setup["env_id"],
            "control_mode": setup["control_mode"],
            "condition": f"{registered.trained_on or 'c11-starts'} (tuning seeds), {setup['episodes']} episodes a rung",
            "max_steps": setup["max_steps"], "rungs": rungs(setup["grace_steps"], setup["max_steps"]),
            "space": {k: list(v) for k, v in space.items()}, "objective": objective.__doc__.split("\n\n")[0],
            "rule": "the highest objective at the largest rung reached, among the trials that reached it",
            "sampler": "Optuna TPE through Ray Tune's OptunaSearch; ASHA (reduction factor 2) stops trials early",
            "trials_asked": trials_asked, "trials_run": sum(t["ended"] != "running" for t in trials),
            "best": best, "trials": trials}


def search_markdown(record: dict) -> str:
    rows = [{"trial": t["trial"], "ended": t["ended"], "steps": f"{t['steps']:,}",
             "objective": f"{t['rungs'][-1]['objective']:.3f}" if t["rungs"] else "-",
             "success 1e-3": f"{t['rungs'][-1]['success_1e-3']:.2f}" if t["rungs"] else "-",
             "point": json.dumps(t["point"], default=str)} for t in record["trials"]]
    best = "none" if record["best"] is None else record["trials"][record["best"]]["trial"]
    return (f"# Search: {record['run']} ({record['algorithm']}) on {record['env_id']}\n\n"
            f"{record['trials_run']} of {record['trials_asked']} trials run. "
            f"Scored on {record['condition']}; rungs {record['rungs']}. {record['sampler']}. "
            f"Best ({record['rule']}): {best}.\n\n"
            + markdown_table(["trial", "ended", "steps", "objective", "success 1e-3", "point"], rows))


def write_yaml(path: Path, value: dict) -> Path:
    require("yaml")
    import yaml

    return write_atomic(path, yaml.safe_dump(value, sort_keys=False))


def rl_zoo_block(algo: str, hyper: dict, env_id: str) -> dict:
    """A block in RL Zoo's hyperparameter format (its policy_kwargs as a dict(...) string, its
    normalize flag; the run's own bookkeeping left out). RL Zoo trains SB3's and sb3-contrib's
    algorithms only: a block trained here on sbx-rl's (``library: sbx``) trains there on SB3's
    implementation of the same algorithm, with the same settings."""
    skip = {"n_envs", "env_threads", "torch_threads", "eval_freq", "eval_episodes", "snapshot_freq",
            "checkpoint_freq", "normalize", "net_arch", "log_std_init", "noise_std", "noise_type", "env_kwargs",
            "library"}
    block = {"n_timesteps": hyper["n_timesteps"], "policy": "MlpPolicy", "n_envs": hyper.get("n_envs", 1)}
    block.update({k: v for k, v in hyper.items() if k not in skip and k != "n_timesteps"})
    normalize = hyper.get("normalize")
    if normalize:
        block["normalize"] = f"dict(norm_obs={normalize.get('norm_obs', True)}, norm_reward={normalize.get('norm_reward', True)})"
    policy = [f"net_arch={list(hyper.get('net_arch', [64, 64]))}"]
    if "log_std_init" in hyper and (algo == "ppo" or hyper.get("use_sde")):
        policy.append(f"log_std_init={hyper['log_std_init']}")
    block["policy_kwargs"] = f"dict({', '.join(policy)})"
    if algo == "td3" and hyper.get("noise_std"):
        block["noise_type"] = hyper.get("noise_type", "normal")
        block["noise_std"] = hyper["noise_std"]
    if hyper.get("env_kwargs"):
        block["env_kwargs"] = dict(hyper["env_kwargs"])
    return block
