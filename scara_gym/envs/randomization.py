"""Domain randomization: model parameters drawn per episode from documented ranges.

A `ParameterRanges` maps dotted parameter paths (those of
`ScaraParams.replace`, e.g. ``"arm.load_mass"``, ``"axes.0.resistance"``) to
uniform ranges [low, high] in the parameter's own unit. The presets scale the
environment's nominal parameters (the C11 set unless ``params`` says otherwise):

| preset | path | range |
|---|---|---|
| physics | arm.load_mass | nominal x [0.5, 2.5] |
| physics | arm.link1_mass, arm.link2_mass | nominal x [0.9, 1.1] |
| physics | axes.i.resistance | nominal x [0.9, 1.3] |
| physics | axes.i.torque_constant | nominal x [0.9, 1.1] |
| physics | axes.i.current_limit | nominal x [0.8, 1.1] |
| wall | obstacle.x_position | nominal + [-0.04, 0.04] m |
| wall | obstacle.height | nominal + [-0.03, 0.03] m |
| all | both of the above | |

Rows with axes.i stand for the three axes i = 0, 1, 2. Each path is drawn independently
(every axis its own factor), in sorted path order, from
the episode's random generator, so a seed reproduces the draws. The four shifts of the
comparison (load x2, wall 2 cm closer, current limits -15 %, resistances +20 %) lie
inside the "all" ranges. With the C11 targets the wall ranges keep the task solvable: the
target tip stays beyond the wall band and the target height above the wall.

No gymnasium import here: the task object (`scara_gym.envs.task`) uses it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from scara_gym.model import checks
from scara_gym.model.params import ScaraParams

# (path, kind, low, high): kind "factor" scales the nominal value, "offset" adds to it
_PHYSICS = (
    ("arm.load_mass", "factor", 0.5, 2.5),
    ("arm.link1_mass", "factor", 0.9, 1.1),
    ("arm.link2_mass", "factor", 0.9, 1.1),
    *[(f"axes.{i}.{name}", "factor", low, high) for i in range(3)
      for name, low, high in (("resistance", 0.9, 1.3), ("torque_constant", 0.9, 1.1),
                              ("current_limit", 0.8, 1.1))],
)
_WALL = (
    ("obstacle.x_position", "offset", -0.04, 0.04),
    ("obstacle.height", "offset", -0.03, 0.03),
)
PRESETS = {"physics": _PHYSICS, "wall": _WALL, "all": _PHYSICS + _WALL}
"""Preset name -> (path, "factor" | "offset", low, high) rows (the module's table)."""

# leaves a range may draw: scalars of the arm, the axes and the wall; the task (start,
# target, accuracy) has reset options of its own, and dec is the seed's rule, not the env's
_RANDOMIZABLE_ROOTS = ("arm", "axes", "obstacle")
_FIXED_LEAVES = ("obstacle.dec",)


def leaf_value(params: ScaraParams, path: str) -> float:
    """The value of a scalar parameter at a dotted path; KeyError naming it otherwise."""
    node = params
    for part in path.split("."):
        if isinstance(node, tuple) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif dataclasses.is_dataclass(node) and part in {f.name for f in dataclasses.fields(node)}:
            node = getattr(node, part)
        else:
            raise KeyError(f"unknown parameter {path!r}")
    if not checks.is_real(node):
        raise KeyError(f"parameter {path!r} is not a scalar (a range draws one number)")
    return float(node)


def check_path(name: str, path, nominal: ScaraParams) -> str:
    """A dotted path to a scalar of ``nominal`` that ranges may draw and reset options may set."""
    if not isinstance(path, str):
        raise TypeError(f"{name}: parameter paths are dotted strings such as 'arm.load_mass', got {path!r}")
    if path.split(".")[0] not in _RANDOMIZABLE_ROOTS or path in _FIXED_LEAVES:
        raise ValueError(f"{name}: {path!r} cannot vary per episode; allowed: scalar parameters under "
                         f"{', '.join(r + '.' for r in _RANDOMIZABLE_ROOTS)} except {', '.join(_FIXED_LEAVES)} "
                         f"(starts and targets are reset options of their own)")
    try:
        leaf_value(nominal, path)
    except KeyError as error:
        raise ValueError(f"{name}: {error.args[0]}") from None
    return path


@dataclass(frozen=True)
class ParameterRanges:
    """Dotted path -> (low, high): uniform per-episode draws, in each parameter's unit."""

    ranges: Mapping[str, tuple[float, float]]

    @classmethod
    def from_argument(cls, value, nominal: ScaraParams) -> ParameterRanges | None:
        """``randomize_params`` of the environments: None/False (off), True ("physics"), a preset
        name, a ParameterRanges, or a dict path -> (low, high) in the parameter's unit.
        """
        text = (f"randomize_params must be False, True, one of {sorted(PRESETS)}, a ParameterRanges or a "
                f"dict of dotted paths -> (low, high)")
        if value is None or value is False:
            return None
        if value is True:
            value = "physics"
        if isinstance(value, str):
            if value not in PRESETS:
                raise ValueError(f"{text}, got {value!r}")
            return cls.preset(value, nominal)
        if isinstance(value, ParameterRanges):
            value = value.ranges
        if not isinstance(value, Mapping) or not value:
            raise TypeError(f"{text}, got {value!r}")
        ranges = {}
        for path, bounds in value.items():
            name = f"randomize_params[{path!r}]"
            check_path("randomize_params", path, nominal)
            if not isinstance(bounds, (tuple, list, np.ndarray)) or len(bounds) != 2:
                raise TypeError(f"{name} must be (low, high), got {bounds!r}")
            low, high = checks.real(f"{name}[0]", bounds[0]), checks.real(f"{name}[1]", bounds[1])
            if high < low:
                raise ValueError(f"{name} must be (low, high) with low <= high, got {bounds!r}")
            for end in (low, high):  # both ends inside the parameter tree's own range
                try:
                    nominal.replace({path: end})
                except (TypeError, ValueError) as error:
                    raise ValueError(f"{name}: {error}") from None
            ranges[path] = (low, high)
        return cls(dict(sorted(ranges.items())))

    @classmethod
    def preset(cls, name: str, nominal: ScaraParams) -> ParameterRanges:
        """A preset of the module's table around the nominal parameters."""
        ranges = {}
        for path, kind, low, high in PRESETS[name]:
            value = leaf_value(nominal, path)
            ranges[path] = (value * low, value * high) if kind == "factor" else (value + low, value + high)
        return cls(dict(sorted(ranges.items())))

    def __post_init__(self) -> None:
        bounds = np.array(list(self.ranges.values()), dtype=float).reshape(-1, 2)
        object.__setattr__(self, "_low", bounds[:, 0])
        object.__setattr__(self, "_high", bounds[:, 1])

    def draw(self, rng: np.random.Generator) -> dict[str, float]:
        """One draw of every path (in the ranges' sorted order), as Python floats."""
        return dict(zip(self.ranges, rng.uniform(self._low, self._high).tolist()))

    def extreme(self, nominal: ScaraParams) -> ScaraParams:
        """The nominal parameters with every range at its end of largest magnitude: what the
        observation bounds are built around.
        """
        return nominal.replace({path: max(bounds, key=abs) for path, bounds in self.ranges.items()})


def check_overrides(name: str, overrides, nominal: ScaraParams) -> dict[str, float]:
    """Per-episode parameter overrides (reset ``options["params"]``): dotted path -> value."""
    if not isinstance(overrides, Mapping):
        raise TypeError(f"{name} must be a dict of dotted paths -> values, e.g. {{'arm.load_mass': 1.0}}, "
                        f"got {overrides!r}")
    result = {}
    for path, value in overrides.items():
        check_path(name, path, nominal)
        result[path] = checks.real(f"{name}[{path!r}]", value)
    return result


def within_bounds(params: ScaraParams, bound_params: ScaraParams) -> str | None:
    """None if the observation bounds built around bound_params hold every observation under
    params, else the reason (the currents, the tip and the wall features).
    """
    for i, (axis, bound) in enumerate(zip(params.axes, bound_params.axes)):
        if axis.current_limit > bound.current_limit:
            return (f"axes.{i}.current_limit = {axis.current_limit:g} A exceeds the observation bound "
                    f"{bound.current_limit:g} A")
    if params.arm.reach > bound_params.arm.reach:
        return f"the reach {params.arm.reach:g} m exceeds the observation bound {bound_params.arm.reach:g} m"
    for field in ("x_position", "height"):
        value, bound = getattr(params.obstacle, field), getattr(bound_params.obstacle, field)
        if abs(value) > abs(bound) + 1e-12 * max(1.0, abs(bound)):
            return f"|obstacle.{field}| = {abs(value):g} m exceeds the observation bound {abs(bound):g} m"
    return None
