"""``python -m agents.compare``: learned vs classical vs optimal, over the same evaluation seeds.

    python -m agents.compare --runs runs/baselines --episodes 100 --out docs/results

Every policy runs the same episodes (seeds 1000..) of ``Scara-C11-v1`` in every condition:

- policies: ``pd`` (the classical baseline), the seed's ``dec`` heuristic in both variants
  at its smallest safe trigger distance (bisected in each condition) and with a 20 % margin,
  ``optimal`` (agents.optimal, "voltage" mode; skipped with randomized targets, which would
  need one solve per target), and every learned run under ``--runs ENV_ID/MODE/ALGO/seedN``
  (agents.baselines), one entry per algorithm over its seeds;
- conditions (``CONDITIONS``): the C11 target with the wall, randomized targets, and the C11
  target under four parameter shifts;
- behind agents.shield's model-predictive shield (its model: the nominal parameters): PD and
  the learned algorithms named by ``--shield`` (default ``SHIELDED``), as entries "... + shield".
  Runs trained behind the shield (agents.torch_ppo's ``shield``) always act behind it.

Learned algorithms are aggregated with rliable over their training seeds: the interquartile
mean (IQM) of the time to target and its 95 % stratified-bootstrap confidence interval
(the evaluation episodes are rliable's tasks, the seeds its runs; an episode that does not
reach the target counts with the 3 s time limit), and the probability that the algorithm
is faster than the heuristic. Every seed's own figures are in ``per_seed``. Writes
``comparison.json`` (``{"policies": [...]}``, one entry per policy and condition),
``comparison.md`` and the figures under ``--out``.

With ``--cache DIR`` a learned run's evaluation in a condition is kept in DIR, keyed by its
model's bytes, the condition, the episodes and the package version, so that a comparison
after new runs evaluates only those (clear DIR after changing the physics or a policy's code
without a version change; the classical policies always run).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import pickle
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from agents.baselines import is_finished
from agents.policies import DecHeuristic, PDPolicy, run_episode, smallest_safe_distance
from scara_gym import DEFAULT_PARAMS, TRAINING_ENV_ID, __version__

TIME_LIMIT = 3.0  # s, the registered episode limit: the time of an episode that never arrives
_axes = DEFAULT_PARAMS.axes


@dataclass(frozen=True)
class Condition:
    """One evaluation condition: environment arguments and parameter overrides."""

    name: str
    description: str
    randomize_target: bool = False
    params: dict = field(default_factory=dict)


CONDITIONS = {c.name: c for c in (
    Condition("c11", "the C11 target (2, 2, 0.3) with the wall"),
    Condition("random-targets", "targets drawn per episode beyond the wall", randomize_target=True),
    Condition("load-x2", "load mass x2 (m3L 0.5 -> 1.0 kg)", params={"arm.load_mass": 2 * DEFAULT_PARAMS.arm.load_mass}),
    Condition("wall-closer", "wall 2 cm closer to the arm's start (x_obs 0.35 -> 0.37 m)",
              params={"obstacle.x_position": DEFAULT_PARAMS.obstacle.x_position + 0.02}),
    Condition("current-limits-15", "current limits -15 %",
              params={f"axes.{i}.current_limit": 0.85 * a.current_limit for i, a in enumerate(_axes)}),
    Condition("resistance+20", "motor resistances +20 %",
              params={f"axes.{i}.resistance": 1.2 * a.resistance for i, a in enumerate(_axes)}),
)}


TASK_KWARGS = ("goal_tolerance",)
"""environment arguments that define the task a run trains for (not its reward or its physics):
an evaluation that uses a run's own reports them beside the benchmark's"""


def make_env(condition: Condition, control_mode: str, env_id: str = TRAINING_ENV_ID, **task):
    """The condition's environment; task: TASK_KWARGS to set (default: the benchmark's own)."""
    import gymnasium as gym

    import scara_gym  # noqa: F401

    unknown = sorted(set(task) - set(TASK_KWARGS))
    if unknown:
        raise ValueError(f"task arguments must be among {TASK_KWARGS}, got {unknown}")
    return gym.make(env_id, control_mode=control_mode, randomize_target=condition.randomize_target,
                    params=DEFAULT_PARAMS.replace(condition.params), **task)


SUMMARY_KEYS = ("success", "collisions", "reach_time", "energy", "steps")


def _same_episode(a: dict, b: dict) -> bool:
    return all(a[key] == b[key] or (key == "reach_time" and np.isnan(a[key]) and np.isnan(b[key]))
               for key in SUMMARY_KEYS)


def episodes_of(env, policy, episodes: int, seed: int, identical: bool = False) -> dict:
    """Per-episode arrays of one policy (and the first episode's trace). identical: the
    condition draws nothing per episode (fixed start, target and parameters) and the policy
    is deterministic, so that every episode is the first one: then the first two are run and,
    where they are the same, the first stands for all (else every episode runs)."""
    results = [run_episode(env, policy, seed=seed + i, record=i == 0) for i in range(min(episodes, 2))]
    if identical and episodes > 2 and _same_episode(*results):
        results += [results[0]] * (episodes - 2)
    else:
        results += [run_episode(env, policy, seed=seed + i) for i in range(len(results), episodes)]
    reach = np.array([r["reach_time"] if r["success"] else np.nan for r in results])
    return {"success": np.array([r["success"] for r in results]),
            "collisions": np.array([r["collisions"] > 0 for r in results]),
            "reach_time": reach, "energy": np.array([r["energy"] for r in results]),
            "trace": results[0]["trace"]}


def time_scores(runs: list[dict]) -> np.ndarray:
    """(runs, episodes) times to target, the time limit where not reached (lower is better)."""
    return np.array([np.where(np.isnan(r["reach_time"]), TIME_LIMIT, r["reach_time"]) for r in runs])


def _interval_estimates(scores: dict, function, reps: int, seed: int):
    """rliable's point estimates and 95 % stratified-bootstrap intervals."""
    from rliable import library as rly

    with warnings.catch_warnings():  # rliable passes arch a RandomState, which arch deprecates
        warnings.simplefilter("ignore", FutureWarning)
        return rly.get_interval_estimates(scores, function, reps=reps, random_state=np.random.RandomState(seed))


def _save(fig, path: Path, written: list[Path]) -> None:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)


def iqm_with_ci(scores: np.ndarray, reps: int = 2000, seed: int = 0) -> tuple[float, list[float]]:
    """rliable's IQM over runs x tasks and its 95 % stratified-bootstrap interval."""
    from rliable import metrics

    point, interval = _interval_estimates({"x": scores}, lambda s: np.array([metrics.aggregate_iqm(s)]), reps, seed)
    return float(point["x"][0]), [float(interval["x"][0, 0]), float(interval["x"][1, 0])]


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> float:
    """rliable.metrics.probability_of_improvement, vectorized over the tasks: per task the
    Mann-Whitney U statistic over all (run of x, run of y) pairs, #(x > y) + #(x = y) / 2,
    divided by the pairs, then averaged over the tasks (rliable's loop calls scipy once per
    task and bootstrap sample: minutes per algorithm with 100 tasks and 2,000 samples)."""
    pairs_x, pairs_y = x[:, None, :], y[None, :, :]
    return float(np.mean((pairs_x > pairs_y).mean(axis=(0, 1)) + 0.5 * (pairs_x == pairs_y).mean(axis=(0, 1))))


def probability_faster(learned: np.ndarray, reference: np.ndarray, reps: int = 2000,
                       seed: int = 0) -> tuple[float, list[float]]:
    """rliable's probability of improvement P(learned faster than reference), with its 95 % CI."""
    point, interval = _interval_estimates(
        {"x": [-learned, -reference]}, lambda x, y: np.array([probability_of_improvement(x, y)]), reps, seed)
    return float(point["x"][0]), [float(interval["x"][0, 0]), float(interval["x"][1, 0])]


def training_seconds(config: dict) -> float | None:
    """A run's training time from its config.json; a fine-tuned run's counts the run it started
    from (agents.baselines.FINE_TUNES)."""
    seconds = config.get("train_seconds")
    return None if seconds is None else seconds + config.get("base_train_seconds", 0.0)


def entry(name: str, kind: str, algorithm: str | None, mode: str, condition: str, runs: list[dict],
          seeds: list[int] | None, note: str = "", train_seconds: list[float] | None = None) -> dict:
    success = np.concatenate([r["success"] for r in runs])
    time_iqm, time_ci = iqm_with_ci(time_scores(runs))
    row = {"name": name, "kind": kind, "algorithm": algorithm, "control_mode": mode, "condition": condition,
           "seeds": seeds, "episodes": int(len(runs[0]["success"])),
           "success_rate": float(success.mean()),
           "collision_rate": float(np.concatenate([r["collisions"] for r in runs]).mean()),
           "time_iqm": time_iqm, "time_ci": time_ci,
           "energy_mean": float(np.mean([r["energy"].mean() for r in runs])), "note": note}
    if seeds is not None:
        row["per_seed"] = [{"seed": s, "success_rate": float(r["success"].mean()),
                            "collision_rate": float(r["collisions"].mean()),
                            "time_mean": float(np.nanmean(r["reach_time"])) if r["success"].any() else None,
                            "energy_mean": float(r["energy"].mean())} for s, r in zip(seeds, runs)]
        for item, seconds in zip(row["per_seed"], train_seconds or []):
            item["train_seconds"] = seconds
    return row


def learned_runs(runs_root: Path, env_id: str = TRAINING_ENV_ID) -> dict[tuple[str, str], list[Path]]:
    """(algorithm, control mode) -> finished run folders, seed order."""
    groups: dict[tuple[str, str], list[Path]] = {}
    for config in sorted(Path(runs_root).glob(f"{env_id}/*/*/seed*/config.json")):
        run = config.parent
        if is_finished(run):  # SB3's model.zip, or agents.torch_ppo's model.pt
            groups.setdefault((run.parent.name, run.parent.parent.name), []).append(run)
    for key in groups:
        groups[key].sort(key=lambda p: int(p.name.removeprefix("seed")))
    return groups


POLICY_FILES = ("config.json", "model.zip", "model.pt", "vecnormalize.pkl")
"""the files of a finished run that its policy's actions depend on"""


def evaluation_key(run_dir: Path, condition: Condition, mode: str, episodes: int, seed: int,
                   shield: bool = False) -> str:
    """What a learned run's evaluation depends on: its policy's files, the condition (and the
    environment it builds), the episodes, the package version and whether a shield acts."""
    digest = hashlib.sha256()
    for name in POLICY_FILES:
        if (Path(run_dir) / name).exists():
            digest.update(name.encode() + (Path(run_dir) / name).read_bytes())
    if shield:
        digest.update(b"agents.shield.Shield, defaults")
    digest.update(json.dumps([dataclasses.asdict(condition), mode, episodes, seed, TRAINING_ENV_ID, __version__],
                             sort_keys=True).encode())
    return digest.hexdigest()[:32]


def learned_episodes(env, run_dir: Path, condition: Condition, mode: str, episodes: int, seed: int,
                     identical: bool, cache: Path | None = None, shield: bool = False) -> dict:
    """episodes_of a finished run's policy (behind agents.shield's Shield with ``shield``),
    from ``cache`` where it holds them (else kept there)."""
    if cache is None:
        return episodes_of(env, learned_policy(env, run_dir, shield), episodes, seed, identical)
    path = Path(cache) / f"{evaluation_key(run_dir, condition, mode, episodes, seed, shield)}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    result = episodes_of(env, learned_policy(env, run_dir, shield), episodes, seed, identical)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".partial")
    partial.write_bytes(pickle.dumps(result))
    partial.replace(path)  # a comparison stopped while writing leaves no half entry
    return result


def learned_policy(env, run_dir: Path, shield: bool = False):
    """The policy of a finished run: SB3's (model.zip) or agents.torch_ppo's (model.pt); with
    ``shield``, behind agents.shield's Shield (its model has the nominal parameters)."""
    if (run_dir / "model.zip").exists():
        from agents.training import SB3Policy
        policy = SB3Policy(env, run_dir)
    else:
        from agents.torch_ppo import TorchPPOPolicy
        policy = TorchPPOPolicy(env, run_dir)
    if shield:
        from agents.shield import Shield
        return Shield(env, policy)
    return policy


SHIELDED = ("torch-ppo-residual-random-replay",)
"""learned algorithms the comparison also runs behind agents.shield's Shield (``--shield``)"""
SHIELD_SUFFIX = " + shield"


def compare(runs_root: Path | None = Path("runs/baselines"), conditions: list[str] = ("c11",),
            episodes: int = 100, seed: int = 1000, include_optimal: bool = True, verbose: bool = True,
            bisection_tolerance: float = 5e-4, cache: Path | None = None, shielded: tuple[str, ...] = SHIELDED):
    """Every policy in every condition: (entries, traces per condition). Every policy here is
    deterministic, so in a condition without draws (fixed target and parameters) its episodes
    are one episode repeated: episodes_of runs two and checks that. cache: a folder that keeps
    learned runs' evaluations (learned_episodes). shielded: learned algorithms that also run
    behind agents.shield's Shield (entries "ALGO + shield"), as PD does ("pd + shield") where
    any is given."""
    from agents.optimal import OptimalPolicy
    from agents.shield import Shield

    entries, traces = [], {}
    groups = learned_runs(runs_root) if runs_root is not None else {}
    for name in conditions:
        condition = CONDITIONS[name]
        traces[name] = {}
        started = time.perf_counter()

        def add(label, kind, algorithm, mode, runs, seeds, note="", train_seconds=None):
            entries.append(entry(label, kind, algorithm, mode, name, runs, seeds, note, train_seconds))
            traces[name][label] = runs[0]["trace"]
            if verbose:
                e = entries[-1]
                print(f"[{name}] {label}: success {_rate(e['success_rate'])}, collisions {_rate(e['collision_rate'])}, "
                      f"time IQM {e['time_iqm']:.4f} s {e['time_ci']}, energy {e['energy_mean']:.1f} J", flush=True)

        reference = None  # the heuristic learned agents are compared with: dec-continue, smallest safe distance
        env = make_env(condition, "pd")
        same = not condition.randomize_target  # every episode alike (see episodes_of)
        add("pd", "pd", None, "pd", [episodes_of(env, PDPolicy(env), episodes, seed, same)], None)
        if shielded:
            add("pd" + SHIELD_SUFFIX, "pd", None, "pd", [episodes_of(env, Shield(env, PDPolicy(env)), episodes, seed, same)],
                None, note="agents.shield's Shield with the nominal parameters")
        for variant in ("continue", "restart"):
            try:  # the bisection runs episode 0 of the evaluation seeds
                smallest, _ = smallest_safe_distance(variant, tolerance=bisection_tolerance, env=env, seed=seed)
            except RuntimeError:  # no trigger distance clears the wall in this condition
                continue
            for label, distance in (("smallest safe", smallest), ("+20 %", 1.2 * smallest)):
                policy = DecHeuristic(env, variant, critical_distance=distance)
                runs = [episodes_of(env, policy, episodes, seed, same)]
                reference = reference or runs
                add(f"dec-{variant}, {label} (d={distance:.4f} m)", "heuristic", None, "pd", runs, None,
                    note=f"trigger distance {distance:.4f} m (smallest safe in this condition: {smallest:.4f} m)")
        if include_optimal and not condition.randomize_target:
            env = make_env(condition, "voltage")
            try:  # the shipped solutions only: a solve takes minutes to hours
                runs = [episodes_of(env, OptimalPolicy(env, solve_missing=False), episodes, seed, same)]
            except LookupError:
                if verbose:
                    print(f"[{name}] optimal: no shipped solution (python -m agents.optimal --condition {name} "
                          f"--write agents/optimal_solutions/{name}.json)", flush=True)
            else:
                add("optimal", "optimal", None, "voltage", runs, None,
                    note="minimum-time voltages held over the control steps (agents.optimal)")
        for (algorithm, mode), run_dirs in sorted(groups.items()):
            env = make_env(condition, mode)
            configs = [json.loads((d / "config.json").read_text()) for d in run_dirs]
            for shield in (False, True) if algorithm in shielded else (False,):
                runs = [learned_episodes(env, d, condition, mode, episodes, seed, same, cache, shield)
                        for d in run_dirs]
                label = algorithm + (SHIELD_SUFFIX if shield else "")
                add(label, "learned", label, mode, runs, [c["seed"] for c in configs],
                    note="agents.shield's Shield with the nominal parameters" if shield else "",
                    train_seconds=[training_seconds(c) for c in configs])
                if reference is not None:
                    p, ci = probability_faster(time_scores(runs), time_scores(reference))
                    entries[-1]["probability_faster_than_heuristic"] = p
                    entries[-1]["probability_faster_ci"] = ci
        if verbose:
            print(f"[{name}] {time.perf_counter() - started:.0f} s", flush=True)
    return entries, traces


def _compare_condition(arguments: tuple) -> tuple[list[dict], dict]:
    runs_root, condition, kwargs = arguments
    return compare(runs_root, [condition], **kwargs)


def compare_in_parallel(runs_root: Path | None, conditions: list[str], jobs: int, **kwargs):
    """compare() with the conditions spread over ``jobs`` processes: the same entries, in the
    same order (each condition is evaluated on its own)."""
    if jobs <= 1 or len(conditions) <= 1:
        return compare(runs_root, conditions, **kwargs)
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(min(jobs, len(conditions))) as pool:
        parts = list(pool.map(_compare_condition, [(runs_root, name, kwargs) for name in conditions]))
    return [e for entries, _ in parts for e in entries], {k: v for _, traces in parts for k, v in traces.items()}


MINIMUM_TIME_BOUND = 1.2217  # [s] the spec's continuous-time bound on the C11 target
SHIFTS = ("load-x2", "wall-closer", "current-limits-15", "resistance+20")
DOMAIN_RANDOMIZED_SUFFIX = "-dr"  # agents.baselines' algorithms trained with physics and wall drawn per episode
TRAINING_BUDGET = 1800.0  # [s] per training run on 2 CPU cores


def _rate(rate: float) -> str:
    """A success or collision rate with two decimals, or three where two would round it to
    another value (0.998 is not 1.00: 1 collision in 500 episodes must show)."""
    text = f"{rate:.2f}"
    return text if float(text) == rate else f"{rate:.3f}"


def _find(entries, condition, kind=None, algorithm=None):
    return [e for e in entries if e["condition"] == condition and (kind is None or e["kind"] == kind)
            and (algorithm is None or e["algorithm"] == algorithm)]


def _clean_every_seed(e: dict, success: float = 1.0) -> bool:
    return all(s["success_rate"] >= success and s["collision_rate"] == 0.0 for s in e.get("per_seed", []))


def _best_learned(learned: list[dict], success: float) -> dict | None:
    """The fastest algorithm (IQM) among those clean on every seed, else the fastest."""
    if not learned:
        return None
    clean = [e for e in learned if _clean_every_seed(e, success)]
    return min(clean or learned, key=lambda e: e["time_iqm"])


def target_checks(entries: list[dict]) -> list[dict]:
    """The issue's targets: {"target", "met" (True/False/None: not evaluated), "reached"}."""
    checks = []

    def check(target, met, reached):
        checks.append({"target": target, "met": met, "reached": reached})

    def summary(e):
        return (f"{e['name']}: success {_rate(e['success_rate'])}, collisions {_rate(e['collision_rate'])}, "
                f"time IQM {e['time_iqm']:.4f} s, energy {e['energy_mean']:.1f} J")

    optimal = _find(entries, "c11", "optimal")
    text = "optimal reference on the C11 target: success, no collision, time within 2 % of 1.2217 s"
    if optimal:
        e = optimal[0]
        check(text, e["success_rate"] == 1.0 and e["collision_rate"] == 0.0
              and e["time_iqm"] <= 1.02 * MINIMUM_TIME_BOUND,
              summary(e) + f" ({100 * (e['time_iqm'] / MINIMUM_TIME_BOUND - 1):+.2f} % over the bound)")
    else:
        check(text, None, "not evaluated")
    heuristic = _find(entries, "c11", "heuristic")
    best = _best_learned(_find(entries, "c11", "learned"), 1.0)
    text = ("best learned on the C11 target: 100 % success and 0 collisions on every seed, IQM time <= 1.35 s, "
            "energy <= 2x the heuristic's")
    if best and heuristic:
        check(text, _clean_every_seed(best) and best["time_iqm"] <= 1.35
              and best["energy_mean"] <= 2 * heuristic[0]["energy_mean"],
              summary(best) + f"; heuristic ({heuristic[0]['name']}) {heuristic[0]['energy_mean']:.1f} J")
    else:
        check(text, None, "not evaluated")
    heuristic_random = _find(entries, "random-targets", "heuristic")
    best = _best_learned(_find(entries, "random-targets", "learned"), 0.99)
    text = "randomized targets: >= 99 % success, 0 collisions, IQM time below the heuristic's"
    if best and heuristic_random:
        check(text, best["success_rate"] >= 0.99 and best["collision_rate"] == 0.0
              and best["time_iqm"] < heuristic_random[0]["time_iqm"],
              summary(best) + f"; heuristic {heuristic_random[0]['time_iqm']:.4f} s")
    else:
        check(text, None, "not evaluated")
    robust = {}  # domain-randomized algorithm -> its entries in the four shifts
    for e in entries:
        if e["kind"] == "learned" and e["condition"] in SHIFTS and e["algorithm"].endswith(DOMAIN_RANDOMIZED_SUFFIX):
            robust.setdefault(e["algorithm"], []).append(e)
    robust = {a: rows for a, rows in robust.items() if len(rows) == len(SHIFTS)}
    text = "domain-randomized agent under the four shifts: >= 95 % success, 0 collisions in each"

    def robust_enough(rows):
        return all(e["success_rate"] >= 0.95 and e["collision_rate"] == 0.0 for e in rows)

    if robust:
        best = max(robust, key=lambda a: (robust_enough(robust[a]),
                                          min(e["success_rate"] - e["collision_rate"] for e in robust[a])))
        check(text, robust_enough(robust[best]), f"{best}: " + "; ".join(
            f"{e['condition']} {_rate(e['success_rate'])} / {_rate(e['collision_rate'])}" for e in robust[best]))
    else:
        check(text, None, f"no domain-randomized agent (*{DOMAIN_RANDOMIZED_SUFFIX}) evaluated in all four shifts")
    text = "fast and frugal: a learned algorithm faster (IQM) than the heuristic on the C11 target with at most its energy"
    learned = _find(entries, "c11", "learned")
    if learned and heuristic:
        h = heuristic[0]
        frugal = [e for e in learned if e["time_iqm"] < h["time_iqm"] and e["energy_mean"] <= h["energy_mean"]]
        closest = min(learned, key=lambda e: e["energy_mean"] / h["energy_mean"] + e["time_iqm"] / h["time_iqm"])
        check(text, bool(frugal), summary(frugal[0] if frugal else closest)
              + f"; heuristic {h['time_iqm']:.4f} s, {h['energy_mean']:.1f} J")
    else:
        check(text, None, "not evaluated")
    seconds = {e["algorithm"]: [s.get("train_seconds") for s in e["per_seed"]] for e in learned
               if not e["algorithm"].endswith(SHIELD_SUFFIX)}  # a shielded entry's runs are listed unshielded
    text = f"each training run <= {TRAINING_BUDGET / 60:.0f} min on 2 CPU cores"
    if seconds:
        longest = {a: max(v for v in values if v is not None) for a, values in seconds.items()
                   if any(v is not None for v in values)}
        check(text, all(v <= TRAINING_BUDGET for v in longest.values()),
              "longest run: " + ", ".join(f"{a} {v / 60:.1f} min" for a, v in longest.items()))
    else:
        check(text, None, "not evaluated")
    return checks


def markdown(entries: list[dict]) -> str:
    lines = ["#### Targets", "", "| target | met | reached |", "|---|---|---|"]
    for c in target_checks(entries):
        met = {True: "yes", False: "**no**", None: "-"}[c["met"]]
        lines.append(f"| {c['target']} | {met} | {c['reached']} |")
    lines.append("")
    return "\n".join(lines) + "\n" + overview(entries) + "\n" + condition_tables(entries)


def overview(entries: list[dict]) -> str:
    """Every policy across the conditions: time to target (IQM), with (success rate / collision
    rate) where not every episode succeeds without a collision; "-" where none succeeds."""
    conditions = list(dict.fromkeys(e["condition"] for e in entries))
    lines = ["#### Overview: time to target, IQM (success rate / collision rate where not 1 / 0)", "",
             "| policy | " + " | ".join(conditions) + " |", "|---|" + "---|" * len(conditions)]
    for name in dict.fromkeys(e["name"].split(" (d=")[0] for e in entries):
        cells = []
        for condition in conditions:
            found = [e for e in entries if e["condition"] == condition and e["name"].split(" (d=")[0] == name]
            if not found:
                cells.append("n/a")
                continue
            e = found[0]
            time_text = "-" if e["success_rate"] == 0 else f"{e['time_iqm']:.3f} s"
            clean = e["success_rate"] == 1.0 and e["collision_rate"] == 0.0
            cells.append(time_text if clean else f"{time_text} ({_rate(e['success_rate'])} / {_rate(e['collision_rate'])})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def condition_tables(entries: list[dict]) -> str:
    """One table per condition (and every seed of the learned entries): the comparison's format."""
    lines = []
    for name in dict.fromkeys(e["condition"] for e in entries):
        lines += [f"#### {name}: {CONDITIONS[name].description}", "",
                  "| policy | kind | mode | seeds | episodes | success | collisions | time to target, IQM [95 % CI] (s) "
                  "| energy (J) | P(faster than heuristic) |", "|---|---|---|---|---|---|---|---|---|---|"]
        for e in (e for e in entries if e["condition"] == name):
            seeds = "-" if e["seeds"] is None else ",".join(map(str, e["seeds"]))
            p = e.get("probability_faster_than_heuristic")
            p_text = "-" if p is None else f"{p:.2f} [{e['probability_faster_ci'][0]:.2f}, {e['probability_faster_ci'][1]:.2f}]"
            lines.append(f"| {e['name']} | {e['kind']} | {e['control_mode']} | {seeds} | {e['episodes']} | "
                         f"{_rate(e['success_rate'])} | {_rate(e['collision_rate'])} | {e['time_iqm']:.4f} "
                         f"[{e['time_ci'][0]:.4f}, {e['time_ci'][1]:.4f}] | {e['energy_mean']:.1f} | {p_text} |")
        per_seed = [e for e in entries if e["condition"] == name and e.get("per_seed")]
        if per_seed:
            lines += ["", "Every seed (success, collisions, mean time of the successful episodes, energy):", ""]
            for e in per_seed:
                cells = [f"seed {s['seed']}: {_rate(s['success_rate'])} / {_rate(s['collision_rate'])} / "
                         + ("-" if s["time_mean"] is None else f"{s['time_mean']:.4f} s") + f" / {s['energy_mean']:.0f} J"
                         for s in e["per_seed"]]
                lines.append(f"- {e['name']}: " + "; ".join(cells))
        lines.append("")
    return "\n".join(lines)


def figures(entries: list[dict], traces: dict, groups: dict, out: Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    obstacle = DEFAULT_PARAMS.obstacle
    if "c11" in traces:
        fig, ax = plt.subplots(figsize=(6.5, 6))
        ax.axvspan(obstacle.x_position - obstacle.critical_distance, obstacle.x_position + obstacle.critical_distance,
                   color="0.88")
        ax.axvline(obstacle.x_position, color="k", lw=2, label="wall (x_obs)")
        for (label, trace), color in zip(traces["c11"].items(), plt.cm.tab10.colors):
            ax.plot(trace[:, 1], trace[:, 2], color="k" if label == "optimal" else color,
                    lw=2.5 if label == "optimal" else 1.1, label=label)
        ax.set(xlabel="x [m]", ylabel="y [m]", title="Tip paths on the C11 target (learned: first seed)", aspect="equal")
        ax.legend(fontsize=7)
        _save(fig, out / "comparison_tip_paths.png", written)

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for e, color in zip([e for e in entries if e["condition"] == "c11"], plt.cm.tab10.colors):
            ax.errorbar(e["time_iqm"], e["energy_mean"], xerr=[[e["time_iqm"] - e["time_ci"][0]],
                                                              [e["time_ci"][1] - e["time_iqm"]]],
                        fmt="o", color=color, label=e["name"])
            for s in e.get("per_seed", []):
                if s["time_mean"] is not None:
                    ax.plot(s["time_mean"], s["energy_mean"], ".", color=color, alpha=0.6)
        ax.set(xlabel="time to target [s] (IQM, 95 % CI; dots: seeds)", ylabel="electrical energy [J]",
               title="Time against energy, C11 target", yscale="log")
        ax.legend(fontsize=7)
        _save(fig, out / "comparison_time_energy.png", written)

    curves = {}
    for (algorithm, mode), run_dirs in sorted(groups.items()):
        data = [np.load(d / "eval" / "evaluations.npz") for d in run_dirs if (d / "eval" / "evaluations.npz").exists()]
        data = [d for d in data if len(d["timesteps"])]
        if data:
            n = min(len(d["timesteps"]) for d in data)
            curves[f"{algorithm} ({mode})"] = (data[0]["timesteps"][:n], np.array([d["results"][:n].mean(axis=1) for d in data]))
    if curves:
        from rliable import metrics

        fig, ax = plt.subplots(figsize=(7, 4))
        for (label, (steps, returns)), color in zip(curves.items(), plt.cm.tab10.colors):
            point, interval = _interval_estimates(
                {label: returns[:, None, :]},
                lambda s: np.array([metrics.aggregate_iqm(s[:, :, t]) for t in range(s.shape[-1])]), 500, 0)
            ax.plot(steps, point[label], color=color, label=f"{label}, {returns.shape[0]} seeds")
            ax.fill_between(steps, interval[label][0], interval[label][1], color=color, alpha=0.2)
        ax.set(xlabel="environment steps", ylabel="evaluation return (IQM over seeds, 95 % CI)",
               title="Learning curves", xscale="log")
        ax.legend(fontsize=8)
        _save(fig, out / "comparison_learning_curves.png", written)
    return written


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(prog="python -m agents.compare", description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=Path, default=Path("runs/baselines"),
                        help="agents.baselines' folder of learned runs (ENV_ID/MODE/ALGO/seedN)")
    parser.add_argument("--conditions", nargs="+", choices=list(CONDITIONS), default=list(CONDITIONS))
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1000, help="episode i uses seed + i")
    parser.add_argument("--no-optimal", action="store_true", help="leave out the optimal reference")
    parser.add_argument("--out", type=Path, default=Path("docs/results"))
    parser.add_argument("--jobs", type=int, default=1, help="processes evaluating conditions side by side")
    parser.add_argument("--shield", nargs="*", default=list(SHIELDED), metavar="ALGO",
                        help="learned algorithms to run behind agents.shield's Shield as well (none: --shield)")
    parser.add_argument("--cache", type=Path, default=None, metavar="DIR",
                        help="keep learned runs' evaluations in DIR and reuse them (e.g. runs/compare-cache)")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    if args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    entries, traces = compare_in_parallel(args.runs, args.conditions, args.jobs, episodes=args.episodes,
                                          seed=args.seed, include_optimal=not args.no_optimal, cache=args.cache,
                                          shielded=tuple(args.shield))
    args.out.mkdir(parents=True, exist_ok=True)
    command = "python -m agents.compare " + " ".join(argv if argv is not None else __import__("sys").argv[1:])
    (args.out / "comparison.json").write_text(json.dumps({"env_id": TRAINING_ENV_ID, "command": command,
                                                           "targets": target_checks(entries),
                                                           "policies": entries}, indent=1))
    (args.out / "comparison.md").write_text(markdown(entries))
    figures(entries, traces, learned_runs(args.runs), args.out)
    print(markdown(entries))
    return entries


if __name__ == "__main__":
    main()
