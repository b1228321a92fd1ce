"""The nonlinear MPC: it reaches the C11 target without a collision, refuses what it cannot do,
warm-starts, and models the robot it is given."""

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401
from scara_gym import DEFAULT_PARAMS

pytest.importorskip("casadi")
from agents.experiments.evaluation import make_policy, mpc_episodes  # noqa: E402
from agents.policies.mpc import MPCConfig, MPCPolicy  # noqa: E402
from scara_gym.benchmark.protocol import get_condition  # noqa: E402
from scara_gym.model import records as R  # noqa: E402
from scara_gym.model.dynamics import derivative  # noqa: E402

ENV_ID = "Scara-C11-v1"
SHORT = MPCConfig(horizon=15)
"""a short test configuration: 0.15 s predicted"""
OPTIMAL_TIME = 1.2241  # s, the minimum-time reference's replay of the C11 episode in the exact ids


def voltage_env(**kwargs):
    return gym.make(ENV_ID, control_mode="voltage", **kwargs)


def test_infeasible_or_unsupported_configurations_are_refused_by_name():
    with pytest.raises(ValueError, match="leaves no critical band"):
        MPCPolicy(voltage_env(), MPCConfig(horizon=5, wall_margin=0.015, band_inset=0.005))
    for field, value in (("horizon", 1), ("wall_margin", -0.01), ("approach_rate", 0.0), ("penalty", float("nan")),
                         ("solver", "snopt")):
        with pytest.raises((ValueError, TypeError), match=field):
            MPCConfig(**{field: value})
    with pytest.raises(ValueError, match="weights must be 3"):
        MPCConfig(weights=(1.0, 2.0))
    with pytest.raises(ValueError, match=r"weights must be 3 finite numbers with every entry >= 0, got \[1.0, -2.0, 3.0\]"):
        MPCConfig(weights=(1.0, -2.0, 3.0))
    assert MPCConfig(weights=[1, 2, 3]).weights == (1.0, 2.0, 3.0)  # a lower bound alone: no upper one needed
    with pytest.raises(TypeError, match="params must be a ScaraParams"):
        MPCConfig(params={"arm.load_mass": 1.0})
    with pytest.raises(ValueError, match="the MPC is given as mpc"):
        make_policy("mpc:horizon=10", voltage_env())


def test_in_pd_mode_it_commands_the_set_point_that_gives_its_voltages_and_reaches_the_target(tmp_path):
    voltage, pd = voltage_env(), gym.make(ENV_ID, control_mode="pd")
    task = pd.unwrapped
    for seed in (0, 5):
        obs, _ = voltage.reset(seed=seed, options={"start": [0.1 * seed, -0.05 * seed, 0.02]})
        obs_pd, _ = pd.reset(seed=seed, options={"start": [0.1 * seed, -0.05 * seed, 0.02]})
        assert np.array_equal(obs, obs_pd)
        planned = MPCPolicy(voltage, SHORT)(obs)  # the same problem, the same plan
        action = MPCPolicy(pd, SHORT)(obs_pd)
        applied = task.pd_action(obs_pd, task.action_to_setpoint(action))  # the PD law's voltages, as actions
        free = np.abs(planned) < 0.999
        assert free.any() or seed == 0
        assert np.allclose(applied[free], planned[free], atol=1e-9)
        assert np.array_equal(np.sign(applied[~free]), np.sign(planned[~free])) and np.all(np.abs(applied[~free]) == 1.0)
    result = mpc_episodes(get_condition("c11"), cache=tmp_path, config=SHORT, mode="pd")
    assert result["success"].tolist() == [True] and result["collisions"].tolist() == [0]
    assert OPTIMAL_TIME <= result["reach_time"][0] < 1.5
    assert mpc_episodes(get_condition("c11"), cache=tmp_path, config=SHORT)["reach_time"][0] != result["reach_time"][0]


def test_the_warm_start_is_the_previous_plan_one_step_on_and_saves_iterations():
    env = voltage_env()
    policy = MPCPolicy(env, SHORT)
    obs, _ = env.reset(seed=0)
    policy.reset()
    warm, cold = [], []
    for k in range(20):
        if k >= 10:
            plan = policy.guess.copy()  # the shifted solution this step starts from
            head, stage, n = policy.HEAD, policy.STAGE, SHORT.horizon
            assert np.array_equal(plan[head + stage * (n - 2):head + stage * (n - 1)], plan[head + stage * (n - 1):head + stage * n])
            fresh = MPCPolicy(env, MPCConfig(horizon=15, first_passes=1))
            fresh(obs)  # the same state from a constant guess
            cold.append(fresh.solver.stats()["iter_count"])
        action = policy(obs)
        if k >= 10:
            warm.append(policy.solver.stats()["iter_count"])
        obs, *_ = env.step(action)
    assert sum(warm) < sum(cold)


def test_the_model_parameters_option_models_another_robot():
    heavy = DEFAULT_PARAMS.replace({"arm.load_mass": 2.0, "axes.0.resistance": 4.5})
    env = voltage_env(params=heavy)
    nominal, matched = MPCPolicy(env, MPCConfig(horizon=5)), MPCPolicy(env, MPCConfig(horizon=5, params=heavy))
    assert nominal.params == DEFAULT_PARAMS and matched.params == heavy  # the default: the nominal robot
    state, volts = np.array([0.3, 0.5, 0.1, 1.0, -0.5, 0.2, 2.0, -1.0, 0.5]), np.array([50.0, -20.0, 60.0])
    config = np.zeros(1, dtype=R.CONFIG)[0]
    config["control"] = R.CONTROL_VOLTAGE
    robot = np.zeros(1, dtype=R.ROBOT)[0]
    robot["command"] = volts / heavy.voltage_limits
    expected = derivative(np.append(state, 0.0), robot, heavy.to_record(), config, np.zeros(R.N_STATE), np.zeros(3))[:9]
    assert np.allclose(np.array(matched.model.free(state, volts)).ravel(), expected, rtol=1e-12, atol=1e-9)
    assert not np.allclose(np.array(nominal.model.free(state, volts)).ravel(), expected, rtol=1e-3)
    obs, _ = env.reset(seed=0)
    assert not np.allclose(nominal(obs), matched(obs))  # the plans differ with the model


def test_the_mpc_reaches_the_c11_target_without_a_collision_and_its_episodes_are_cached(tmp_path):
    condition = get_condition("c11")
    first = mpc_episodes(condition, cache=tmp_path, config=SHORT)
    assert first["success"].tolist() == [True] and first["collisions"].tolist() == [0]
    assert OPTIMAL_TIME <= first["reach_time"][0] < 1.5  # above the optimum, below the tuned heuristic's 1.50 s
    t = first["solve_time"]
    assert t["failures"] == 0 and t["solves"] == first["solve_times"].size >= first["reach_time"][0] / 0.01
    assert 0 < t["median"] <= t["p95"] <= t["worst"]
    again = mpc_episodes(condition, cache=tmp_path, config=SHORT)
    assert again["reach_time"].tolist() == first["reach_time"].tolist()
    assert np.array_equal(again["solve_times"], first["solve_times"])  # read back, not re-run
    assert len(list(tmp_path.iterdir())) == 1


def test_the_mpc_refuses_a_config_of_the_wrong_type_by_name():
    with pytest.raises(TypeError, match="solver_options must be a dict of CasADi solver options, got 'fast'"):
        MPCConfig(solver_options="fast")
    with pytest.raises(TypeError, match="config must be an MPCConfig or None, got 'fast'"):
        MPCPolicy(gym.make("Scara-C11-v1", control_mode="voltage"), config="fast")
