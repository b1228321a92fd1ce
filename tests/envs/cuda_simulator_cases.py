"""The CUDA vector env against the CPU vector env, run under numba's CUDA simulator.

Not collected on its own (no ``test_`` prefix): tests/envs/test_cuda_vector.py runs this file
in a pytest subprocess with ``NUMBA_ENABLE_CUDASIM=1``, which numba reads at import. Under the
simulator the kernels call the same CPU-compiled functions, so everything is bit for bit.
"""

import gymnasium as gym
import numba
import numpy as np
import pytest
import torch

import scara_gym  # noqa: F401
from scara_gym.envs.cuda_vector import ScaraCudaVectorEnv

pytestmark = pytest.mark.skipif(not numba.config.ENABLE_CUDASIM, reason="needs NUMBA_ENABLE_CUDASIM=1")

CONFIGS = {
    # collisions (terminating) and successes, random targets drawn ahead in plan rings
    "pd-random": dict(control_mode="pd", randomize_target=True),
    # successes without the wall
    "pd-free": dict(control_mode="pd", obstacle=False),
    # truncations: a short time limit, collisions as penalties
    "voltage": dict(control_mode="voltage", collision="penalty", max_episode_steps=40),
    # parameters drawn per episode (plans carry parameter records), on v1's exact switches
    "physics": dict(control_mode="pd", randomize_params="physics", randomize_target=True, exact_switches=True,
                    rtol=1e-6, atol=1e-8),
    # the wall drawn per episode (Scara-C11-RandomWall-v0's preset)
    "wall": dict(control_mode="pd", randomize_params="wall", randomize_target=True),
    # starts drawn per episode (the protocol's start region), carried by the plans
    "starts": dict(control_mode="voltage", randomize_start=True, randomize_target=True, collision="penalty",
                   max_episode_steps=40),
    # sim-to-real actuation on the device: dead time and slew limit, clipped actions counted
    "delay-slew": dict(control_mode="pd", randomize_target=True, action_delay=2, action_rate_limit=30.0),
    "voltage-slew": dict(control_mode="voltage", collision="penalty", max_episode_steps=40, action_delay=1,
                         action_rate_limit=50.0),
}


def pair(name, autoreset_mode, n=4, **extra):
    kwargs = dict(CONFIGS[name], **extra)
    make = lambda **device: gym.make_vec("Scara-C11-v0", num_envs=n, vectorization_mode="vector_entry_point",  # noqa: E731
                                         autoreset_mode=autoreset_mode, **device, **kwargs)
    return make(), make(device="cuda")


def actions_for(name, rng, n):
    if CONFIGS[name]["control_mode"] == "pd":  # head for the target with kicks: successes and collisions
        kicks = rng.random((n, 1)) < 0.05
        return np.array([2 / np.pi, 2 / np.pi, 0.5]) + rng.normal(0.0, 0.5, (n, 3)) * kicks
    return rng.uniform(-1.2, 1.2, (n, 3))


def assert_same(cpu_value, gpu_value, where):
    if isinstance(cpu_value, dict):
        assert set(cpu_value) == set(gpu_value), where
        for key in cpu_value:
            assert_same(cpu_value[key], gpu_value[key], f"{where}[{key}]")
        return
    assert isinstance(gpu_value, torch.Tensor), f"{where}: {type(gpu_value)} is not a tensor"
    gpu = gpu_value.numpy()
    cpu = np.asarray(cpu_value)
    assert gpu.dtype == cpu.dtype, f"{where}: dtype {gpu.dtype} != {cpu.dtype}"
    assert np.array_equal(cpu, gpu, equal_nan=cpu.dtype.kind == "f"), f"{where}: {cpu} != {gpu}"


# Not the full product (each case is 7-17 s on the simulator): every config meets one autoreset
# mode, and every way an episode ends meets both (collisions: pd-random, wall against physics,
# delay-slew; truncations: voltage, voltage-slew against starts; successes: pd-free in both).
ENV_CASES = [("pd-random", "NextStep"), ("wall", "NextStep"), ("physics", "SameStep"), ("delay-slew", "SameStep"),
             ("voltage", "NextStep"), ("voltage-slew", "NextStep"), ("starts", "SameStep"),
             ("pd-free", "NextStep"), ("pd-free", "SameStep")]

ENDS = {"pd-random": "collisions", "pd-free": "successes", "voltage": "truncations", "physics": "collisions",
        "wall": "collisions", "delay-slew": "collisions", "voltage-slew": "truncations", "starts": "truncations"}
"""how a config's episodes end, which its case asserts happened"""


def test_the_env_cases_cover_every_config_and_every_episode_end_in_both_autoreset_modes():
    assert {name for name, _ in ENV_CASES} == set(CONFIGS)
    assert {mode for _, mode in ENV_CASES} == {"NextStep", "SameStep"}
    assert set(ENDS) == set(CONFIGS)
    assert {(ENDS[name], mode) for name, mode in ENV_CASES} == {
        (end, mode) for end in set(ENDS.values()) for mode in ("NextStep", "SameStep")}


@pytest.mark.parametrize(("name", "autoreset_mode"), ENV_CASES)
def test_the_cuda_env_is_the_cpu_env_bit_for_bit(name, autoreset_mode):
    n, steps = 4, 200
    cpu, gpu = pair(name, autoreset_mode, n)
    assert isinstance(gpu, ScaraCudaVectorEnv)
    obs_cpu, info_cpu = cpu.reset(seed=5)
    obs_gpu, info_gpu = gpu.reset(seed=5)
    assert_same(obs_cpu, obs_gpu, "reset obs")
    assert_same(info_cpu, info_gpu, "reset info")
    rng = np.random.default_rng(1)
    counts = dict(successes=0, collisions=0, truncations=0)
    for k in range(steps):
        actions = actions_for(name, rng, n)
        given = torch.from_numpy(actions) if k % 2 else actions  # tensors and arrays alike
        cpu_out, gpu_out = cpu.step(actions), gpu.step(given)
        for label, c, g in zip(("obs", "reward", "terminated", "truncated", "info"), cpu_out, gpu_out):
            assert_same(c, g, f"step {k} {label}")
        info = cpu_out[4]
        counts["successes"] += int(info["is_success"].sum())
        counts["collisions"] += int(info["collision"].sum())
        counts["truncations"] += int(cpu_out[3].sum())
    # the episodes ended the ways the config is there for
    assert counts[ENDS[name]] > 0, counts
    assert np.array_equal(cpu.unwrapped.targets, gpu.unwrapped.targets)


def test_a_rejected_action_changes_nothing_and_reset_options_hold_for_one_episode():
    cpu, gpu = pair("pd-free", "NextStep", n=2)
    target = np.array([1.0, -1.0, 0.2])
    for env in (cpu, gpu):
        env.reset(seed=0, options={"target": target})
    bad = np.zeros((2, 3))
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="action"):
        gpu.step(torch.from_numpy(bad))
    with pytest.raises(ValueError, match="shape"):
        gpu.step(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="real numbers"):
        gpu.step(torch.zeros((2, 3), dtype=torch.complex64))
    assert np.array_equal(gpu.unwrapped.targets, np.tile(target, (2, 1)))
    rng = np.random.default_rng(2)
    for k in range(150):  # the first episodes go to the option's target, later ones to the default
        actions = actions_for("pd-free", rng, 2)
        for label, c, g in zip(("obs", "reward", "terminated", "truncated", "info"), cpu.step(actions),
                               gpu.step(actions)):
            assert_same(c, g, f"step {k} {label}")


def test_unsupported_options_and_order_are_named():
    with pytest.raises(ValueError, match="device must be one of"):
        gym.make_vec("Scara-C11-v1", num_envs=2, vectorization_mode="vector_entry_point", device="gpu")
    env = gym.make_vec("Scara-C11-v1", num_envs=2, vectorization_mode="vector_entry_point", device="cuda")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((2, 3)))


def test_the_torch_ppo_trains_on_the_cuda_env(tmp_path):
    from agents.algorithms.torch_ppo import Config, train

    summary = train(Config(device="cuda", num_envs=4, num_steps=8, num_minibatches=2, update_epochs=1,
                           total_timesteps=64, checkpoint_every=1, out=str(tmp_path / "run")))
    assert summary["global_step"] == 64
    assert (tmp_path / "run" / "model.pt").exists()


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "SameStep"])
def test_parameters_set_for_one_episode_go_back_to_the_nominal_ones(autoreset_mode):
    """A reset option's parameters hold for that episode only, also on the GPU (where the next
    episodes of a task without draws begin on the device)."""
    cpu, gpu = pair("pd-free", autoreset_mode, n=3)
    options = {"params": {"axes.0.resistance": 1.2 * scara_gym.DEFAULT_PARAMS.axes[0].resistance}}
    assert_same(*[env.reset(seed=4, options=options)[1] for env in (cpu, gpu)], "reset info")
    rng = np.random.default_rng(3)
    ends = 0
    for k in range(340):
        actions = actions_for("pd-free", rng, 3)
        cpu_out, gpu_out = cpu.step(actions), gpu.step(actions)
        for label, c, g in zip(("obs", "reward", "terminated", "truncated", "info"), cpu_out, gpu_out):
            assert_same(c, g, f"step {k} {label}")
        ends += int(cpu_out[2].sum())
    assert ends > 3  # later episodes ran (on the nominal parameters, as the CPU env's did)
    assert np.array_equal(cpu.unwrapped._task.robot_params["resistance"],
                          gpu.unwrapped.d_params.copy_to_host()["resistance"])


def test_the_gpu_benchmark_runs_and_finds_no_difference_on_the_simulator():
    from scara_gym.benchmark.bench import bench_gpu

    (row,) = bench_gpu(sizes=(6,), steps=5)
    assert row["n"] == 6 and row["rate"] > 0 and row["q_difference"] == 0.0


GOAL_CONFIGS = {
    "wall": dict(),                 # goals beyond the wall: collisions end episodes
    "free": dict(obstacle=False),   # goals reached
    "loose": dict(obstacle=False, goal_tolerance=0.05),  # the kernel's goal test at another tolerance
}


# Pairwise, not the full product (each case is about 11 s on the simulator): every config meets
# every reward type, and every config and every reward type meet both autoreset modes.
GOAL_CASES = [(name, reward_type, ("NextStep", "SameStep")[(k + i) % 2])
              for i, name in enumerate(GOAL_CONFIGS) for k, reward_type in enumerate(("sparse", "dense", "mixed"))]


@pytest.mark.parametrize(("name", "reward_type", "autoreset_mode"), GOAL_CASES)
def test_the_cuda_goal_env_is_the_cpu_goal_env_bit_for_bit(name, reward_type, autoreset_mode):
    """Scara-C11-Goal-v0 on the device: the goal test ends episodes in the step kernel; rewards,
    terms, success and the Dict observations (final ones too) are the CPU goal env's."""
    from scara_gym.envs.goal import ScaraCudaGoalVectorEnv

    n, steps = 3, 250
    make = lambda **device: gym.make_vec(  # noqa: E731
        "Scara-C11-Goal-v0", num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=autoreset_mode,
        reward_type=reward_type, action_delay=1, **GOAL_CONFIGS[name], **device)
    cpu, gpu = make(), make(device="cuda")
    assert isinstance(gpu, ScaraCudaGoalVectorEnv)
    assert gpu.single_observation_space == cpu.single_observation_space
    for label, c, g in zip(("obs", "info"), cpu.reset(seed=3), gpu.reset(seed=3)):
        assert_same(c, g, f"reset {label}")
    rng = np.random.default_rng(1)
    successes = collisions = 0
    for k in range(steps):  # the set-point at the goal, kicked now and then
        goals = np.array([cpu.unwrapped.setpoint_to_action(t) for t in cpu.unwrapped.targets])
        actions = goals + rng.normal(0.0, 0.3, (n, 3)) * (rng.random((n, 1)) < 0.2)
        cpu_out, gpu_out = cpu.step(actions), gpu.step(torch.from_numpy(actions))
        for label, c, g in zip(("obs", "reward", "terminated", "truncated", "info"), cpu_out, gpu_out):
            assert_same(c, g, f"step {k} {label}")
        successes += int(cpu_out[4]["is_success"].sum())
        collisions += int(cpu_out[4]["collision"].sum())
    assert (collisions if name == "wall" else successes) > 0, (successes, collisions)
    if name == "loose":  # the kernel ran the goal test at this threshold
        assert gpu.unwrapped.rules.threshold == 0.05 + 1e-6


def test_observation_noise_on_the_device_is_seeded_gaussian_and_leaves_the_physics_alone():
    """The noise is drawn on the device (not the CPU env's draws): per entry zero-mean with
    the configured std, inside the observation space, reproduced by the seed; rewards, flags
    and the entries without noise are the noise-free env's."""
    std = {"q": 0.01, "current": 0.05}
    n, steps = 8, 60
    make = lambda **extra: gym.make_vec("Scara-C11-v1", num_envs=n, vectorization_mode="vector_entry_point",  # noqa: E731
                                        device="cuda", randomize_target=True, **extra)
    clean, noisy, again = make(), make(observation_noise=std), make(observation_noise=std)
    space = noisy.observation_space
    layout = scara_gym.envs.OBSERVATION_LAYOUT
    noisy_columns = np.zeros(space.shape[1], dtype=bool)
    expected_std = np.zeros(space.shape[1])
    for field, value in std.items():
        noisy_columns[layout[field]] = True
        expected_std[layout[field]] = value
    runs = [env.reset(seed=7)[0].numpy() for env in (clean, noisy, again)]
    differences, rng = [], np.random.default_rng(0)
    for k in range(steps + 1):
        obs_clean, obs_noisy, obs_again = runs
        assert obs_noisy.dtype == np.float32 and space.contains(obs_noisy)
        assert np.array_equal(obs_noisy, obs_again)  # the same seed, the same noise
        assert np.array_equal(obs_noisy[:, ~noisy_columns], obs_clean[:, ~noisy_columns])
        inside = (obs_clean > space.low + 0.2) & (obs_clean < space.high - 0.2)  # away from the clipping
        differences.append(np.where(inside, obs_noisy.astype(np.float64) - obs_clean, np.nan)[:, noisy_columns])
        if k == steps:
            break
        actions = np.array([2 / np.pi, 2 / np.pi, 0.5]) + rng.normal(0.0, 0.3, (n, 3))
        outs = [env.step(actions) for env in (clean, noisy, again)]
        for label, c, g in zip(("reward", "terminated", "truncated"), outs[0][1:4], outs[1][1:4]):
            assert torch.equal(c, g), label
        runs = [out[0].numpy() for out in outs]
    differences = np.concatenate(differences)
    measured = np.nanstd(differences, axis=0)
    assert np.allclose(measured, expected_std[noisy_columns], rtol=0.2), measured
    assert np.all(np.abs(np.nanmean(differences, axis=0)) < 4 * expected_std[noisy_columns] / np.sqrt(
        np.sum(np.isfinite(differences), axis=0)))
    # at reset every robot rests at the start: the q columns differ by the noise alone
    q = layout["q"]
    first, same, other = (noisy.reset(seed=s)[0].numpy()[:, q] for s in (7, 7, 8))
    assert np.array_equal(first, same) and not np.array_equal(first, other)


@pytest.mark.parametrize("env_id", scara_gym.ENV_IDS)
def test_every_registered_id_has_the_cuda_backend(env_id):
    """device="cuda" on every id, with the id's registered arguments: the CPU env's first steps."""
    make = lambda **device: gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point",  # noqa: E731
                                         **device)
    cpu, gpu = make(), make(device="cuda")
    for label, c, g in zip(("obs", "info"), cpu.reset(seed=11), gpu.reset(seed=11)):
        assert_same(c, g, f"reset {label}")
    rng = np.random.default_rng(0)
    for k in range(5):
        actions = rng.uniform(-1.0, 1.0, (3, 3))
        for label, c, g in zip(("obs", "reward", "terminated", "truncated", "info"), cpu.step(actions),
                               gpu.step(actions)):
            assert_same(c, g, f"step {k} {label}")


def test_sensor_noise_is_refused_by_name_on_the_device():
    with pytest.raises(ValueError, match="sensor_noise is not implemented on the CUDA vector env"):
        ScaraCudaVectorEnv(num_envs=2, sensor_noise={"q": 1e-3})


def test_random_starts_with_a_delay_in_pd_mode_are_refused_on_the_device():
    with pytest.raises(ValueError, match="randomize_start with action_delay or action_rate_limit in 'pd' mode"):
        ScaraCudaVectorEnv(num_envs=2, randomize_start=True, action_delay=1)
    ScaraCudaVectorEnv(num_envs=2, randomize_start=True)  # without the line: the plans carry the starts


def test_the_cuda_env_defaults_to_the_latest_integration():
    assert {name: getattr(ScaraCudaVectorEnv(num_envs=2)._task, name) for name in scara_gym.LATEST_INTEGRATION} \
        == scara_gym.LATEST_INTEGRATION


@pytest.mark.parametrize("name", ["pd-random", "physics", "delay-slew"])
def test_disabled_autoreset_with_a_reset_mask_is_the_cpu_env_bit_for_bit(name):
    """"Disabled": no robot resets by itself; reset(options={"reset_mask": m}) begins the robots
    of m on the device as the CPU env does, the others untouched; an ended robot stepped again
    is named."""
    n = 4
    cpu, gpu = pair(name, "Disabled", n)
    for label, c, g in zip(("obs", "info"), cpu.reset(seed=5), gpu.reset(seed=5)):
        assert_same(c, g, f"reset {label}")
    rng = np.random.default_rng(1)
    seeds, resets = iter(range(50, 10_000)), 0
    for k in range(160):
        actions = actions_for(name, rng, n)
        cpu_out, gpu_out = cpu.step(actions), gpu.step(actions)
        for label, c, g in zip(("obs", "reward", "terminated", "truncated", "info"), cpu_out, gpu_out):
            assert_same(c, g, f"step {k} {label}")
        done = cpu_out[2] | cpu_out[3]
        if done.any():
            with pytest.raises(RuntimeError, match="have ended their episodes"):
                gpu.step(actions)
            seed = [next(seeds) if d else None for d in done]
            options = {"reset_mask": done}
            for label, c, g in zip(("obs", "info"), cpu.reset(seed=seed, options=dict(options)),
                                   gpu.reset(seed=seed, options=dict(options))):
                assert_same(c, g, f"masked reset at {k}: {label}")
            resets += int(done.sum())
    assert resets >= 2
