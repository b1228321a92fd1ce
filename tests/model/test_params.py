import math

import numpy as np
import pytest

from scara_gym.model import records as R
from scara_gym.model.params import DEFAULT_PARAMS, ArmParams, AxisParams, ObstacleParams, ScaraParams, TaskParams


def test_derived_inertias_match_spec():
    arm = DEFAULT_PARAMS.arm
    assert arm.theta1 == pytest.approx(1.866667, abs=1e-6)
    assert arm.theta2 == pytest.approx(0.72, abs=1e-12)
    assert arm.theta3 == pytest.approx(0.45, abs=1e-12)
    assert DEFAULT_PARAMS.vertical_mass == pytest.approx(0.5 + 9.1e-6 * 1047**2)


def test_default_axes_are_the_spec_table():
    table = [(3.9, 0.0073, 0.4, 130, 6.64, 1000, 10, 100),
             (50, 0.025, 0.25, 100, 2.771, 1000, 25, 75),
             (40, 0.025, 0.4, 1047, 1.732, 5000, 10, 90)]
    for axis, row in zip(DEFAULT_PARAMS.axes, table):
        assert (axis.resistance, axis.inductance, axis.torque_constant, axis.gear_ratio,
                axis.current_limit, axis.p_gain, axis.d_gain, axis.voltage_limit) == row
    assert DEFAULT_PARAMS.obstacle.wide_voltage_limits == (200.0, 150.0, 180.0)
    assert DEFAULT_PARAMS.task.target == (2.0, 2.0, 0.3)


def test_to_record_fills_every_field_by_name():
    p = DEFAULT_PARAMS.to_record()
    assert p.dtype == R.PARAMS
    assert p["gear_ratio"][2] == 1047 and p["wide_voltage_limit"][1] == 150
    assert p["wall_x"] == 0.35 and p["wall_height"] == 0.15 and p["dec"] == 5e-5
    assert list(p["target"]) == [2, 2, 0.3] and p["accuracy"] == 0.001
    assert p["theta1"] == pytest.approx(DEFAULT_PARAMS.arm.theta1)
    assert p["vertical_mass"] == DEFAULT_PARAMS.vertical_mass
    # no field left at its zero fill: every field of the record is set from the tree
    for name in R.PARAMS.names:
        assert np.all(p[name] != 0), name


def test_params_are_frozen():
    with pytest.raises(AttributeError):
        DEFAULT_PARAMS.arm.load_mass = 2.0


@pytest.mark.parametrize("build, words", [
    (lambda: ArmParams(link1_mass=-1.0), ["ArmParams.link1_mass", "in [0.01, 1000]", "kg", "-1.0"]),
    (lambda: ArmParams(link2_length=math.nan), ["ArmParams.link2_length", "finite"]),
    (lambda: AxisParams(current_limit=0.0), ["AxisParams.current_limit", "in [0.001, 1000]", "A"]),
    (lambda: AxisParams(d_gain=-5.0), ["AxisParams.d_gain", "in [0, 100000]"]),
    (lambda: ObstacleParams(dec=0.0), ["ObstacleParams.dec", "in (0, 1]"]),
    (lambda: ObstacleParams(dec=2.0), ["ObstacleParams.dec", "in (0, 1]"]),
    (lambda: ObstacleParams(wide_voltage_limits=(1, 2)), ["wide_voltage_limits", "3 finite"]),
    (lambda: TaskParams(target=(2.0, math.inf, 0.3)), ["TaskParams.target", "finite"]),
    (lambda: TaskParams(start=(0.0, 0.0)), ["TaskParams.start"]),
    (lambda: TaskParams(accuracy=-0.1), ["TaskParams.accuracy", "in [1e-09, 1]"]),
])
def test_non_physical_values_are_rejected_with_the_field_and_range(build, words):
    with pytest.raises(ValueError) as info:
        build()
    for word in words:
        assert word in str(info.value)


def test_wrong_types_are_rejected():
    with pytest.raises(TypeError, match="ArmParams.load_mass"):
        ArmParams(load_mass="heavy")
    with pytest.raises(TypeError, match="ScaraParams.axes"):
        ScaraParams(axes=(AxisParams(), AxisParams()))


def test_replace_by_dotted_path():
    params = DEFAULT_PARAMS.replace({"arm.load_mass": 1.0, "axes.2.p_gain": 4000.0, "obstacle.dec": 5e-3})
    assert params.arm.load_mass == 1.0
    assert params.axes[2].p_gain == 4000.0
    assert params.axes[1].p_gain == 1000.0
    assert params.obstacle.dec == 5e-3
    assert DEFAULT_PARAMS.arm.load_mass == 0.5  # the original is untouched
    with pytest.raises(KeyError, match="arm.mass"):
        DEFAULT_PARAMS.replace({"arm.mass": 1.0})
    with pytest.raises(KeyError, match="0..2"):
        DEFAULT_PARAMS.replace({"axes.3.p_gain": 1.0})
    with pytest.raises(ValueError, match="AxisParams.voltage_limit"):
        DEFAULT_PARAMS.replace({"axes.0.voltage_limit": -100.0})
    assert params.to_record().tobytes() != DEFAULT_PARAMS.to_record().tobytes()
