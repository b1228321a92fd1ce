"""The C11 parameter tree: one frozen, typed, validated set of numbers.

The seed paper states the equations, not the numbers. The defaults are a reconstructed
set: the OpenModelica solutions of exercise A60 (ch. 17.2) of P. Junglas, "Praxis der
Simulationstechnik" (repository modelica-3rdparty/PraxisSimulationstechnik,
package Kap17, Solutions/ScaraA.mo and ScaraB.mo), a SCARA robot of exactly the
C11 structure with the same start and target. The obstacle values are not in the
seed paper either; they are chosen so that the restart variant reproduces the
seed's 1.4555 s.

Every leaf field carries its unit and allowed range in ``metadata``; the
validation message names the field path and that range. The hot path does not
see these objects: `ScaraParams.to_record` packs them into the ``PARAMS``
record of `scara_gym.model.records`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from scara_gym.model import checks
from scara_gym.model.checks import UserError, UserKeyError, UserTypeError
from scara_gym.model.records import PARAMS


def _quantity(default: float, unit: str, low: float, high: float, doc: str = "", *,
              low_open: bool = False) -> Any:
    """A scalar field: its unit and allowed interval [low, high] (open at low if low_open)
    in ``metadata``. The intervals keep every quantity physical and float64 arithmetic far
    from overflow; they span about three decades around the C11 values.
    """
    return field(default=default, metadata={"unit": unit, "range": (low, high, low_open), "doc": doc})


def _check_quantity(path: str, value: Any, unit: str, allowed) -> float:
    low, high, low_open = allowed
    return checks.real(path, value, low, high, unit=unit, low_open=low_open)


def _check_vector(path: str, value: Any, unit: str, low: float = -math.inf, high: float = math.inf) -> tuple:
    text = "" if math.isinf(low) else f"each in [{low:g}, {high:g}]"
    vector = checks.real_array(path, value, (3,), unit=unit, low=None if math.isinf(low) else low,
                               high=high, range_text=text)
    return tuple(float(v) for v in vector)


MIN_ELECTRICAL_TIME_CONSTANT = 1e-5  # [s] L/R of each motor; C11's smallest is 5e-4 s


class _Validated:
    """Checks every scalar field against its ``metadata`` range after construction."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if "range" in f.metadata:
                value = _check_quantity(f"{type(self).__name__}.{f.name}", getattr(self, f.name),
                                        f.metadata["unit"], f.metadata["range"])
                object.__setattr__(self, f.name, value)


@dataclass(frozen=True)
class ArmParams(_Validated):
    """Mechanics of the two links and the vertical load (seed eq. 3-9)."""

    link1_length: float = _quantity(0.4, "m", 0.01, 10.0, doc="L1")
    link2_length: float = _quantity(0.3, "m", 0.01, 10.0, doc="L2")
    link1_mass: float = _quantity(8.0, "kg", 0.01, 1000.0, doc="m1, uniform rod")
    link2_mass: float = _quantity(6.0, "kg", 0.01, 1000.0, doc="m2, uniform rod")
    end_mass: float = _quantity(2.5, "kg", 0.0, 1000.0,
                                doc="m_end, stator of the vertical drive at the end of link 2")
    load_mass: float = _quantity(0.5, "kg", 0.001, 1000.0, doc="m3L, load moved by the prismatic joint")
    motor3_rotor_inertia: float = _quantity(9.1e-6, "kg m^2", 0.0, 1.0,
                                            doc="th3mot; motors 1 and 2 have none")
    gravity: float = _quantity(9.81, "m/s^2", 0.0, 100.0, doc="g")

    @property
    def theta1(self) -> float:
        """th1 = m1 L1^2/3 + (m2 + m_end + m3L) L1^2 [kg m^2]."""
        return (self.link1_mass * self.link1_length**2 / 3
                + (self.link2_mass + self.end_mass + self.load_mass) * self.link1_length**2)

    @property
    def theta2(self) -> float:
        """th2 = (m2 L2/2 + (m_end + m3L) L2) L1 [kg m^2]."""
        return ((self.link2_mass * self.link2_length / 2
                 + (self.end_mass + self.load_mass) * self.link2_length) * self.link1_length)

    @property
    def theta3(self) -> float:
        """th3 = m2 L2^2/3 + (m_end + m3L) L2^2 [kg m^2]."""
        return (self.link2_mass * self.link2_length**2 / 3
                + (self.end_mass + self.load_mass) * self.link2_length**2)

    @property
    def reach(self) -> float:
        """Largest tip distance from the base, L1 + L2 [m]."""
        return self.link1_length + self.link2_length


@dataclass(frozen=True)
class AxisParams(_Validated):
    """One DC motor with gear and its saturated PD controller (seed eq. 13-16)."""

    resistance: float = _quantity(3.9, "Ohm", 0.001, 1e4, doc="R")
    inductance: float = _quantity(0.0073, "H", 1e-6, 10.0, doc="L")
    torque_constant: float = _quantity(0.4, "N m/A", 0.001, 100.0, doc="kT (also the back-EMF constant)")
    gear_ratio: float = _quantity(130.0, "1 (rad/m for the prismatic axis)", 1.0, 1e5, doc="u")
    current_limit: float = _quantity(6.64, "A", 0.001, 1000.0, doc="Imax")
    p_gain: float = _quantity(1000.0, "V/rad (V/m)", 0.0, 1e6, doc="P")
    d_gain: float = _quantity(10.0, "V s/rad (V s/m)", 0.0, 1e5, doc="D")
    voltage_limit: float = _quantity(100.0, "V", 0.001, 1e4, doc="Umax")

    def __post_init__(self) -> None:
        super().__post_init__()
        # the explicit integrator resolves the motor's electrical transient (eigenvalue -R/L)
        if self.inductance / self.resistance < MIN_ELECTRICAL_TIME_CONSTANT:
            raise UserError(
                f"AxisParams: inductance / resistance (the electrical time constant) must be >= "
                f"{MIN_ELECTRICAL_TIME_CONSTANT:g} s, got {self.inductance!r} H / {self.resistance!r} Ohm "
                f"= {self.inductance / self.resistance:.3g} s (C11: 5e-4 to 1.9e-3 s)")


def _default_axes() -> tuple[AxisParams, AxisParams, AxisParams]:
    # spec table "axis | R | L | kT | u | Imax | P | D | Umax"
    return (
        AxisParams(3.9, 0.0073, 0.4, 130.0, 6.64, 1000.0, 10.0, 100.0),
        AxisParams(50.0, 0.025, 0.25, 100.0, 2.771, 1000.0, 25.0, 75.0),
        AxisParams(40.0, 0.025, 0.4, 1047.0, 1.732, 5000.0, 10.0, 90.0),
    )


@dataclass(frozen=True)
class TaskParams(_Validated):
    """The point-to-point move of task b."""

    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """q(0) [rad, rad, m]; rates and currents start at 0."""
    target: tuple[float, float, float] = (2.0, 2.0, 0.3)
    """q^ [rad, rad, m]."""
    accuracy: float = _quantity(0.001, "rad (m)", 1e-9, 1.0, doc="acc: reached when all |q_i - q^_i| < acc")

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "start", _check_vector("TaskParams.start", self.start, "rad, rad, m"))
        object.__setattr__(self, "target", _check_vector("TaskParams.target", self.target, "rad, rad, m"))


@dataclass(frozen=True)
class ObstacleParams(_Validated):
    """The wall of task c and the seed's ``dec`` avoidance rule (seed section 3)."""

    x_position: float = _quantity(0.35, "m", -10.0, 10.0, doc="x_obs, plane of the wall")
    critical_distance: float = _quantity(0.02, "m", 1e-4, 1.0, doc="d_crit")
    height: float = _quantity(0.15, "m", -10.0, 10.0, doc="h_obs")
    dec: float = _quantity(5e-5, "1", 0.0, 1.0, low_open=True,
                           doc="factor on q1', q2' while critical; the seed's dec")
    wide_voltage_limits: tuple[float, float, float] = (200.0, 150.0, 180.0)
    """Umax_wide [V] per axis, the permitted voltage while critical (2 Umax)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        limits = _check_vector("ObstacleParams.wide_voltage_limits", self.wide_voltage_limits, "V",
                               0.001, 1e4)
        object.__setattr__(self, "wide_voltage_limits", limits)


@dataclass(frozen=True)
class ScaraParams:
    """Root of the parameter tree: arm, three axes, task b and the obstacle of task c."""

    arm: ArmParams = field(default_factory=ArmParams)
    axes: tuple[AxisParams, AxisParams, AxisParams] = field(default_factory=_default_axes)
    task: TaskParams = field(default_factory=TaskParams)
    obstacle: ObstacleParams = field(default_factory=ObstacleParams)

    def __post_init__(self) -> None:
        for name, cls in (("arm", ArmParams), ("task", TaskParams), ("obstacle", ObstacleParams)):
            if not isinstance(getattr(self, name), cls):
                raise UserTypeError(f"ScaraParams.{name} must be a {cls.__name__}, got {getattr(self, name)!r}")
        axes = tuple(self.axes) if isinstance(self.axes, (tuple, list)) else ()
        if len(axes) != 3 or not all(isinstance(a, AxisParams) for a in axes):
            raise UserTypeError(f"ScaraParams.axes must be 3 AxisParams, got {self.axes!r}")
        object.__setattr__(self, "axes", axes)
        # th1 th3 - th2^2 cos^2 q2 > 0 for every q2 is what makes M invertible.
        if self.arm.theta1 * self.arm.theta3 - self.arm.theta2**2 <= 0:
            raise UserError("ScaraParams.arm: th1*th3 - th2^2 must be > 0 (mass matrix singular)")

    @property
    def vertical_mass(self) -> float:
        """ma33 = m3L + th3mot u3^2 [kg]: effective mass of the prismatic axis."""
        return self.arm.load_mass + self.arm.motor3_rotor_inertia * self.axes[2].gear_ratio**2

    @property
    def voltage_limits(self) -> np.ndarray:
        """The axes' armature voltage limits Umax [V], shape (3,)."""
        return np.array([a.voltage_limit for a in self.axes])

    @property
    def current_limits(self) -> np.ndarray:
        """The axes' armature current limits Imax [A], shape (3,)."""
        return np.array([a.current_limit for a in self.axes])

    def replace(self, overrides: Mapping[str, Any] | None = None, **kwargs: Any) -> ScaraParams:
        """A copy with dotted-path overrides.

        Args:
            overrides: {dotted path: value}, e.g. ``{"arm.load_mass": 1.0, "axes.2.p_gain": 4000}``.
            **kwargs: more overrides, a keyword per path without a dot (e.g. a whole ``task=...``).

        Returns:
            The new, validated ScaraParams (a bad value raises ValueError naming its path and range).
        """
        if overrides is not None and not isinstance(overrides, Mapping):
            raise UserTypeError(f"parameter overrides must be a dict of dotted paths -> values, e.g. "
                                f"{{'arm.load_mass': 1.0}}, got {overrides!r}")
        items = dict(overrides or {})
        items.update(kwargs)
        for path in items:
            if not isinstance(path, str):
                raise UserTypeError(f"parameter override keys must be dotted paths such as 'arm.load_mass', "
                                    f"got {path!r}")
        if len(items) > 1:
            try:  # one new node per changed subtree (per-episode draws change a dozen leaves)
                return _replace_tree(self, _path_tree(items))
            except (KeyError, TypeError, ValueError):
                pass  # one path at a time below, which names the override at fault
        result = self
        for path, value in items.items():
            try:
                result = _replace_path(result, path.split("."), value, path)
            except (TypeError, ValueError) as error:  # name the override, not only the class
                raise type(error)(f"override {path!r}: {error}") from None
        return result

    def to_record(self) -> np.void:
        """The compiled core's ``PARAMS`` record (a view into a fresh one-element array)."""
        record = np.zeros(1, dtype=PARAMS)[0]
        arm = self.arm
        record["theta1"], record["theta2"], record["theta3"] = arm.theta1, arm.theta2, arm.theta3
        record["vertical_mass"] = self.vertical_mass
        record["load_mass"], record["gravity"] = arm.load_mass, arm.gravity
        record["link1_length"], record["link2_length"] = arm.link1_length, arm.link2_length
        for name in ("resistance", "inductance", "torque_constant", "gear_ratio", "current_limit",
                     "p_gain", "d_gain", "voltage_limit"):
            record[name] = [getattr(axis, name) for axis in self.axes]
        obstacle = self.obstacle
        record["wide_voltage_limit"] = obstacle.wide_voltage_limits
        record["wall_x"], record["critical_distance"] = obstacle.x_position, obstacle.critical_distance
        record["wall_height"], record["dec"] = obstacle.height, obstacle.dec
        record["target"] = self.task.target
        record["accuracy"] = self.task.accuracy
        return record


_LEAF = object()


def _path_tree(items: Mapping[str, Any]) -> dict:
    """Dotted paths -> a nested dict of their parts, the values under _LEAF keys."""
    tree: dict = {}
    for path, value in items.items():
        node = tree
        for part in path.split("."):
            node = node.setdefault(part, {})
        if node:
            raise UserError(f"override {path!r} is both a leaf and a subtree")
        node[_LEAF] = value
    return tree


def _replace_tree(node: Any, tree: dict) -> Any:
    if _LEAF in tree:
        if len(tree) > 1:
            raise UserError("a leaf and its subtree overridden together")
        return tree[_LEAF]
    if isinstance(node, tuple) and not dataclasses.is_dataclass(node):
        items = list(node)
        for part, subtree in tree.items():
            if not part.isdigit() or int(part) >= len(items):
                raise KeyError(part)
            items[int(part)] = _replace_tree(items[int(part)], subtree)
        return tuple(items)
    if not dataclasses.is_dataclass(node):
        raise KeyError(tree)
    names = {f.name for f in dataclasses.fields(node)}
    if not set(tree) <= names:
        raise KeyError(sorted(set(tree) - names))
    return dataclasses.replace(node, **{part: _replace_tree(getattr(node, part), subtree)
                                        for part, subtree in tree.items()})


def _replace_path(node: Any, parts: list[str], value: Any, full: str) -> Any:
    head, rest = parts[0], parts[1:]
    if isinstance(node, tuple) and not dataclasses.is_dataclass(node):
        if not head.isdigit() or int(head) >= len(node):
            raise UserKeyError(f"unknown parameter {full!r}: index {head!r} must be 0..{len(node) - 1}")
        items = list(node)
        items[int(head)] = _replace_path(items[int(head)], rest, value, full) if rest else value
        return tuple(items)
    if not dataclasses.is_dataclass(node):
        raise UserKeyError(f"unknown parameter {full!r}")
    names = [f.name for f in dataclasses.fields(node)]
    if head not in names:
        raise UserKeyError(f"unknown parameter {full!r}: {type(node).__name__} has {', '.join(names)}")
    new = _replace_path(getattr(node, head), rest, value, full) if rest else value
    return dataclasses.replace(node, **{head: new})


DEFAULT_PARAMS = ScaraParams()


def resolve_params(params: ScaraParams | Mapping[str, Any] | None) -> ScaraParams:
    """A ScaraParams from None (the C11 defaults), a ScaraParams, or a dict of dotted-path
    overrides of the defaults.
    """
    if params is None:
        return DEFAULT_PARAMS
    if isinstance(params, ScaraParams):
        return params
    if isinstance(params, Mapping):
        return DEFAULT_PARAMS.replace(params)
    raise UserTypeError(f"params must be a ScaraParams or a dict of dotted-path overrides such as "
                        f"{{'arm.load_mass': 1.0}}, got {params!r}")
