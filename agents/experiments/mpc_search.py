"""The real-time MPC and the dec heuristic tuned under the learned baselines' written rule (issue 58 item 3).

    scara-agents tune-mpc --trials 20 --episodes 20 --out runs/search/mpc-rti
    scara-agents tune-heuristic --variant continue --trials 20 --episodes 20 --out runs/search/dec-continue

The learned algorithms are tuned by `agents.experiments.search`: at least 20 trials proposed by
Optuna's TPE sampler, each scored by `search.objective` (the clean success rate at each band,
less a small weight on the IQM time to the C11 band) on tuning episodes of c11-starts
(`scara_gym.benchmark.protocol.tuning`: never an evaluation seed), the best trial by that
objective. The MPC gets the same: the same sampler, trial count, tuning episodes, objective and
rule, over what shapes its plan (`SPACE`: the horizon, the wall margin and approach rate, the
height margin, the cost weights). It has no training steps, so a trial is scored once and
nothing is stopped early. The first trial is the published configuration (`MPCConfig()`'s
defaults), so that the record says where it stands among the others. The seed paper's ``dec``
heuristic gets the same over its one parameter, the trigger distance (`heuristic_controller`),
its first trial the distance the comparison uses (agents.experiments.tuning's bisection rule).

Each finished trial is appended to ``OUT/trials.jsonl`` at once (a crash loses at most the trial
under way), and a search run again into the same ``OUT`` goes on from those trials (they are
given back to the sampler). Then ``OUT/search.json`` (every trial, the choice, the rule),
``OUT/search.md`` and ``OUT/best.json`` (the chosen MPCConfig fields).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.experiments.report import markdown_table
from agents.experiments.search import objective, rung_figures
from agents.experiments.tuning import tune_heuristic
from agents.files import write_atomic, write_json
from agents.policies.heuristic import DecHeuristic
from agents.policies.mpc import MPCConfig
from agents.policies.mpc_rti import RTIConfig, RTIMPCPolicy
from scara_gym import DEFAULT_PARAMS, ScaraParams
from scara_gym.benchmark.protocol import ENV_ID, evaluate, tuning
from scara_gym.extras import require
from scara_gym.model.checks import UserError

CONDITION = "c11-starts"
"""the tuning episodes' condition: the learned baselines' search tunes on its draws too"""

SPACE = {
    "horizon": ("choice", [15, 20, 25, 30, 40]),
    "wall_margin": ("uniform", 1e-3, 8e-3),          # m, the tip's least distance from the wall below h_obs
    "approach_rate": ("loguniform", 5.0, 80.0),      # 1/s, how fast the tip may close on the wall
    "height_margin": ("uniform", 5e-4, 5e-3),        # m, q3 above h_obs in the steps above the wall
    "weight_scale_1": ("loguniform", 0.2, 5.0),      # each axis' error weight, times its default
    "weight_scale_2": ("loguniform", 0.2, 5.0),
    "weight_scale_3": ("loguniform", 0.2, 5.0),
    "voltage_weight": ("loguniform", 1e-8, 1e-4),
}
"""what the search varies: name -> ("choice", values) or ("uniform" | "loguniform", low, high).
MPCConfig's fields, but weight_scale_i: the i-th cost weight over its default (1 / v_max_i^2)."""

DEFAULT_POINT = {"horizon": MPCConfig.horizon, "wall_margin": MPCConfig.wall_margin,
                 "approach_rate": MPCConfig.approach_rate, "height_margin": MPCConfig.height_margin,
                 "weight_scale_1": 1.0, "weight_scale_2": 1.0, "weight_scale_3": 1.0,
                 "voltage_weight": MPCConfig.voltage_weight}
"""the published configuration as a point of SPACE: the search's first trial"""


def default_weights(params: ScaraParams | None = None) -> np.ndarray:
    """MPCConfig.weights' default as MPCPolicy computes it: 1 / v_max_i^2, v_max_i = Umax_i / (kT_i u_i)
    the speed the back-EMF allows at Umax (each joint's error in seconds at the axis' top speed).
    Kept here, not in agents.policies.mpc: that module's source keys the MPC's cached evaluations."""
    params = DEFAULT_PARAMS if params is None else params
    top_speed = params.voltage_limits / np.array([a.torque_constant * a.gear_ratio for a in params.axes])
    return 1.0 / top_speed**2


def mpc_config(point: dict) -> MPCConfig:
    """The MPC's problem at a point of SPACE (its other fields at their defaults)."""
    scales = np.array([point[f"weight_scale_{i}"] for i in (1, 2, 3)], dtype=float)
    fields = {k: v for k, v in point.items() if not k.startswith("weight_scale_")}
    return MPCConfig(**{**fields, "horizon": int(fields["horizon"])}, weights=tuple(scales * default_weights()))


def score_point(point: dict, episodes: int, mode: str = "voltage") -> dict:
    """One trial: the real-time MPC at ``point`` on ``episodes`` tuning episodes of CONDITION;
    {"objective", "collision_rate", "success_BAND"..., "step_time_median", "step_time_p95"}."""
    config = RTIConfig(mpc=mpc_config(point))
    return score_policy(lambda env: RTIMPCPolicy(env, config), episodes, mode)


def score_policy(factory, episodes: int, mode: str) -> dict:
    """A policy (``factory(env)``) on ``episodes`` tuning episodes of CONDITION, scored by the
    search's objective, with its time per step."""
    condition = tuning(CONDITION, episodes)
    step_times: list[float] = []

    def timed_policy(env):
        policy = factory(env)

        def act(obs):
            started = time.perf_counter()
            action = policy(obs)
            step_times.append(time.perf_counter() - started)
            return action

        act.reset = policy.reset
        return act

    result = evaluate(condition, timed_policy, mode, episodes, record=0)
    figures = rung_figures(0, result)
    figures.pop("steps")
    return {**figures, "step_time_median": float(np.median(step_times)),
            "step_time_p95": float(np.percentile(step_times, 95))}


def _read_trials(path: Path) -> list[dict]:
    """The finished trials of an earlier run of the search (a torn last line, from a crash, left out)."""
    if not path.exists():
        return []
    trials = []
    for line in path.read_text().splitlines():
        try:
            trials.append(json.loads(line))
        except ValueError:
            break
    return trials


@dataclass(frozen=True)
class Controller:
    """What a controller's search varies and how a point is scored and written."""

    name: str
    space: dict
    default_point: dict
    """the published configuration: the first trial"""
    score: Callable[[dict, int, str], dict]
    best: Callable[[dict], dict]
    """the chosen point as OUT/best.json's content"""


def mpc_controller(score=score_point, space: dict | None = None) -> Controller:
    space = SPACE if space is None else space
    return Controller("mpc-rti", space, {k: v for k, v in DEFAULT_POINT.items() if k in space}, score,
                      lambda point: {"mpc": {k: (list(v) if isinstance(v, tuple) else v)
                                             for k, v in vars(mpc_config(point)).items() if k in MPC_FIELDS}})


HEURISTIC_SPACE = {"distance": ("uniform", 0.02, 0.2)}
"""the heuristic's search: its trigger distance [m] (the bisection's published ones are 0.06-0.08 m)"""


def heuristic_controller(variant: str, score=None, published: float | None = None) -> Controller:
    """The dec heuristic's search (variant "continue" or "restart"), "pd" mode; its first trial
    the published distance (``published``, else agents.experiments.tuning's rule computes it)."""
    def score_distance(point: dict, episodes: int, mode: str) -> dict:
        return score_policy(lambda env: DecHeuristic(env, variant, critical_distance=point["distance"]), episodes,
                            mode)

    distance = tune_heuristic(variant)["distance"] if published is None else published
    return Controller(f"dec-{variant}", HEURISTIC_SPACE, {"distance": float(distance)},
                      score_distance if score is None else score,
                      lambda point: {f"dec-{variant}": {"distance": point["distance"]}})


def tune_mpc(out: Path, trials: int = 20, episodes: int = 20, mode: str = "voltage", seed: int = 0,
             space: dict | None = None, score=score_point) -> dict:
    """The real-time MPC's search (module docstring); returns the record written to OUT/search.json."""
    return tune_controller(mpc_controller(score, space), out, trials, episodes, mode, seed)


def tune_controller(controller: Controller, out: Path, trials: int = 20, episodes: int = 20, mode: str = "voltage",
                    seed: int = 0) -> dict:
    """The search of the module docstring for ``controller``; returns the record written to OUT/search.json."""
    require("optuna")
    import optuna

    if trials < 1 or episodes < 1:
        raise UserError(f"trials and episodes must be at least 1, got {trials} and {episodes}")
    space, score = controller.space, controller.score
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "trials.jsonl"
    done = _read_trials(log)
    if log.exists():  # a line torn by a crash is dropped before new trials are appended after it
        write_atomic(log, "".join(json.dumps(t) + "\n" for t in done))
    setup = {"episodes": episodes, "mode": mode, "seed": seed, "env_id": ENV_ID, "space": sorted(space)}
    if controller.name != "mpc-rti":  # the MPC's records were written before the setup named the policy
        setup["policy"] = controller.name
    if done and done[0].get("setup") != setup:
        raise UserError(f"{out} holds a search of another setup ({done[0].get('setup')}); give another --out")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="maximize", sampler=optuna.samplers.TPESampler(seed=seed))
    distributions = {name: (optuna.distributions.CategoricalDistribution(args[0]) if kind == "choice" else
                            optuna.distributions.FloatDistribution(args[0], args[1], log=kind == "loguniform"))
                     for name, (kind, *args) in space.items()}
    for t in done:
        study.add_trial(optuna.trial.create_trial(params=t["point"], distributions=distributions,
                                                  value=t["figures"]["objective"]))
    if not done:
        study.enqueue_trial(dict(controller.default_point))
    while len(done) < trials:
        trial = study.ask(distributions)
        point = dict(trial.params)
        started = time.perf_counter()
        figures = score(point, episodes, mode)
        study.tell(trial, figures["objective"])
        entry = {"setup": setup, "trial": len(done), "point": point, "figures": figures,
                 "seconds": time.perf_counter() - started}
        with log.open("a") as f:  # one line per finished trial, flushed before the next starts
            f.write(json.dumps(entry) + "\n")
            f.flush()
        done.append(entry)
        print(f"trial {entry['trial']}: objective {figures['objective']:.4f}, success 1e-3 "
              f"{figures['success_1e-3']:.2f}, collisions {figures['collision_rate']:.2f} ({entry['seconds']:.0f} s)")
    best = max(range(len(done)), key=lambda i: done[i]["figures"]["objective"])
    record = {"policy": controller.name, "env_id": ENV_ID, "control_mode": mode,
              "condition": f"{CONDITION} (tuning seeds), {episodes} episodes a trial",
              "space": {k: list(v) for k, v in space.items()}, "objective": objective.__doc__.split("\n\n")[0],
              "rule": "the highest objective (the learned baselines' search's rule; one score per trial, no rungs)",
              "sampler": f"Optuna TPE (seed {seed}); the first trial is the published configuration",
              "trials_asked": trials, "trials_run": len(done), "best": best, "trials": done}
    write_json(out / "search.json", record)
    write_atomic(out / "search.md", mpc_search_markdown(record))
    write_json(out / "best.json", controller.best(done[best]["point"]))
    return record


MPC_FIELDS = ("horizon", "wall_margin", "approach_rate", "height_margin", "weights", "voltage_weight")
"""the MPCConfig fields a search point sets"""


def mpc_search_markdown(record: dict) -> str:
    rows = [{"trial": t["trial"], "objective": f"{t['figures']['objective']:.4f}",
             "success 1e-3": f"{t['figures']['success_1e-3']:.2f}",
             "collisions": f"{t['figures']['collision_rate']:.2f}",
             "step time median / p95 (ms)": f"{1e3 * t['figures']['step_time_median']:.1f} / "
                                            f"{1e3 * t['figures']['step_time_p95']:.1f}",
             "point": json.dumps({k: round(v, 6) if isinstance(v, float) else v for k, v in t["point"].items()})}
            for t in record["trials"]]
    return (f"# Search: {record['policy']} on {record['env_id']} ({record['control_mode']} mode)\n\n"
            f"{record['trials_run']} of {record['trials_asked']} trials run. Scored on {record['condition']}. "
            f"{record['sampler']}. Best ({record['rule']}): trial {record['best']}.\n\n"
            + markdown_table(["trial", "objective", "success 1e-3", "collisions", "step time median / p95 (ms)",
                              "point"], rows))
