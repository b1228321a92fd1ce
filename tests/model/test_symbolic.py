"""The CasADi twin against the compiled model: right-hand side, voltages and event functions
at random states in every hybrid mode and configuration, to 1e-12 relative."""

import itertools

import numpy as np
import pytest

from scara_gym.model import records as R
from scara_gym.model.dynamics import derivative, tip_position
from scara_gym.model.integrator import event_values
from scara_gym.model.params import DEFAULT_PARAMS

ca = pytest.importorskip("casadi")
from scara_gym.model.symbolic import MODES, symbolic_model  # noqa: E402

STATES = 1000
CONFIGS = [dict(control=control, widen=widen, decelerate=decelerate, exact_switches=exact)
           for control, widen, decelerate, exact in itertools.product(("pd", "voltage"), (True, False), (True, False),
                                                                      (True, False))]


def _config(control, widen, decelerate, exact_switches, critical_rule=R.CRIT_SWITCH):
    config = np.zeros(1, dtype=R.CONFIG)[0]
    config["control"] = R.CONTROL_PD if control == "pd" else R.CONTROL_VOLTAGE
    config["widen"], config["decelerate"], config["exact_switches"] = widen, decelerate, exact_switches
    config["critical_rule"], config["wall"] = critical_rule, True
    return config


def _random_case(rng, control):
    """A state spanning the workspace and past the current limits, a command, and random modes."""
    x = np.concatenate([rng.uniform([-4, -4, -0.1], [4, 4, 0.5]), rng.uniform(-8, 8, 3), rng.uniform(-8, 8, 3),
                        rng.uniform(-50, 50, 1)])
    command = rng.uniform([-4, -4, -0.1], [4, 4, 0.5]) if control == "pd" else rng.uniform(-1, 1, 3)
    modes = np.concatenate([rng.integers(-1, 2, 6), rng.integers(0, 2, 1), rng.choice([-1, 1], 1),
                            rng.integers(0, 2, 2)]).astype(float)
    return x, command, modes


def _robot(command, modes):
    robot = np.zeros(1, dtype=R.ROBOT)[0]
    robot["command"] = command
    robot["hold"], robot["saturation"] = modes[0:3], modes[3:6]
    for name in ("critical", "side", "above", "inside"):
        robot[name] = modes[MODES.index(name)]
    return robot


def _close(symbolic, compiled):
    compiled = np.asarray(compiled, dtype=float)
    scale = np.maximum(np.abs(compiled), 1.0)
    return np.max(np.abs(np.asarray(symbolic, dtype=float).reshape(compiled.shape) - compiled) / scale)


@pytest.mark.parametrize("settings", CONFIGS, ids=lambda s: "-".join(f"{k}={v}" for k, v in s.items()))
def test_rhs_voltages_and_events_equal_the_compiled_model_in_every_mode(settings):
    params = DEFAULT_PARAMS
    p = params.to_record()
    model = symbolic_model(params, **settings)
    config = _config(**settings)
    rng = np.random.default_rng(0)
    cases = [_random_case(rng, settings["control"]) for _ in range(STATES)]
    xs, commands, modes = (np.array(column).T for column in zip(*cases))
    compiled = {"rhs": [], "voltages": [], "events": []}
    for i in range(STATES):
        robot = _robot(commands[:, i], modes[:, i])
        volts = np.zeros(3)
        compiled["rhs"].append(derivative(xs[:, i], robot, p, config, np.zeros(R.N_STATE), volts))
        compiled["voltages"].append(volts)
        compiled["events"].append(event_values(xs[:, i], robot, p, config, np.zeros(3), np.zeros(R.N_EVENTS)))
    worst = max(_close(getattr(model, name).map(STATES)(xs, commands, modes), np.array(values).T)
                for name, values in compiled.items())
    seen_modes = {tuple(column) for column in modes[:7].T}
    assert worst <= 1e-12
    assert len(seen_modes) > 500  # the draws cover the hold x saturation x critical combinations


def test_the_critical_rule_and_the_wall_switch_their_event_functions():
    config_off = _config("pd", True, False, True, critical_rule=R.CRIT_OFF)
    config_off["wall"] = False
    model = symbolic_model(control="pd", critical_rule="off", wall=False)
    x, command, modes = _random_case(np.random.default_rng(3), "pd")
    g = event_values(x, _robot(command, modes), DEFAULT_PARAMS.to_record(), config_off, np.zeros(3),
                     np.zeros(R.N_EVENTS))
    assert g[R.E_CRITICAL] == g[R.E_SIDE] == 1.0
    assert _close(model.events(x, command, modes), g) <= 1e-12


def test_free_model_is_the_voltage_mode_without_holds_and_tip_is_the_kinematics():
    params = DEFAULT_PARAMS.replace({"arm.load_mass": 1.0, "obstacle.x_position": 0.37})
    p = params.to_record()
    model = symbolic_model(params)
    config = _config("voltage", True, False, True)
    rng = np.random.default_rng(1)
    for _ in range(200):
        x, command, modes = _random_case(rng, "voltage")
        modes[:3] = 0.0
        volts = model.voltages(x, command, modes)
        expected = derivative(x, _robot(command, modes), p, config, np.zeros(R.N_STATE), np.zeros(3))
        assert _close(model.free(x[:9], volts), expected[:9]) <= 1e-12
        assert _close(model.tip(x[:3]), tip_position(x[0], x[1], x[2], p)) <= 1e-12


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="control must be one of"):
        symbolic_model(control="current")
    with pytest.raises(ValueError, match="critical_rule must be one of"):
        symbolic_model(critical_rule="sometimes")
    with pytest.raises(TypeError, match="params must be a ScaraParams"):
        symbolic_model({"arm.load_mass": 1.0})


@pytest.mark.parametrize("flag, value", [("widen", "yes"), ("exact_switches", 2)])
def test_the_symbolic_models_flags_are_booleans(flag, value):
    from scara_gym.model.symbolic import symbolic_model

    with pytest.raises(TypeError, match=f"{flag} must be True or False, got {value!r}"):
        symbolic_model(**{flag: value})
