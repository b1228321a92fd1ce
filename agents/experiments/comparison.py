"""The comparison: learned vs classical vs optimal, every policy over the same evaluation seeds.

Every policy runs the same episodes (seeds 1000..) of ``Scara-C11-v1`` in every condition
(:data:`agents.experiments.conditions.CONDITIONS`: the C11 target with the wall, randomized
targets, and the C11 target under four parameter shifts):

- policies: ``pd`` (the classical baseline), the seed's ``dec`` heuristic in both variants at its
  smallest safe trigger distance (bisected in each condition) and with a 20 % margin, ``optimal``
  (the minimum-time reference, "voltage" mode; skipped with randomized targets, which would need
  one solve per target), and every learned run under ``RUNS/ENV_ID/MODE/NAME/seedN``, one entry
  per registered run over its seeds;
- behind scara_gym.wrappers.Shield (its model: the nominal parameters): PD and the runs named by
  ``shielded`` (default: those tagged "also-shielded"), as entries "... + shield". Runs trained
  behind the shield (tag "shielded") always act behind it.

Learned runs are aggregated with rliable over their training seeds (agents.experiments.statistics);
every seed's own figures are in ``per_seed``. The report (tables, figures) is
agents.experiments.report's; the acceptance targets are agents.experiments.targets'.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from agents.experiments.conditions import CONDITIONS, make_env
from agents.experiments.evaluation import episodes_of, learned_episodes, learned_runs
from agents.experiments.registry import RUNS, tagged
from agents.experiments.statistics import entry, probability_faster, rate_text, time_scores, training_seconds
from agents.policies import DecHeuristic, PDPolicy, smallest_safe_distance
from agents.policies.optimal import OptimalPolicy
from scara_gym.wrappers import Shield

SHIELDED = tagged("also-shielded")
"""registered runs the comparison also evaluates behind the shield by default (``--shield``)"""
SHIELD_SUFFIX = " + shield"
SHIELD_NOTE = "scara_gym.wrappers.Shield with the nominal parameters"


def compare(runs_root: Path | None = Path("runs/baselines"), conditions: list[str] = ("c11",),
            episodes: int = 100, seed: int = 1000, include_optimal: bool = True, verbose: bool = True,
            bisection_tolerance: float = 5e-4, cache: Path | None = None, shielded: tuple[str, ...] = SHIELDED):
    """Every policy in every condition: (entries, traces per condition). Every policy here is
    deterministic, so in a condition without draws (fixed target and parameters) its episodes
    are one episode repeated: episodes_of runs two and checks that. cache: a folder that keeps
    learned runs' evaluations (learned_episodes). shielded: learned algorithms that also run
    behind scara_gym.wrappers.Shield (entries "ALGO + shield"), as PD does ("pd + shield") where
    any is given. Every entry says whether a shield acts ("shielded"); a learned one names its
    runs' folder ("run") and carries their registry tags ("tags")."""
    entries, traces = [], {}
    groups = learned_runs(runs_root) if runs_root is not None else {}
    for name in conditions:
        started = time.perf_counter()
        table = _ConditionTable(CONDITIONS[name], verbose)
        table.classical(episodes, seed, bisection_tolerance, shielded, include_optimal)
        table.learned(groups, episodes, seed, cache, shielded)
        entries += table.entries
        traces[name] = table.traces
        if verbose:
            print(f"[{name}] {time.perf_counter() - started:.0f} s", flush=True)
    return entries, traces


class _ConditionTable:
    """The entries and first-episode traces of one condition, as they are added."""

    def __init__(self, condition, verbose: bool) -> None:
        self.condition, self.verbose = condition, verbose
        self.same = not condition.randomize_target  # every episode alike (see episodes_of)
        self.entries: list[dict] = []
        self.traces: dict = {}
        self.reference = None  # the heuristic learned agents are compared with: dec-continue, smallest safe distance

    def add(self, label, kind, algorithm, mode, runs, seeds, note="", train_seconds=None, shielded=False, tags=(),
            run=None) -> dict:
        e = {**entry(label, kind, algorithm, mode, self.condition.name, runs, seeds, note, train_seconds),
             "shielded": shielded, "run": run, "tags": sorted(tags)}
        self.entries.append(e)
        self.traces[label] = runs[0]["trace"]
        if self.verbose:
            print(f"[{self.condition.name}] {label}: success {rate_text(e['success_rate'])}, collisions "
                  f"{rate_text(e['collision_rate'])}, time IQM {e['time_iqm']:.4f} s {e['time_ci']}, "
                  f"energy {e['energy_mean']:.1f} J", flush=True)
        return e

    def classical(self, episodes: int, seed: int, bisection_tolerance: float, shielded, include_optimal: bool) -> None:
        """PD (and behind the shield), the heuristic at its smallest safe distance and +20 %, the optimal replay."""

        condition, same = self.condition, self.same
        env = make_env(condition, "pd")
        self.add("pd", "pd", None, "pd", [episodes_of(env, PDPolicy(env), episodes, seed, same)], None)
        if shielded:
            self.add("pd" + SHIELD_SUFFIX, "pd", None, "pd",
                     [episodes_of(env, Shield(env, PDPolicy(env)), episodes, seed, same)], None, note=SHIELD_NOTE,
                     shielded=True)
        for variant in ("continue", "restart"):
            try:  # the bisection runs episode 0 of the evaluation seeds
                smallest, _ = smallest_safe_distance(variant, tolerance=bisection_tolerance, env=env, seed=seed)
            except RuntimeError:  # no trigger distance clears the wall in this condition
                continue
            for label, distance in (("smallest safe", smallest), ("+20 %", 1.2 * smallest)):
                policy = DecHeuristic(env, variant, critical_distance=distance)
                runs = [episodes_of(env, policy, episodes, seed, same)]
                self.reference = self.reference or runs
                self.add(f"dec-{variant}, {label} (d={distance:.4f} m)", "heuristic", None, "pd", runs, None,
                         note=f"trigger distance {distance:.4f} m (smallest safe in this condition: {smallest:.4f} m)")
        if include_optimal and not condition.randomize_target:
            env = make_env(condition, "voltage")
            try:  # the shipped solutions only: a solve takes minutes to hours
                runs = [episodes_of(env, OptimalPolicy(env, solve_missing=False), episodes, seed, same)]
            except LookupError:
                if self.verbose:
                    print(f"[{condition.name}] optimal: no shipped solution (scara-agents optimal --condition "
                          f"{condition.name} --write agents/optimal_solutions/{condition.name}.json)", flush=True)
            else:
                self.add("optimal", "optimal", None, "voltage", runs, None,
                         note="minimum-time voltages held over the control steps (agents.policies.optimal)")

    def learned(self, groups: dict, episodes: int, seed: int, cache, shielded) -> None:
        """Every learned run's seeds (and behind the shield where ``shielded`` names it)."""
        for (algorithm, mode), run_dirs in sorted(groups.items()):
            env = make_env(self.condition, mode)
            configs = [json.loads((d / "config.json").read_text()) for d in run_dirs]
            tags = RUNS[algorithm].tags if algorithm in RUNS else frozenset()
            for shield in (False, True) if algorithm in shielded else (False,):
                runs = [learned_episodes(env, d, self.condition, mode, episodes, seed, self.same, cache, shield)
                        for d in run_dirs]
                label = algorithm + (SHIELD_SUFFIX if shield else "")
                e = self.add(label, "learned", label, mode, runs, [c["seed"] for c in configs],
                             note=SHIELD_NOTE if shield else "", train_seconds=[training_seconds(c) for c in configs],
                             shielded=shield or "shielded" in tags, tags=tags, run=algorithm)
                if self.reference is not None:
                    p, ci = probability_faster(time_scores(runs), time_scores(self.reference))
                    e["probability_faster_than_heuristic"] = p
                    e["probability_faster_ci"] = ci


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
