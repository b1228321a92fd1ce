"""Add (or replace) PD behind the robust shield in published robustness curves, and redraw the figure.

    python docs/scripts/refresh_curves.py [--results docs/results] [--episodes 20]

The points come from the curves' own loop (``agents.experiments.curves.curve_points``: the same
conditions, episodes and summaries as ``scara-agents curves --robust-shield``); only the robust
shield's points are evaluated, so that adding it does not cost re-evaluating every other policy.
Every other curve row is kept as published.
"""

import argparse
import json
from pathlib import Path

from agents.experiments.curves import ROBUST_CURVE_LABEL, curve_points, robust_shield_policy, write_curves


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("docs/results"))
    parser.add_argument("--episodes", type=int, default=None, help="default: the published curves' count")
    args = parser.parse_args()
    data = json.loads((args.results / "curves.json").read_text())
    episodes = args.episodes or data["episodes"]
    if episodes != data["episodes"]:
        raise SystemExit(f"--episodes: the published curves have {data['episodes']} episodes per point")
    fresh = curve_points({ROBUST_CURVE_LABEL: robust_shield_policy}, {}, episodes)
    for curve, points in fresh.items():
        if points["factors"] != data["curves"][curve]["factors"]:
            raise SystemExit(f"curve {curve!r}: the published factors {data['curves'][curve]['factors']} are not "
                             f"today's {points['factors']}")
        data["curves"][curve]["policies"][ROBUST_CURVE_LABEL] = points["policies"][ROBUST_CURVE_LABEL]
    data["command"] += f" (and {ROBUST_CURVE_LABEL}: python docs/scripts/refresh_curves.py)"
    print(write_curves(data, args.results))


if __name__ == "__main__":
    main()
