"""The comparison's acceptance targets: each a rule over the comparison's entries, with what it reached."""

from __future__ import annotations

from agents.experiments.conditions import SHIFTS
from agents.experiments.statistics import rate_text

MINIMUM_TIME_BOUND = 1.2217
"""[s] the continuous-time minimum-time bound on the C11 target (the free problem's optimum)"""
TRAINING_BUDGET = 1800.0
"""[s] per training run on 2 CPU cores"""


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
    """The acceptance targets: {"target", "met" (True/False/None: not evaluated), "reached"}."""
    checks = []

    def check(target, met, reached):
        checks.append({"target": target, "met": met, "reached": reached})

    def summary(e):
        return (f"{e['name']}: success {rate_text(e['success_rate'])}, collisions {rate_text(e['collision_rate'])}, "
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
        if e["kind"] == "learned" and e["condition"] in SHIFTS and "domain-randomized" in e.get("tags", ()):
            robust.setdefault(e["algorithm"], []).append(e)
    robust = {a: rows for a, rows in robust.items() if len(rows) == len(SHIFTS)}
    text = "domain-randomized agent under the four shifts: >= 95 % success, 0 collisions in each"

    def robust_enough(rows):
        return all(e["success_rate"] >= 0.95 and e["collision_rate"] == 0.0 for e in rows)

    if robust:
        best = max(robust, key=lambda a: (robust_enough(robust[a]),
                                          min(e["success_rate"] - e["collision_rate"] for e in robust[a])))
        check(text, robust_enough(robust[best]), f"{best}: " + "; ".join(
            f"{e['condition']} {rate_text(e['success_rate'])} / {rate_text(e['collision_rate'])}" for e in robust[best]))
    else:
        check(text, None, "no domain-randomized agent (registry tag) evaluated in all four shifts")
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
    # keyed by the runs' folder: a run also evaluated behind the shield is listed once
    seconds = {e["run"]: [s.get("train_seconds") for s in e["per_seed"]] for e in learned}
    text = f"each training run <= {TRAINING_BUDGET / 60:.0f} min on 2 CPU cores"
    if seconds:
        longest = {a: max(v for v in values if v is not None) for a, values in seconds.items()
                   if any(v is not None for v in values)}
        check(text, all(v <= TRAINING_BUDGET for v in longest.values()),
              "longest run: " + ", ".join(f"{a} {v / 60:.1f} min" for a, v in longest.items()))
    else:
        check(text, None, "not evaluated")
    return checks
