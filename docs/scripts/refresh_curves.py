"""Add (or replace) PD behind the robust shield in published robustness curves, and redraw the figure.

    python docs/scripts/refresh_curves.py [--results docs/results]

The points come from the curves' own loop (``agents.experiments.curves.curve_points``: the same
conditions, episodes and summaries as ``scara-agents curves --robust-shield``), with the published
curves' episode count; only the robust shield's points are evaluated, so that adding it does not
cost re-evaluating every other policy. Every other curve row is kept as published.
"""

import argparse
import json
from pathlib import Path

from agents.experiments.comparison import ROBUST_LABEL, robust_shield_pd
from agents.experiments.curves import curve_points, write_curves

COMMAND = f" (and {ROBUST_LABEL}: python docs/scripts/refresh_curves.py)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("docs/results"))
    args = parser.parse_args()
    data = json.loads((args.results / "curves.json").read_text())
    fresh = curve_points({ROBUST_LABEL: robust_shield_pd}, {}, data["episodes"])
    for curve, points in fresh.items():
        if points["factors"] != data["curves"][curve]["factors"]:
            raise SystemExit(f"curve {curve!r}: the published factors {data['curves'][curve]['factors']} are not "
                             f"today's {points['factors']}")
        data["curves"][curve]["policies"][ROBUST_LABEL] = points["policies"][ROBUST_LABEL]
    if not data["command"].endswith(COMMAND):
        data["command"] += COMMAND
    print(write_curves(data, args.results))


if __name__ == "__main__":
    main()
