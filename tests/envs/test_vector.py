"""The native vector environment and its stable-baselines3 adapter."""

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401
from scara_gym.envs.vector import ScaraVectorEnv


def make_vec(n, **kwargs):
    return gym.make_vec("Scara-C11-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("kwargs", [
    dict(control_mode="voltage", collision="penalty", randomize_target=True),
    dict(control_mode="pd", randomize_target=True),
    dict(control_mode="pd", obstacle=False),
    dict(control_mode="pd", randomize_target=True, observation_noise={"q": 1e-3, "current": 0.05},
         action_delay=2, action_rate_limit=30.0),
])
def test_each_sub_environment_is_the_single_environment(kwargs):
    n, seed, horizon = 4, 21, 320
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.2, 1.2, size=(horizon, n, 3))
    if kwargs["control_mode"] == "pd":  # head for the target, so that episodes end by success too
        actions = np.clip(actions * 0.1 + np.array([2 / np.pi, 2 / np.pi, 0.5]), -1, 1)
    venv = make_vec(n, **kwargs)
    obs, _ = venv.reset(seed=seed)
    vec_obs, vec_rew, vec_term, vec_trunc, vec_clipped = [obs], [], [], [], []
    for k in range(horizon):
        obs, rew, term, trunc, info = venv.step(actions[k])
        vec_obs.append(obs), vec_rew.append(rew), vec_term.append(term), vec_trunc.append(trunc)
        vec_clipped.append(info["clipped_actions"])
    ended = 0
    for i in range(n):
        env = gym.make("Scara-C11-v0", **kwargs)
        obs, _ = env.reset(seed=seed + i)
        assert np.array_equal(obs, vec_obs[0][i])
        for k in range(horizon):
            obs, rew, term, trunc, info = env.step(actions[k, i])
            assert np.array_equal(obs, vec_obs[k + 1][i]), (i, k)
            assert info["clipped_actions"] == vec_clipped[k][i]
            assert rew == vec_rew[k][i] and term == vec_term[k][i] and trunc == vec_trunc[k][i]
            if term or trunc:
                ended += 1
                # NextStep autoreset: the following step resets with reward 0
                assert vec_rew[k + 1][i] == 0.0 and not vec_term[k + 1][i]
                break
    assert ended >= 1
    if kwargs["control_mode"] == "voltage":  # actions beyond [-1, 1] were counted alike
        assert sum(int(c.sum()) for c in vec_clipped) > 0


def test_same_step_autoreset_returns_the_final_observation_in_info():
    venv = ScaraVectorEnv(num_envs=3, autoreset_mode="SameStep", control_mode="pd")
    venv.reset(seed=0)
    action = np.tile(venv.setpoint_to_action([2.0, 2.0, 0.3]), (3, 1))
    for _ in range(100):  # plain PD hits the wall at about 0.36 s
        obs, _, term, trunc, info = venv.step(action)
        if term.any():
            break
    assert term.all() and info["collision"].all()
    assert info["_final_obs"].all()
    assert np.all(info["final_obs"][:, 0] > 0.3)  # q1 at the wall, not the reset q1 = 0
    assert np.allclose(obs[:, :3], 0.0)  # already reset


def test_bad_vector_input():
    venv = ScaraVectorEnv(num_envs=2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 3\)"):
        venv.step(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        venv.step(np.full((2, 3), np.nan))
    with pytest.raises(ValueError, match="num_envs"):
        ScaraVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        ScaraVectorEnv(num_envs=2, autoreset_mode="Sometimes")
    with pytest.raises(ValueError, match="control_mode"):
        ScaraVectorEnv(num_envs=2, control_mode="torque")


def test_thread_count_does_not_change_the_rollouts():
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (30, 6, 3))
    runs = []
    for threads in (1, None):
        venv = ScaraVectorEnv(num_envs=6, control_mode="voltage", num_threads=threads)
        obs, _ = venv.reset(seed=3)
        runs.append([obs] + [venv.step(a)[0] for a in actions])
    assert all(np.array_equal(a, b) for a, b in zip(*runs))


THREADS_STARTED = """
import os, sys
import numpy as np
from scara_gym.envs.vector import ScaraVectorEnv

venv = ScaraVectorEnv(num_envs=8, control_mode="voltage", num_threads=int(sys.argv[1]))
venv.reset(seed=0)
before = len(os.listdir("/proc/self/task"))
for _ in range(20):
    venv.step(np.random.default_rng(0).uniform(-1, 1, (8, 3)))
print(len(os.listdir("/proc/self/task")) - before)
"""


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads through Linux's /proc")
def test_a_one_thread_vector_env_starts_no_thread_pool():
    # a parallel loop run with one thread still wakes numba's pool, whose idle OpenMP worker
    # then spins on a core: the one-thread env steps on the calling thread alone
    env = {**os.environ, "NUMBA_NUM_THREADS": "2"}
    started = {}
    for threads in (1, 2):
        done = subprocess.run([sys.executable, "-c", THREADS_STARTED, str(threads)], env=env, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        started[threads] = int(done.stdout.split()[-1])
    assert started == {1: 0, 2: started[2]} and started[2] > 0, started  # two threads: the pool starts


def test_thread_count_and_reset_are_checked():
    with pytest.raises(ValueError, match=r"num_threads must be an integer in \[1, "):
        ScaraVectorEnv(num_envs=2, num_threads=0)
    with pytest.raises(RuntimeError, match="reset"):
        ScaraVectorEnv(num_envs=2).step(np.zeros((2, 3)))


THREADED_STEPS = """
import threading
import numba
import numpy as np
from scara_gym.envs.vector import ScaraVectorEnv

def rollout(seed, out):
    venv = ScaraVectorEnv(num_envs=16, control_mode="voltage")
    venv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    rewards = [venv.step(rng.uniform(-1, 1, (16, 3)))[1] for _ in range(60)]
    out[seed] = np.array(rewards)

threaded, sequential = {}, {}
threads = [threading.Thread(target=rollout, args=(seed, threaded)) for seed in (1, 2, 3)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
for seed in (1, 2, 3):
    rollout(seed, sequential)
assert numba.threading_layer() == "workqueue", numba.threading_layer()
assert all(np.array_equal(threaded[s], sequential[s]) for s in (1, 2, 3))
print("ok")
"""


def test_vector_envs_stepped_from_several_threads_under_the_workqueue_layer():
    # numba's workqueue layer aborts the process on concurrent parallel calls; the vector env
    # serializes its parallel step, so this runs and matches sequential stepping
    env = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue", "NUMBA_NUM_THREADS": "2"}
    done = subprocess.run([sys.executable, "-c", THREADED_STEPS], env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("ok")


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_an_autoreset_that_cannot_start_a_robot_resets_none_and_names_it(mode, monkeypatch):
    venv = ScaraVectorEnv(num_envs=3, max_episode_steps=2, autoreset_mode=mode, randomize_target=True)
    venv.reset(seed=0)
    actions = np.zeros((3, 3))
    venv.step(actions)
    if mode == "NextStep":
        venv.step(actions)  # every robot's episode ends here; the next step resets them
    task, real = venv._task, venv._task.episode_start
    calls = []

    def second_fails(rng, options):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("randomize_target: no target in the documented region passes the wall rules")
        return real(rng, options)

    monkeypatch.setattr(task, "episode_start", second_fails)
    states = [rng.bit_generator.state for rng in venv._rngs]
    targets, x = venv.targets, task.robots["x"].copy()
    with pytest.raises(RuntimeError, match="autoreset: robot 1's next episode cannot start .*no robot of this step"):
        venv.step(actions)
    assert [rng.bit_generator.state for rng in venv._rngs] == states  # no draw was kept
    assert np.array_equal(venv.targets, targets)  # robot 0's draw did not start its episode
    if mode == "NextStep":
        assert np.array_equal(task.robots["x"], x)  # the step was refused whole
    else:
        assert (task.outcomes["episode_steps"] == 2).all()  # stepped, none reset
    monkeypatch.setattr(task, "episode_start", real)
    venv.step(actions)  # the same resets, drawn again from the same generators
    assert not np.array_equal(venv.targets, targets)


@pytest.mark.parametrize("kwargs", [
    dict(control_mode="pd", randomize_target=True),
    dict(control_mode="pd", randomize_target=True, observation_noise={"q": 1e-3}, action_delay=1),
])
def test_disabled_autoreset_resets_exactly_the_masked_robots_as_single_envs(kwargs):
    """With autoreset off, reset(options={"reset_mask": m}) resets the robots of m, each bit for
    bit as the single env reset with the same seed, and leaves the other robots' episodes
    (their state and noise draws) as they were."""
    n, horizon = 4, 260
    rng = np.random.default_rng(5)
    # head for the target with noise: episodes end at different steps (success or collision)
    actions = np.clip(rng.normal(0, 0.3, (horizon, n, 3)) + np.array([2 / np.pi, 2 / np.pi, 0.5]), -1, 1)
    venv = gym.make_vec("Scara-C11-v2", num_envs=n, vectorization_mode="vector_entry_point",
                        autoreset_mode="Disabled", **kwargs)
    singles = [gym.make("Scara-C11-v2", **kwargs) for _ in range(n)]
    seeds = iter(range(100, 10_000))
    first = [next(seeds) for _ in range(n)]
    obs, _ = venv.reset(seed=first)
    for i, env in enumerate(singles):
        assert np.array_equal(env.reset(seed=first[i])[0], obs[i])
    resets = 0
    for k in range(horizon):
        obs, reward, terminated, truncated, info = venv.step(actions[k])
        done = terminated | truncated
        for i, env in enumerate(singles):
            single = env.step(actions[k, i])
            assert np.array_equal(single[0], obs[i]) and single[1:4] == (reward[i], terminated[i], truncated[i])
        if done.any():
            with pytest.raises(RuntimeError, match=rf"robots \[{', '.join(map(str, np.flatnonzero(done)))}\]"):
                venv.step(actions[k])  # an ended robot is not stepped silently
            seed = [next(seeds) if d else None for d in done]
            before = obs.copy()
            obs, info = venv.reset(seed=seed, options={"reset_mask": done})
            resets += int(done.sum())
            assert np.array_equal(info["_target"], done)
            assert np.array_equal(obs[~done], before[~done])  # the others untouched
            for i in np.flatnonzero(done):
                assert np.array_equal(singles[i].reset(seed=seed[i])[0], obs[i])
    assert resets >= 2


def test_reset_mask_is_checked():
    venv = ScaraVectorEnv(num_envs=2, autoreset_mode="Disabled")
    with pytest.raises(RuntimeError, match="without a mask first"):
        venv.reset(options={"reset_mask": np.array([True, False])})
    venv.reset(seed=0)
    for bad in (np.array([1, 0]), np.array([False, False]), np.array([True]), [True, False]):
        with pytest.raises(ValueError, match=r"reset_mask'\] must be a numpy bool array of shape \(2,\)"):
            venv.reset(options={"reset_mask": bad})
    with pytest.raises(ValueError, match="needs autoreset_mode='Disabled'"):
        ScaraVectorEnv(num_envs=2).reset(options={"reset_mask": np.array([True, False])})


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep", "Disabled"])
def test_gymnasium_vector_wrappers_in_every_autoreset_mode(autoreset_mode):
    from gymnasium.wrappers.vector import (
        ClipAction,
        DtypeObservation,
        NormalizeObservation,
        NormalizeReward,
        RecordEpisodeStatistics,
    )

    venv = gym.make_vec("Scara-C11-v2", num_envs=3, vectorization_mode="vector_entry_point",
                        autoreset_mode=autoreset_mode, control_mode="pd")
    inner = ClipAction(venv)
    # Gymnasium's own rules: NormalizeObservation takes NextStep only, its per-step observation
    # transforms NextStep or Disabled, and neither SameStep
    if autoreset_mode == "NextStep":
        inner = NormalizeObservation(inner)
    elif autoreset_mode == "Disabled":
        inner = DtypeObservation(inner, np.float64)
    else:
        with pytest.raises(ValueError, match="NEXT_STEP or DISABLED"):
            DtypeObservation(inner, np.float64)
    wrapped = RecordEpisodeStatistics(NormalizeReward(inner))
    obs, _ = wrapped.reset(seed=0)
    action = np.tile(venv.unwrapped.setpoint_to_action([2.0, 2.0, 0.3]), (3, 1))  # plain PD: the wall
    ended = 0
    for _ in range(80):
        obs, reward, terminated, truncated, info = wrapped.step(action)
        assert obs.shape == (3, 18) and np.isfinite(obs).all() and np.isfinite(reward).all()
        done = terminated | truncated
        if done.any():
            ended += 1
            assert info["_episode"][done].all() and (info["episode"]["l"][done] > 0).all()
            if autoreset_mode == "Disabled":
                wrapped.reset(options={"reset_mask": done})
    assert ended >= 1
