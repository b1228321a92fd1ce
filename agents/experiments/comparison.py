"""The comparison: learned vs classical vs optimal, every policy in the protocol's conditions.

Every policy runs the same episodes of every condition of the evaluation protocol
(`scara_gym.benchmark.protocol`: the C11 episode, perturbed starts, randomized targets,
drawn and fixed parameter shifts, sensor noise, actuation delay, a rate limit), on
the protocol's one id (``protocol.ENV_ID``, the latest), each condition on its own evaluation seeds:

- policies: ``pd`` (the classical baseline); the seed's ``dec`` heuristic in both variants at its
  trigger distance tuned once on the tuning set and at 1.2 times it
  (`agents.experiments.tuning`: never re-tuned on a condition it is scored on); ``optimal``
  (the minimum-time replay, "voltage" mode) where the condition keeps the C11 start, target and
  parameters and a solution is shipped (an open-loop replay does not see sensor noise); ``mpc``
  (the nonlinear MPC, agents.policies.mpc, "voltage" mode, its nominal model, with its solve
  times per control step); and every learned run under ``RUNS/ENV_ID/MODE/NAME/seedN``, one
  entry per registered run over
  its seeds (kind "learned"; "offline" for those tagged so: trained on a dataset, agents.algorithms.bc);
- behind scara_gym.wrappers.Shield (its model: the nominal parameters): PD and the runs named by
  ``shielded`` (default: those tagged "also-shielded"), as entries "... + shield". Runs trained
  behind the shield (tag "shielded") always act behind it.

Learned runs are aggregated with rliable over their training seeds (agents.experiments.statistics);
every seed's own figures are in ``per_seed``. Every entry is scored at the C11 band and at the looser
bands of scara_gym.benchmark.episodes (``success_rate_1e-2``, ``time_iqm_1e-2``, ...; statistics'
docstring) and, per episode, by a normalized time score (`time_score_reference`): 0 = "pd +
shield"'s time in the same episode, 1 = the time of the optimal replay where the condition has it,
else of the MPC ("mpc", voltage mode), each entry naming which ("time_score_reference"); a
condition with neither (``include_mpc=False`` outside the optimal's conditions) leaves the score
out. The report (tables, figures) is agents.experiments.report's; the acceptance targets are
agents.experiments.targets'.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import time
from functools import partial
from pathlib import Path

from agents.algorithms.loaders import load_policy, run_spec
from agents.experiments.entries import Entry, shield_added
from agents.experiments.evaluation import (
    cached_evaluation,
    condition_description,
    decision_time,
    learned_episodes,
    learned_runs,
    mpc_episodes,
    rti_episodes,
)
from agents.experiments.registry import RUNS, tagged
from agents.experiments.statistics import (
    figures,
    probability_faster,
    rate_text,
    time_score_fields,
    time_scores,
    training_seconds,
)
from agents.experiments.tuning import tune_heuristic
from agents.files import json_record
from agents.policies import (
    DecHeuristic,
    PDPolicy,
    base as policies_base,
    heuristic as policies_heuristic,
    pd as policies_pd,
)
from agents.policies.optimal import SOLUTIONS, OptimalPolicy, policy as optimal_policy, solutions as optimal_solutions
from scara_gym.benchmark.protocol import ENV_ID, evaluate, get_condition
from scara_gym.model.checks import UserError
from scara_gym.wrappers import Shield, shield as shield_module

SHIELDED = tagged("also-shielded")
"""registered runs the comparison also evaluates behind the shield by default (``--shield``)"""
SHIELD_SUFFIX = " + shield"
SHIELD_NOTE = "scara_gym.wrappers.Shield with the nominal parameters"
ROBUST_RANGES = "all"
"""the robust shield's ranges (scara_gym.envs.randomization's preset): every shift of the protocol lies inside"""
ROBUST_LABEL = f"pd + robust shield ({ROBUST_RANGES!r} ranges)"
ROBUST_NOTE = (f"scara_gym.wrappers.Shield with the nominal parameters, robust over the {ROBUST_RANGES!r} ranges "
               "(their ends, the adverse corners and 8 draws, robust_seed 0)")
HEURISTIC_VARIANTS = ("continue", "restart")


def shield_pd(env) -> Shield:
    """The "pd + shield" policy: PD behind the shield with the nominal parameters."""
    return Shield(env, PDPolicy(env))


def shipped_optimal(env) -> OptimalPolicy:
    """The optimal replay from the shipped solutions only (a solve takes minutes to hours)."""
    return OptimalPolicy(env, solve_missing=False)


def robust_shield_pd(env) -> Shield:
    """The ROBUST_LABEL policy: PD behind the shield robust over ROBUST_RANGES."""
    return Shield(env, PDPolicy(env), robust=ROBUST_RANGES)


CLASSICAL_SOURCES = (policies_base, policies_pd, policies_heuristic, optimal_policy, optimal_solutions, shield_module)
"""the modules whose source a classical policy's cached evaluation digests"""
OPTIMAL_CONDITIONS = ("c11", "sensor-noise", "sensor-noise-x5")
"""conditions where the optimal replay applies: the C11 start, target and parameters"""


def tuned_heuristics(verbose: bool = False) -> dict:
    """variant -> tune_heuristic's record (the heuristic's rows use these distances everywhere)."""
    tuned = {}
    for variant in HEURISTIC_VARIANTS:
        try:
            tuned[variant] = tune_heuristic(variant)
        except RuntimeError as error:  # no trigger distance clears the tuning set
            tuned[variant] = {"distance": None, "error": str(error)}
        if verbose:
            print(f"[tuning] dec-{variant}: {tuned[variant]}", flush=True)
    return tuned


def compare(runs_root: Path | None = Path("runs/baselines"), conditions: list[str] = ("c11",),
            episodes: int | None = None, include_optimal: bool = True, verbose: bool = True,
            cache: Path | None = None, shielded: tuple[str, ...] = SHIELDED, heuristics: dict | None = None,
            pilots: bool = False, robust_shield: bool = True, include_mpc: bool = True, only: tuple[str, ...] = (),
            decision_times: bool = True, mpc_latency: bool = True, run_names: tuple[str, ...] | None = None):
    """Every policy in every condition: (entries, traces per condition). episodes: per condition
    (None: the condition's own count; a dict: condition -> count, None or missing for its own;
    the C11 episode is one). only: kinds of ONLY_ROWS, evaluated alone (every other row left
    out; scored against the same references as in the full table, evaluated or read from
    ``cache`` beside them: _ConditionTable.only), to merge into a published comparison
    (merge_entries). cache: a folder that keeps every
    evaluation (learned runs': learned_episodes; the classical policies' and the MPC's:
    cached_evaluation). shielded: learned algorithms that also run behind
    scara_gym.wrappers.Shield (entries "ALGO + shield"), as PD does ("pd + shield") where any is
    given. heuristics: tuned_heuristics() (computed here where None). pilots: also the runs
    tagged "pilot" (left out by default). robust_shield: PD behind the robust shield where the
    condition shifts the parameters. include_mpc: the MPC's entry (its evaluations are kept in
    ``cache`` too; "solve_time": median, p95 and worst per control step [s]). decision_times:
    every entry's compute per control step ("decision_time": median and 95th percentile [s],
    evaluation.decision_time, timed afresh on this machine over the condition's first episodes;
    the MPC's is its solve time per control step). mpc_latency: with the MPC, each of its modes
    again under its own latency (``added_delay``: _ConditionTable.mpc_latency). run_names: only
    these registered runs of ``runs_root`` (None: every one). Every entry names the id it was scored on
    ("env_id": the protocol's) and says
    whether a shield acts ("shielded") and for
    which parameters it is built ("shield_range": "nominal" or the robust ranges); a learned one
    names its runs' folder ("run") and carries their registry tags ("tags")."""
    entries, traces = [], {}
    heuristics = tuned_heuristics(verbose) if heuristics is None else heuristics
    groups = learned_runs(runs_root) if runs_root is not None else {}
    if not pilots:
        groups = {key: dirs for key, dirs in groups.items() if "pilot" not in getattr(RUNS.get(key[0]), "tags", ())}
    if run_names is not None:
        groups = {key: dirs for key, dirs in groups.items() if key[0] in run_names}
    for name in conditions:
        started = time.perf_counter()
        count = episodes.get(name) if isinstance(episodes, dict) else episodes
        table = _ConditionTable(get_condition(name), count, verbose, cache, mpc_latency)
        if only:
            table.only(only, heuristics, groups, shielded, include_optimal, include_mpc)
        else:
            table.classical(heuristics, shielded, include_optimal, robust_shield)
            if include_mpc:
                table.mpc(table.mpc_latency_rows)
            table.learned(groups, cache, shielded)
            table.time_scores()
        if decision_times:
            table.decision_times()
        entries += [e.record() for e in table.entries]
        traces[name] = table.traces
        if verbose:
            print(f"[{name}] {time.perf_counter() - started:.0f} s", flush=True)
    return entries, traces


MPC_ROWS = (
    ("mpc", "voltage", "nonlinear MPC on the nominal model (agents.policies.mpc), IPOPT every control step"),
    ("mpc (pd)", "pd", "the same MPC in the \"pd\" mode: the set-point for which the PD law gives its voltages "
                       "at the step's start"),
)
"""the MPC's comparison rows: (label, control mode, note)"""
RTI_ROWS = (
    ("mpc-rti", "voltage", "real-time MPC: the MPC's problem by one SQP step per control step on HPIPM from the "
                           "shifted plan (agents.policies.mpc_rti)"),
    ("mpc-rti (pd)", "pd", "the real-time MPC in the \"pd\" mode"),
)
"""the real-time MPC's comparison rows (kind "mpc-rti"): (label, control mode, note)"""


class _ConditionTable:
    """The entries and first-episode traces of one condition, as they are added."""

    def __init__(self, condition, episodes: int | None, verbose: bool, cache=None, mpc_latency: bool = True) -> None:
        self.condition, self.verbose, self.cache = condition, verbose, cache
        self.episodes = 1 if condition.episodes == 1 else episodes  # the C11 episode is one episode
        self.entries: list[Entry] = []
        self.runs: list[list[dict]] = []  # each entry's per-episode arrays, for the normalized time score
        self.traces: dict = {}
        self.reference = None  # the heuristic learned agents are compared with: dec-continue at its tuned distance
        self.factories: dict[str, tuple] = {}  # label -> (policy factory, control mode): its decisions timed
        self.mpc_latency_rows = mpc_latency  # the MPC also under its own latency

    def add(self, label, kind, algorithm, mode, runs, seeds, note="", train_seconds=None, shielded=False, tags=(),
            run=None, shield_range=None, factory=None, variant=None, setting=None, added_delay=0) -> Entry:
        e = Entry(label, kind, algorithm, mode, self.condition.name, ENV_ID, None if seeds is None else tuple(seeds),
                  variant=variant, setting=setting, shielded=shielded,
                  shield_range=shield_range or ("nominal" if shielded else None), added_delay=added_delay, run=run,
                  tags=tuple(sorted(tags)),
                  note=note, figures=figures(runs, seeds, train_seconds))
        self.entries.append(e)
        self.runs.append(runs)
        self.traces[label] = runs[0]["trace"]
        if factory is not None:
            self.factories[label] = (factory, mode)
        if self.verbose:
            f = e.figures
            print(f"[{self.condition.name}] {label}: success {rate_text(f['success_rate'])}, collisions "
                  f"{rate_text(f['collision_rate'])}, time IQM {f['time_iqm']:.4f} s {f['time_ci']}, "
                  f"energy {f['energy_mean']:.1f} J", flush=True)
        return e

    def update(self, e: Entry, **more) -> Entry:
        """Figures added to an entry of the table (it is frozen: replaced by its copy)."""
        updated = e.with_figures(**more)
        self.entries[self.entries.index(e)] = updated
        return updated

    def run(self, key: str, factory, mode: str = "pd") -> dict:
        """A classical policy's episodes, from the cache where it keeps them (key: what names
        the policy and its settings; the cache digests the policies' and the shield's source)."""
        def run() -> dict:
            result = evaluate(self.condition, factory, mode, self.episodes)
            result.pop("condition")
            return result

        description = [key, mode, *condition_description(self.condition, self.episodes)]
        return cached_evaluation(self.cache, "classical", CLASSICAL_SOURCES, description, run)

    def classical(self, heuristics: dict, shielded, include_optimal: bool, robust_shield: bool = True) -> None:
        """PD (and behind the shield: the nominal one, and the robust one where the parameters
        shift), the heuristic at its tuned distance and with the margin, the optimal replay."""
        self.add("pd", "pd", None, "pd", [self.run("pd", PDPolicy)], None, factory=PDPolicy)
        self.add("pd" + SHIELD_SUFFIX, "pd", None, "pd", [self.run("shield:pd", shield_pd)],
                 None, note=SHIELD_NOTE, shielded=True, factory=shield_pd)
        if robust_shield:
            self.robust_shield()
        for variant, tuned in heuristics.items():
            if tuned.get("distance") is None:
                continue
            for label, distance in (("tuned", tuned["distance"]), ("margin", tuned["margin_distance"])):
                def heuristic(env, d=distance, v=variant):
                    return DecHeuristic(env, v, critical_distance=d)

                runs = [self.run(f"dec-{variant}:{distance!r}", heuristic)]
                if variant == "continue" and label == "tuned":
                    self.reference = runs
                self.add(f"dec-{variant}, {label} (d={distance:.4f} m)", "heuristic", None, "pd", runs, None,
                         variant=variant, setting=label,
                         note=f"trigger distance {distance:.4f} m, tuned once on the tuning set "
                              f"(agents.experiments.tuning: {tuned['distance']:.4f} m)", factory=heuristic)
        if include_optimal and self.condition.name in OPTIMAL_CONDITIONS:
            try:  # the shipped solutions only: a solve takes minutes to hours
                shipped = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(SOLUTIONS.glob("*.json")))).hexdigest()
                runs = [self.run(f"optimal:{shipped}", shipped_optimal, "voltage")]
            except LookupError:
                if self.verbose:
                    print(f"[{self.condition.name}] optimal: no shipped solution", flush=True)
            else:
                self.add("optimal", "optimal", None, "voltage", runs, None,
                         note="minimum-time voltages held over the control steps (agents.policies.optimal)",
                         factory=shipped_optimal)

    def robust_shield(self) -> None:
        """PD behind the robust shield, where the condition shifts the parameters."""
        if self.condition.params or self.condition.env_kwargs.get("randomize_params"):
            runs = [self.run(f"robust-shield:{ROBUST_RANGES}:pd", robust_shield_pd)]
            self.add(ROBUST_LABEL, "pd", None, "pd", runs, None, note=ROBUST_NOTE, shielded=True,
                     shield_range=ROBUST_RANGES, factory=robust_shield_pd)

    def only(self, kinds, heuristics: dict, groups: dict, shielded, include_optimal: bool = True,
             include_mpc: bool = True) -> None:
        """The rows of ``kinds`` (ONLY_ROWS) alone, as the full table computes them: with the
        heuristic's episodes (P(faster than the heuristic)) and the normalized time score's
        references (pd + shield, the optimal replay or the MPC) evaluated beside them in a table
        that is not published, from the cache where it keeps them."""
        unknown = [kind for kind in kinds if kind not in ONLY_ROWS]
        if unknown:
            raise UserError(f"--only: unknown kind of row {unknown[0]!r}; the kinds are {sorted(ONLY_ROWS)}")
        references = _ConditionTable(self.condition, self.episodes, False, self.cache)
        references.classical(heuristics, shielded, include_optimal, robust_shield=False)
        self.reference = references.reference
        for kind in kinds:
            if kind == "mpc":
                self.mpc(self.mpc_latency_rows)
            elif kind == "robust-shield":
                self.robust_shield()
            else:
                self.learned(groups, self.cache, shielded, shields=(kind == "learned-shielded",))
        if include_mpc and not any(e.kind == "optimal" for e in references.entries):
            references.mpc_reference(self)
        self.time_scores(references)

    def mpc_reference(self, evaluated: _ConditionTable) -> None:
        """The MPC's "voltage" row alone (the normalized time score's 1 where no optimal replay is):
        the one of the ``evaluated`` table where it has it (not evaluated twice), else evaluated."""
        label, mode, note = MPC_ROWS[0]
        runs = [r for e, r in zip(evaluated.entries, evaluated.runs) if e.name == label]
        self.add(label, "mpc", None, mode,
                 runs[0] if runs else [mpc_episodes(self.condition, self.episodes, self.cache, mode=mode)], None,
                 note=note)

    def mpc(self, latency: bool = True) -> None:
        """The nonlinear MPC and the real-time MPC with their nominal model in both control modes,
        and their solve times; with ``latency``, each again under its own latency (mpc_latency)."""
        for kind, rows, episodes in (("mpc", MPC_ROWS, mpc_episodes), ("mpc-rti", RTI_ROWS, rti_episodes)):
            for label, mode, note in rows:
                result = episodes(self.condition, self.episodes, self.cache, mode=mode)
                self.update(self.add(label, kind, None, mode, [result], None, note=note),
                            solve_time=result["solve_time"])
                if latency:
                    self.mpc_latency(label, kind, mode, result["solve_time"]["p95"], episodes)

    def mpc_latency(self, label: str, kind: str, mode: str, p95: float, episodes) -> None:
        """The MPC as it would act in real time: each of its actions applied ceil(p95 / control
        step) control steps late (on top of the condition's own delay), its 95th-percentile solve
        time in this condition; none where that is 0 steps."""
        control_dt = self.condition.make_env(mode).unwrapped.control_dt
        steps = math.ceil(p95 / control_dt - 1e-9)
        if steps < 1:
            return
        own = self.condition.env_kwargs.get("action_delay", 0)
        delayed = dataclasses.replace(self.condition, env_kwargs={**self.condition.env_kwargs, "action_delay": own + steps})
        result = episodes(delayed, self.episodes, self.cache, mode=mode)
        e = self.add(f"{label}, latency {steps}", kind, None, mode, [result], None, added_delay=steps,
                 note=f"the same controller under its own latency: its 95th-percentile solve time here, {1e3 * p95:.1f} ms, "
                      f"as {steps} control steps of actuation delay ({control_dt * 1e3:g} ms each)"
                      + (f" on top of the condition's {own}" if own else ""))
        self.update(e, solve_time=result["solve_time"])

    def decision_times(self) -> None:
        """Every entry's compute per decision ("decision_time"): its policy timed over the
        condition's first episodes (evaluation.decision_time); the MPC's solve times per control
        step, which its evaluation kept ("timed": "solve")."""
        for e in list(self.entries):
            if e.figures.get("solve_time"):
                t = e.figures["solve_time"]
                self.update(e, decision_time={"median": t["median"], "p95": t["p95"], "decisions": t["solves"],
                                              "timed": "solve"})
            elif e.name in self.factories:
                factory, mode = self.factories[e.name]
                t = {**decision_time(self.condition, factory, mode), "timed": "decision"}
                self.update(e, decision_time=t)
                if self.verbose:
                    print(f"[{self.condition.name}] {e.name}: {1e6 * t['median']:.0f} us per decision (median), "
                          f"95th percentile {1e6 * t['p95']:.0f} us", flush=True)

    def time_scores(self, references: _ConditionTable | None = None) -> None:
        """Every entry's normalized time score (statistics.time_score_fields) against this
        condition's "pd + shield" (0) and time_score_reference's entry (1), found among the
        ``references`` table's entries (default: this table's); none without both."""
        references = self if references is None else references
        found = time_score_reference([e.record() for e in references.entries])
        if found is None:
            return
        labels = [e.name for e in references.entries]
        zero, one = (references.runs[labels.index(label)] for label in found)
        for e, runs in zip(list(self.entries), self.runs):
            fields = time_score_fields(runs, zero, one, found[1], e.seeds)
            scores = fields.pop("per_seed_scores", [])
            if "per_seed" in e.figures:
                fields["per_seed"] = [{**item, "time_score_mean": score}
                                      for item, score in zip(e.figures["per_seed"], scores)]
            self.update(e, **fields)

    def learned(self, groups: dict, cache, shielded, shields=(False, True)) -> None:
        """Every learned run's seeds (and behind the shield where ``shielded`` names it); shields:
        which of the two evaluations (without, behind the shield) to make."""
        for (algorithm, mode), run_dirs in sorted(groups.items()):
            configs = [json_record(d / "config.json") for d in run_dirs]
            tags = RUNS[algorithm].tags if algorithm in RUNS else frozenset()
            for shield in [s for s in ((False, True) if algorithm in shielded else (False,)) if s in shields]:
                runs = [learned_episodes(d, self.condition, mode, self.episodes, cache, shield) for d in run_dirs]
                label = algorithm + ("" if mode == "pd" else f" ({mode})") + (SHIELD_SUFFIX if shield else "")
                kind = "offline" if "offline" in tags else "learned"
                e = self.add(label, kind, label, mode, runs, [c["seed"] for c in configs],
                             note=SHIELD_NOTE if shield else "", train_seconds=[training_seconds(c) for c in configs],
                             shielded=shield or "shielded" in tags, tags=tags, run=algorithm,
                             factory=partial(load_policy, run_spec(run_dirs[0], shield)))  # its first seed timed
                if self.reference is not None:
                    p, ci = probability_faster(time_scores(runs), time_scores(self.reference))
                    self.update(e, probability_faster_than_heuristic=p, probability_faster_ci=ci)


def time_score_reference(records) -> tuple[str, str] | None:
    """(the entry scoring 0, the entry scoring 1) of the normalized time score among a condition's
    entry ``records``, by their names: "pd + shield" (PD behind the nominal shield) and the optimal
    replay, else the MPC in "voltage" mode; None where either is missing."""
    zero = [e for e in records if e["kind"] == "pd" and e.get("shield_range") == "nominal"]
    one = ([e for e in records if e["kind"] == "optimal"]
           or [e for e in records if e["kind"] == "mpc" and e["control_mode"] == "voltage" and not e.get("added_delay")])
    return (zero[0]["name"], one[0]["name"]) if zero and one else None


ONLY_ROWS = {
    "learned": lambda e: e["kind"] in ("learned", "offline") and not shield_added(e),
    "mpc": lambda e: e["kind"] in ("mpc", "mpc-rti"),
    "robust-shield": lambda e: e["kind"] == "pd" and e.get("shield_range") == ROBUST_RANGES,
    "learned-shielded": shield_added,
}
"""the kinds of row ``compare --only`` evaluates alone (after a change to that policy alone, so as
not to re-evaluate every learned run): which entries (records) they are. "learned": the learned
and offline rows (without an added shield) of the runs under ``--runs``; merged, they replace
those runs' rows only (merge_entries), so a folder holding just new runs adds their rows. Rows
evaluated alone get the normalized time score of the full table (_ConditionTable.only)."""


def merge_entries(published: list[dict], fresh: list[dict], kinds) -> list[dict]:
    """``published`` entries with the rows of ``kinds`` (ONLY_ROWS) of every condition ``fresh``
    covers replaced by ``fresh``'s: a row kept where it was, a new one after its unshielded twin,
    else after the last row of its kind in its condition, else at the condition's end. The other
    entries are kept as published. For "learned", only the rows of the runs ``fresh`` has."""
    fresh_runs = {(e["condition"], e.get("run")) for e in fresh if ONLY_ROWS["learned"](e)}
    chosen = [(lambda e: ONLY_ROWS["learned"](e) and (e["condition"], e.get("run")) in fresh_runs)
              if k == "learned" else ONLY_ROWS[k] for k in kinds]

    def picked(e: dict) -> bool:
        return any(c(e) for c in chosen)

    conditions = {e["condition"] for e in fresh}
    policies = list(published)
    at_old = {(e["condition"], e["name"]): i for i, e in enumerate(policies) if picked(e)}
    replaced = {}
    for entry_ in fresh:
        key = (entry_["condition"], entry_["name"])
        if key in at_old:
            replaced[at_old[key]] = entry_
    policies = [replaced.get(i, e) for i, e in enumerate(policies)
                if i in replaced or not (picked(e) and e["condition"] in conditions)]
    for entry_ in fresh:
        if (entry_["condition"], entry_["name"]) in at_old:
            continue
        names = [i for i, e in enumerate(policies) if e["condition"] == entry_["condition"]]
        twin = [i for i in names if shield_added(entry_) and not shield_added(policies[i])
                and policies[i].get("run") == entry_.get("run") and policies[i]["control_mode"] == entry_["control_mode"]]
        kind = [i for i in names if picked(policies[i]) or policies[i]["kind"] == entry_["kind"]]
        where = twin or kind or names
        policies.insert(where[-1] + 1 if where else len(policies), entry_)
    return policies


def _compare_condition(arguments: tuple) -> tuple[list[dict], dict]:
    runs_root, condition, kwargs = arguments
    return compare(runs_root, [condition], **kwargs)


def compare_in_parallel(runs_root: Path | None, conditions: list[str], jobs: int, **kwargs):
    """compare() with the conditions spread over ``jobs`` processes: the same entries, in the
    same order (each condition is evaluated on its own; the heuristic is tuned once, here)."""
    kwargs.setdefault("heuristics", tuned_heuristics(kwargs.get("verbose", True)))
    if jobs <= 1 or len(conditions) <= 1:
        return compare(runs_root, conditions, **kwargs)
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(min(jobs, len(conditions))) as pool:
        parts = list(pool.map(_compare_condition, [(runs_root, name, kwargs) for name in conditions]))
    return [e for entries, _ in parts for e in entries], {k: v for _, traces in parts for k, v in traces.items()}

