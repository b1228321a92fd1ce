"""Re-evaluate one kind of row of a published comparison after a change to that policy alone, and
rewrite the comparison's JSON and report with them (the other entries are kept as published).

    python docs/scripts/refresh_rows.py mpc [--results docs/results] [--jobs 2]
    python docs/scripts/refresh_rows.py robust-shield
    python docs/scripts/refresh_rows.py learned-shielded [--runs docs/results/runs]

Each condition's rows come from the comparison's own code (``_ConditionTable.mpc``,
``_ConditionTable.robust_shield``, or ``_ConditionTable.learned`` behind the shield for the runs
tagged "also-shielded": the same episodes, seeds and summaries as ``scara-agents compare``; a
row the comparison has not had yet goes where ``compare`` puts it, after its kind's or its
unshielded twin's rows), the targets from ``target_checks`` and the report from ``comparison_markdown``: only
those rows' evaluation is rerun, so that a change to one policy does not cost the hours of
re-evaluating every learned run. The figures are not redrawn (they need every entry's
first-episode trace); ``python docs/gen_pages.py`` then regenerates the tables the docs and the
README take from the JSON.
"""

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from agents.experiments.comparison import ROBUST_LABEL, SHIELD_SUFFIX, SHIELDED, _ConditionTable, tuned_heuristics
from agents.experiments.evaluation import learned_runs
from agents.experiments.report import comparison_markdown
from agents.experiments.targets import target_checks
from agents.files import write_atomic, write_json
from scara_gym.benchmark.protocol import get_condition

ROWS = {"mpc": lambda e: e["kind"] == "mpc", "robust-shield": lambda e: e["name"] == ROBUST_LABEL,
        "learned-shielded": lambda e: e["kind"] == "learned" and e["name"].endswith(SHIELD_SUFFIX)}
"""the kinds of row this script refreshes: which entries they are"""


def fresh_entries(arguments: tuple) -> list[dict]:
    rows, name, episodes, groups, heuristics = arguments
    table = _ConditionTable(get_condition(name), episodes, verbose=True)
    if rows == "mpc":
        table.mpc()
    elif rows == "robust-shield":
        table.robust_shield()
    else:  # the heuristic's rows first: the learned rows' P(faster than heuristic) compares with them
        table.classical(heuristics, SHIELDED, include_optimal=False, robust_shield=False)
        table.entries.clear()
        table.learned(groups, None, SHIELDED, shields=(True,))
    return table.entries


def _twin(entry: dict, rows: str) -> str | None:
    """The name of the entry a new ``entry`` follows: its unshielded twin, or (None) its kind's last."""
    return entry["name"][:-len(SHIELD_SUFFIX)] if rows == "learned-shielded" else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", choices=sorted(ROWS))
    parser.add_argument("--results", type=Path, default=Path("docs/results"))
    parser.add_argument("--runs", type=Path, default=Path("docs/results/runs"))
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    path = args.results / "comparison.json"
    data = json.loads(path.read_text())
    chosen = ROWS[args.rows]
    old = {(e["condition"], e["name"]): e for e in data["policies"] if chosen(e)}
    groups, heuristics = {}, None
    if args.rows == "learned-shielded":
        groups = {key: dirs for key, dirs in learned_runs(args.runs).items() if key[0] in SHIELDED}
        heuristics = tuned_heuristics(verbose=True)
        counts = {e["condition"]: e["episodes"] for e in data["policies"] if e["kind"] == "pd"}
    else:
        counts = {condition: e["episodes"] for (condition, _), e in old.items()}
    work = [(args.rows, name, counts[name], groups, heuristics) for name in data["conditions"] if name in counts]
    with ProcessPoolExecutor(args.jobs) as pool:
        fresh = {arguments[1]: entries for arguments, entries in zip(work, pool.map(fresh_entries, work))}
    policies = [e for e in data["policies"] if not (chosen(e) and e["condition"] in fresh)]
    for condition, entries in fresh.items():  # each after its twin, else after its condition's last
        for entry in entries:
            names = [i for i, e in enumerate(policies) if e["condition"] == condition]
            twin = [i for i in names if policies[i]["name"] == _twin(entry, args.rows)]
            kind = [i for i in names if chosen(policies[i]) or policies[i]["kind"] == entry["kind"]]
            at = (twin or kind or names)[-1] + 1
            policies.insert(at, entry)
    data["policies"] = policies
    data["targets"] = target_checks(data["policies"])
    data.setdefault("refreshed_by", {})[args.rows] = f"python docs/scripts/refresh_rows.py {args.rows}"
    write_json(path, data, indent=1)
    write_atomic(args.results / "comparison.md", comparison_markdown(data["policies"]))
    for e in (e for e in policies if chosen(e)):
        before = old.get((e["condition"], e["name"]))
        was = (f"success {before['success_rate']:.3f}, collisions {before['collision_rate']:.3f}, time IQM "
               f"{before['time_iqm']:.4f} s -> " if before else "new: ")
        timing = e.get("solve_time")
        solve = (f"; median solve {timing['median'] * 1e3:.1f} ms, p95 {timing['p95'] * 1e3:.1f}, worst "
                 f"{timing['worst'] * 1e3:.0f}" if timing else "")
        print(f"{e['condition']}, {e['name']}: {was}success {e['success_rate']:.3f}, collisions "
              f"{e['collision_rate']:.3f}, time IQM {e['time_iqm']:.4f} s{solve}")


if __name__ == "__main__":
    main()
