"""Every public entry point answers bad input with a clear error.

Each case names the entry point, a call with one bad argument, and the words its message
must hold: the argument's name and its allowed range or choices. The error must be
raised by scara_gym's own checks (the innermost frame lies in the package), not by numpy,
numba or gymnasium deep inside, and rejected steps leave the environment as it was.
"""

import math
from pathlib import Path

import numpy as np
import pytest

import scara_gym
from scara_gym import Simulator, compare_forms, obstacle_avoidance, point_to_point
from scara_gym.envs import ScaraEnv
from scara_gym.envs.vector import ScaraVectorEnv
from scara_gym.model.simulator import start_state

PACKAGE = Path(scara_gym.__file__).parent
JOINTS = "q1, q2 in [-pi, pi] rad and q3 in [0, 0.4] m"
RTOL = "rtol must be a finite number in [1e-14, 0.01]"
ATOL = "atol must be a finite number in [1e-16, 0.01]"


def env(**kwargs):
    return lambda: ScaraEnv(**kwargs)


def reset(**kwargs):
    def call():
        ScaraEnv().reset(**kwargs)
    return call


def step(action):
    def call():
        e = ScaraEnv()
        e.reset(seed=0)
        e.step(action)
    return call


def vector(**kwargs):
    return lambda: ScaraVectorEnv(**kwargs)


def vector_reset(**kwargs):
    def call():
        ScaraVectorEnv(num_envs=2).reset(**kwargs)
    return call


def vector_step(actions, do_reset=True):
    def call():
        venv = ScaraVectorEnv(num_envs=2)
        if do_reset:
            venv.reset(seed=0)
        venv.step(actions)
    return call


def sb3(call_name, *args, **kwargs):
    def call():
        from scara_gym.integrations.sb3 import SB3VecEnv
        if call_name == "init":
            SB3VecEnv(*args, **kwargs)
            return
        venv = SB3VecEnv(num_envs=2)
        if call_name == "step_before_reset":
            venv.step(np.zeros((2, 3)))
        elif call_name == "step":
            venv.reset()
            venv.step(*args)
        elif call_name == "seed":
            venv.seed(*args)
            venv.reset()
    return call


def simulator(**kwargs):
    return lambda: Simulator(**kwargs)


def sim_call(method, *args, **kwargs):
    def call():
        sim = Simulator(record=0)
        if method != "advance_before_reset":
            if method == "reset":
                sim.reset(*args, **kwargs)
                return
            sim.reset(start_state(scara_gym.DEFAULT_PARAMS), command=(2.0, 2.0, 0.3))
            sim.advance(0.01)
        sim.advance(*args, **kwargs)
    return call


CASES = [
    # -- ScaraEnv / gym.make keyword arguments
    ("env control_mode name", env(control_mode="torque"), ["control_mode", "'pd', 'voltage'"]),
    ("env control_mode type", env(control_mode=1), ["control_mode", "'pd', 'voltage'"]),
    ("env obstacle text", env(obstacle="yes"), ["obstacle must be True or False"]),
    ("env obstacle int", env(obstacle=1), ["obstacle must be True or False"]),
    ("env collision", env(collision="bounce"), ["collision", "'terminate', 'penalty'"]),
    ("env randomize_target", env(randomize_target="no"), ["randomize_target must be True or False"]),
    ("env target q1 range", env(target=[5.0, 2.0, 0.3]), ["target", JOINTS, "5.0"]),
    ("env target q3 range", env(target=[2.0, 2.0, 0.5]), ["target", JOINTS]),
    ("env target shape", env(target=[2.0, 2.0]), ["target must be 3", "shape"]),
    ("env target nan", env(target=[2.0, 2.0, math.nan]), ["target must be 3 finite"]),
    ("env target complex", env(target=[2 + 1j, 2.0, 0.3]), ["target", "complex"]),
    ("env target text", env(target="far"), ["target must be 3 finite", "text"]),
    ("env start below", env(start=[0.0, 0.0, -0.1]), ["start", JOINTS]),
    ("env start far", env(start=[10.0, 0.0, 0.0]), ["start", JOINTS]),
    ("env reward_weights unknown", env(reward_weights={"speed": 1.0}), ["unknown terms", "progress"]),
    ("env reward_weights negative", env(reward_weights={"time": -1.0}), ["reward_weights.time", ">= 0"]),
    ("env reward_weights complex", env(reward_weights={"time": 1 + 1j}), ["reward_weights.time", ">= 0"]),
    ("env reward_weights type", env(reward_weights="heavy"), ["reward_weights must be", "progress"]),
    ("env control_dt zero", env(control_dt=0.0), ["control_dt", "[0.0001, 1] [s]"]),
    ("env control_dt nan", env(control_dt=math.nan), ["control_dt", "[0.0001, 1] [s]"]),
    ("env control_dt tiny", env(control_dt=1e-300), ["control_dt", "[0.0001, 1] [s]"]),
    ("env control_dt text", env(control_dt="0.01"), ["control_dt", "[0.0001, 1] [s]"]),
    ("env time_limit below control_dt", env(time_limit=0.001), ["time_limit", "[0.01, 10000]", "control_dt"]),
    ("env time_limit inf", env(time_limit=math.inf), ["time_limit", "[0.01, 10000]"]),
    ("env params negative mass", env(params={"arm.load_mass": -1.0}), ["arm.load_mass", "[0.001, 1000] [kg]"]),
    ("env params overflowing mass", env(params={"arm.load_mass": 1e300}), ["arm.load_mass", "[0.001, 1000] [kg]"]),
    ("env params huge gain", env(params={"axes.0.p_gain": 1e200}), ["axes.0.p_gain", "[0, 1e+06]"]),
    ("env params axes replaced", env(params={"axes": 5}), ["axes", "3 AxisParams"]),
    ("env params unknown field", env(params={"arm.weight": 1.0}), ["arm.weight", "link1_length"]),
    ("env params axis index", env(params={"axes.3.p_gain": 1.0}), ["axes.3.p_gain", "0..2"]),
    ("env params inductance", env(params={"axes.0.inductance": 1e-9}), ["axes.0.inductance", "[1e-06, 10] [H]"]),
    ("env params stiff motor", env(params={"axes.1.resistance": 1e4}), ["axes.1.resistance", "time constant", ">= 1e-05 s"]),
    ("env params dec", env(params={"obstacle.dec": 0.01}), ["obstacle.dec", "obstacle_avoidance", "DecHeuristic"]),
    ("env params type", env(params="c11"), ["params must be a ScaraParams or a dict"]),
    ("env params text value", env(params={"arm.gravity": "9.81"}), ["arm.gravity", "[0, 100]"]),
    ("env params key type", env(params={1: 2.0}), ["keys must be dotted paths"]),
    ("env params wide limits", env(params={"obstacle.wide_voltage_limits": (200, 0, 180)}),
     ["wide_voltage_limits", "[0.001, 10000]"]),
    ("env rtol loose", env(rtol=0.5), [RTOL]),
    ("env rtol one", env(rtol=1.0), [RTOL]),
    ("env rtol zero", env(rtol=0), [RTOL]),
    ("env rtol below float64", env(rtol=1e-16), [RTOL]),
    ("env atol negative", env(atol=-1.0), [ATOL]),
    ("env atol nan", env(atol=math.nan), [ATOL]),
    ("env exact_switches", env(exact_switches="yes"), ["exact_switches must be True or False"]),
    ("env tolerance_weights zero", env(tolerance_weights={"current": 0.0}),
     ["tolerance_weights['current']", "[0.001, 1000]"]),
    ("env tolerance_weights nan", env(tolerance_weights={"q": math.nan}), ["tolerance_weights['q']", "[0.001, 1000]"]),
    ("env tolerance_weights group", env(tolerance_weights={"voltage": 2.0}),
     ["unknown tolerance_weights ['voltage']", "'current', 'energy', 'q', 'rate'"]),
    ("env tolerance_weights list", env(tolerance_weights=[1.0, 2.0]), ["tolerance_weights must be a dict"]),
    ("env render_mode", env(render_mode="ascii"), ["render_mode", "rgb_array"]),
    # -- reset
    ("reset seed float", reset(seed=1.5), ["seed must be an integer >= 0"]),
    ("reset seed negative", reset(seed=-1), ["seed must be an integer >= 0"]),
    ("reset seed text", reset(seed="abc"), ["seed must be an integer >= 0"]),
    ("reset options text", reset(options="x"), ["reset options must be a dict", "start", "target"]),
    ("reset options unknown", reset(options={"goal": [1, 2, 3]}), ["unknown reset options", "target"]),
    ("reset options target nan", reset(options={"target": [math.nan, 2.0, 0.3]}), ["options['target']", "finite"]),
    ("reset options target range", reset(options={"target": [4.0, 2.0, 0.3]}), ["options['target']", JOINTS]),
    ("reset options start shape", reset(options={"start": [0.0, 0.0]}), ["options['start'] must be 3"]),
    ("reset options start at target", reset(options={"start": [2.0, 2.0, 0.3]}), ["already within acc"]),
    # -- step
    ("step short", step(np.zeros(2)), ["action must be 3", "shape (3,)"]),
    ("step column", step(np.zeros((3, 1))), ["action must be 3", "shape (3,)"]),
    ("step nan", step(np.array([0.0, math.nan, 0.0])), ["action must be 3 finite", "[-1, 1]"]),
    ("step inf", step(np.array([math.inf, 0.0, 0.0])), ["action must be 3 finite", "[-1, 1]"]),
    ("step text", step("fast"), ["action must be 3 finite", "text"]),
    ("step complex", step(np.array([1j, 0.0, 0.0])), ["action", "complex"]),
    ("step object", step([1.0, None, 0.0]), ["action", "non-numeric"]),
    ("step bool", step(np.array([True, False, True])), ["action", "boolean"]),
    ("step mixed text", step([0.0, "a", 0.0]), ["action", "text"]),
    ("step before reset", lambda: ScaraEnv().step(np.zeros(3)), ["call reset() before step()"]),
    # -- native vector environment
    ("vector num_envs zero", vector(num_envs=0), ["num_envs must be an integer >= 1"]),
    ("vector num_envs float", vector(num_envs=2.0), ["num_envs must be an integer >= 1"]),
    ("vector max_episode_steps", vector(max_episode_steps=0), ["max_episode_steps must be an integer >= 1"]),
    ("vector autoreset_mode", vector(autoreset_mode="Sometimes"), ["autoreset_mode", "NextStep", "SameStep"]),
    ("vector num_threads", vector(num_threads=0), ["num_threads must be an integer in [1, "]),
    ("vector render_mode", vector(render_mode="rgb_array"), ["does not render", "render_mode=None"]),
    ("vector rtol", vector(rtol=0.2), [RTOL]),
    ("vector step before reset", vector_step(np.zeros((2, 3)), do_reset=False), ["call reset() before step()"]),
    ("vector reset seed float", vector_reset(seed=1.5), ["seed must be an integer >= 0"]),
    ("vector reset seed list length", vector_reset(seed=[1, 2, 3]), ["seed must be None, an integer >= 0 or a list of 2"]),
    ("vector reset seed list entry", vector_reset(seed=[1, "a"]), ["seed[1] must be an integer >= 0"]),
    ("vector reset options text", vector_reset(options="x"), ["reset options must be a dict"]),
    ("vector reset options target", vector_reset(options={"target": [2.0, 2.0, 9.0]}), ["options['target']", JOINTS]),
    ("vector step shape", vector_step(np.zeros(3)), ["action must be 2x3", "shape (2, 3)"]),
    ("vector step nan", vector_step(np.full((2, 3), math.nan)), ["action must be 2x3 finite"]),
    ("vector step complex", vector_step(np.zeros((2, 3), dtype=complex)), ["action", "complex"]),
    # -- stable-baselines3 adapter
    ("sb3 num_envs", sb3("init", num_envs=0), ["num_envs must be an integer >= 1"]),
    ("sb3 step before reset", sb3("step_before_reset"), ["call reset() before step()"]),
    ("sb3 step shape", sb3("step", np.zeros((3, 3))), ["action must be 2x3", "shape (2, 3)"]),
    ("sb3 seed float", sb3("seed", 1.5), ["seed", "integer >= 0"]),
    ("sb3 control_mode", sb3("init", num_envs=2, control_mode="torque"), ["control_mode", "'pd', 'voltage'"]),
    # -- the simulation API
    ("point_to_point t_end zero", lambda: point_to_point(t_end=0.0), ["t_end", "(0, 1000] [s]"]),
    ("point_to_point t_end nan", lambda: point_to_point(t_end=math.nan), ["t_end", "(0, 1000] [s]"]),
    ("point_to_point t_end negative", lambda: point_to_point(t_end=-1.0), ["t_end", "(0, 1000] [s]"]),
    ("point_to_point form", lambda: point_to_point(form="semi-implicit"), ["form", "'explicit', 'implicit'"]),
    ("point_to_point q0", lambda: point_to_point(q0=[0.0, math.nan, 0.0]), ["q0 must be 3 finite"]),
    ("point_to_point rtol", lambda: point_to_point(rtol=0.5), [RTOL]),
    ("point_to_point params", lambda: point_to_point(params="c11"), ["params must be a ScaraParams or a dict"]),
    ("obstacle_avoidance variant", lambda: obstacle_avoidance(variant="jump"), ["variant", "'restart'"]),
    ("obstacle_avoidance dec zero", lambda: obstacle_avoidance(dec=0.0), ["obstacle.dec", "(0, 1]"]),
    ("obstacle_avoidance dec two", lambda: obstacle_avoidance(dec=2.0), ["obstacle.dec", "(0, 1]"]),
    ("compare_forms repeats", lambda: compare_forms(repeats=0), ["repeats must be an integer >= 1"]),
    # -- Simulator
    ("Simulator stop text", simulator(stop="target"), ["stop must be a tuple", "collision"]),
    ("Simulator stop name", simulator(stop=("wall",)), ["stop must be one of", "'target'"]),
    ("Simulator max_steps", simulator(max_steps=0), ["max_steps must be an integer in [1, "]),
    ("Simulator max_step", simulator(max_step=0.0), ["max_step", "(0, 1] [s]"]),
    ("Simulator record", simulator(record=-1), ["record must be an integer in [0, "]),
    ("Simulator max_events", simulator(max_events=0), ["max_events must be an integer in [1, "]),
    ("Simulator widen", simulator(widen="yes"), ["widen must be True or False"]),
    ("Simulator critical", simulator(critical="sometimes"), ["critical must be one of", "'switch'"]),
    ("Simulator atol", simulator(atol=0.5), [ATOL]),
    ("Simulator advance before reset", sim_call("advance_before_reset", 1.0), ["call reset(x0) before advance()"]),
    ("Simulator reset size", sim_call("reset", np.zeros(9)), ["initial state must be 10", "shape"]),
    ("Simulator reset t0", sim_call("reset", np.zeros(10), t0=math.nan), ["t0 must be a finite number"]),
    ("Simulator advance nan", sim_call("advance", math.nan), ["t_end", "not before the simulator's time"]),
    ("Simulator advance backwards", sim_call("advance", 0.001), ["t_end", ">= 0.01"]),
    ("Simulator advance command", sim_call("advance", 0.02, command=[1.0, 2.0]), ["command must be 3"]),
]


def test_the_catalogue_is_large_and_its_names_are_unique():
    names = [name for name, _, _ in CASES]
    assert len(names) >= 60
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("name, call, words", CASES, ids=[c[0] for c in CASES])
def test_bad_input_gets_a_clear_error(name, call, words):
    with pytest.raises((ValueError, TypeError, KeyError, RuntimeError)) as info:
        call()
    message = str(info.value)
    for word in words:
        assert word in message, f"{name}: {word!r} not in {message!r}"
    innermost = Path(info.traceback[-1].path)
    assert PACKAGE in innermost.parents, f"{name}: raised in {innermost}, not by scara_gym's checks"


GOOD = np.array([0.3, -0.2, 0.5])
BAD_ACTIONS = [np.array([0.0, math.nan, 0.0]), np.array([1j, 0.0, 0.0]), np.zeros(2), "fast",
               [1.0, None, 0.0], np.array([math.inf, 0.0, 0.0], dtype=np.float32)]


@pytest.mark.parametrize("control_mode", ["pd", "voltage"])
def test_a_rejected_step_changes_nothing(control_mode):
    env, twin = ScaraEnv(control_mode=control_mode), ScaraEnv(control_mode=control_mode)
    env.reset(seed=3)
    twin.reset(seed=3)
    for _ in range(20):  # a few steps in, so that rates, currents and the step size are set
        env.step(GOOD)
        twin.step(GOOD)
    state, time = env.state, env.time
    for bad in BAD_ACTIONS:
        with pytest.raises(ValueError):
            env.step(bad)
        assert np.array_equal(env.state, state) and env.time == time
    for _ in range(5):
        assert np.array_equal(env.step(GOOD)[0], twin.step(GOOD)[0])
    assert np.array_equal(env.state, twin.state)


def test_a_rejected_vector_step_or_reset_changes_nothing():
    venv, twin = ScaraVectorEnv(num_envs=3), ScaraVectorEnv(num_envs=3)
    venv.reset(seed=5)
    twin.reset(seed=5)
    actions = np.tile(GOOD, (3, 1))
    venv.step(actions)
    twin.step(actions)
    before = venv._task.robots.copy()
    for bad in (np.full((3, 3), math.nan), np.zeros((2, 3)), np.zeros((3, 3), dtype=complex)):
        with pytest.raises(ValueError):
            venv.step(bad)
    with pytest.raises(ValueError):
        venv.reset(options={"target": [2.0, 2.0, 9.0]})
    assert venv._task.robots.tobytes() == before.tobytes()
    for _ in range(5):
        assert np.array_equal(venv.step(actions)[0], twin.step(actions)[0])


def test_numpy_scalars_are_numbers():
    env = ScaraEnv(control_dt=np.float64(0.01), time_limit=np.float32(3.0), rtol=np.float64(1e-5),
                   atol=np.float32(1e-6), obstacle=np.bool_(True),
                   reward_weights={"time": np.float32(5.0)}, params={"arm.load_mass": np.float32(1.0)},
                   target=(np.float64(2.0), np.int64(2), np.float32(0.3)))
    obs, _ = env.reset(seed=np.int64(1), options={"start": np.zeros(3, dtype=np.float32)})
    assert env.observation_space.contains(obs)
    env.step([np.float32(0.1), np.float64(0.2), np.int64(0)])
    venv = ScaraVectorEnv(num_envs=np.int64(2), max_episode_steps=np.int32(10))
    venv.reset(seed=np.int64(3))
    venv.reset(seed=[np.int64(1), None])
    assert env.reward_weights.time == 5.0 and env.params.arm.load_mass == 1.0
