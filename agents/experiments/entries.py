"""One row of the comparison, typed: what the row is and the figures it reached, serialized once.

A comparison entry is a policy scored in one condition. What the row *is* (its kind, algorithm,
heuristic variant and setting, run, id, shield) are fields of `Entry`; code reads them there and
never out of the row's label, which is for people. The figures (success, collisions, times,
per seed, time scores, solve and decision times) are `agents.experiments.statistics`' numbers.
`Entry.record` is the one serialization: the dict that ``comparison.json`` holds and the
report, the targets and the merge read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from agents.experiments.registry import RUNS, zero_shot

KINDS = ("pd", "heuristic", "optimal", "mpc", "mpc-rti", "learned", "offline")
"""the kinds of row: PD, the seed paper's heuristic, the optimal replay, the MPC, the real-time MPC, a
learned run, a run trained on an offline dataset"""
SETTINGS = ("tuned", "margin")
"""a heuristic row's trigger distance: the one tuned on the tuning set, or 1.2x it"""
IDENTITY = ("name", "kind", "algorithm", "control_mode", "condition", "env_id", "seeds", "variant", "setting",
            "shielded", "shield_range", "added_delay", "run", "tags", "note")
"""the record's keys that say what the row is (Entry's fields); every other key is a figure"""


@dataclass(frozen=True)
class Entry:
    """A policy scored in a condition of the protocol.

    Attributes:
        name: the row's label (the heuristic's carries its distance): for tables, not for code.
        kind: one of KINDS.
        algorithm: a learned row's (its registered run, with its mode and shield), else None.
        control_mode: "pd" or "voltage".
        condition: the protocol condition it was scored in.
        env_id: the id it was scored on.
        seeds: a learned row's training seeds, else None.
        variant: a heuristic row's ("continue" or "restart"), else None.
        setting: a heuristic row's distance, one of SETTINGS, else None.
        shielded: whether it acts behind scara_gym.wrappers.Shield.
        shield_range: the parameters the shield is built for ("nominal" or a robust preset), None without one.
        added_delay: control steps of actuation delay the row adds to its condition's own (the MPC
            under its own latency: its 95th-percentile solve time in control steps), else 0.
        run: a learned row's registered run (its folder's name), else None.
        tags: the run's registry tags.
        note: how it was made, for people.
        figures: the numbers it reached (statistics.figures and what the comparison adds to them).
    """

    name: str
    kind: str
    algorithm: str | None
    control_mode: str
    condition: str
    env_id: str
    seeds: tuple[int, ...] | None = None
    variant: str | None = None
    setting: str | None = None
    shielded: bool = False
    shield_range: str | None = None
    added_delay: int = 0
    run: str | None = None
    tags: tuple[str, ...] = ()
    note: str = ""
    figures: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if (self.variant is None) != (self.setting is None) or (self.variant is not None and self.kind != "heuristic"):
            raise ValueError(f"{self.name}: a heuristic row has a variant and a setting, another row neither")
        if self.setting is not None and self.setting not in SETTINGS:
            raise ValueError(f"setting must be one of {SETTINGS}, got {self.setting!r}")
        if self.shielded != (self.shield_range is not None):
            raise ValueError(f"{self.name}: a shielded row names its shield's range, another row none")
        if (not isinstance(self.added_delay, int) or self.added_delay < 0
                or (self.added_delay and self.kind not in ("mpc", "mpc-rti"))):
            raise ValueError(f"{self.name}: added_delay is a count of control steps >= 0, on an MPC row only")
        clash = {*IDENTITY, "row"} & set(self.figures)
        if clash:
            raise ValueError(f"{self.name}: figures must not hold the entry's own fields {sorted(clash)}")

    @property
    def row(self) -> str:
        """The row across conditions: the label, the heuristic's without its distance."""
        return f"dec-{self.variant}, {self.setting}" if self.variant is not None else self.name

    def with_figures(self, **figures) -> Entry:
        """The same entry with these figures added (or replaced)."""
        return dataclasses.replace(self, figures={**self.figures, **figures})

    def record(self) -> dict:
        """The entry as comparison.json holds it: its fields, then its figures (JSON types)."""
        out = {name: getattr(self, name) for name in IDENTITY}
        out["seeds"] = None if self.seeds is None else list(self.seeds)
        out["tags"] = sorted(self.tags)
        out["row"] = self.row
        return {**out, **self.figures}


def row_of(record: Mapping) -> str:
    """A record's row across conditions (Entry.row). A record written before entries were typed
    has no "row": its label, less the distance a heuristic's carried (" (d=...)")."""
    return record["row"] if "row" in record else record["name"].split(" (d=")[0]


def is_heuristic(record: Mapping, variant: str, setting: str) -> bool:
    """Whether a record is the heuristic's row of that variant and setting (Entry's fields)."""
    return record.get("variant") == variant and record.get("setting") == setting


def shield_added(record: Mapping) -> bool:
    """Whether the comparison put a learned run behind the shield (its "+ shield" row): shielded,
    although its run does not act behind one itself."""
    return (record["kind"] in ("learned", "offline") and bool(record.get("shielded"))
            and "shielded" not in record.get("tags", ()))


def is_zero_shot(record: Mapping) -> bool:
    """Whether a learned or offline record is zero-shot (agents.experiments.registry.zero_shot):
    scored in a training distribution's condition (c11-starts, random-targets, random-shifts) whose
    draws its run never trained on. The registry says what a registered run trained on (so a
    record published before a run's tags were completed reads them as they are now); the record's
    own tags, for a run the registry does not hold."""
    if record["kind"] not in ("learned", "offline"):
        return False
    return zero_shot(run_tags(record), record["condition"])


def run_tags(record: Mapping):
    """The tags of a record's run: the registry's for a registered run (so a record published
    before its run's tags were completed reads them as they are now), else the record's own."""
    registered = RUNS.get(record.get("run"))
    return registered.tags if registered else record.get("tags", ())
