"""Re-evaluate the MPC's entries of a published comparison after a change to the MPC alone, and
rewrite the comparison's JSON and report with them (the other entries are kept as published).

    python docs/scripts/refresh_mpc_rows.py [--results docs/results] [--jobs 2]

Each condition's MPC entry comes from the comparison's own code (``_ConditionTable.mpc``: the same
episodes, seeds and solve-time summary as ``scara-agents compare``), the targets from
``target_checks`` and the report from ``comparison_markdown``: only the MPC's evaluation is rerun,
so that a change to the MPC does not cost the hours of re-evaluating every learned run. The
figures are not redrawn (they need every entry's first-episode trace); ``python docs/gen_pages.py``
then regenerates the tables the docs and the README take from the JSON.
"""

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from agents.experiments.comparison import _ConditionTable
from agents.experiments.report import comparison_markdown
from agents.experiments.targets import target_checks
from agents.files import write_atomic, write_json
from scara_gym.benchmark.protocol import get_condition


def mpc_entries(arguments: tuple[str, int]) -> list[dict]:
    name, episodes = arguments
    table = _ConditionTable(get_condition(name), episodes, verbose=True)
    table.mpc()
    return table.entries


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("docs/results"))
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    path = args.results / "comparison.json"
    data = json.loads(path.read_text())
    old = {(e["condition"], e["name"]): e for e in data["policies"] if e["kind"] == "mpc"}
    episodes = {condition: e["episodes"] for (condition, _), e in old.items()}
    work = [(name, episodes[name]) for name in data["conditions"] if name in episodes]
    with ProcessPoolExecutor(args.jobs) as pool:
        fresh = {name: entries for (name, _), entries in zip(work, pool.map(mpc_entries, work))}
    policies = []  # each condition's MPC entries replaced, in place, by its fresh ones
    for e in data["policies"]:
        if e["kind"] != "mpc":
            policies.append(e)
        elif e["condition"] in fresh:
            policies += fresh.pop(e["condition"])
    data["policies"] = policies
    data["targets"] = target_checks(data["policies"])
    data["mpc_refreshed_by"] = "python docs/scripts/refresh_mpc_rows.py"
    write_json(path, data, indent=1)
    write_atomic(args.results / "comparison.md", comparison_markdown(data["policies"]))
    for e in (e for e in policies if e["kind"] == "mpc"):
        before, after = old.get((e["condition"], e["name"])), e["solve_time"]
        was = (f"median {before['solve_time']['median'] * 1e3:.1f}, success {before['success_rate']:.3f}, collisions "
               f"{before['collision_rate']:.3f}, time IQM {before['time_iqm']:.4f} s -> " if before else "new: ")
        print(f"{e['condition']}, {e['name']}: {was}median {after['median'] * 1e3:.1f} ms, p95 {after['p95'] * 1e3:.1f},"
              f" worst {after['worst'] * 1e3:.0f}; success {e['success_rate']:.3f}, collisions "
              f"{e['collision_rate']:.3f}, time IQM {e['time_iqm']:.4f} s")


if __name__ == "__main__":
    main()
