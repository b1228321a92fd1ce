"""The minimum-time reference: its model, the shipped solution replayed in the env, the bound."""

import json

import gymnasium as gym
import numpy as np
import pytest

import scara_gym  # noqa: F401
from agents.policies import run_episode
from agents.policies.optimal import SOLUTIONS, OptimalPolicy, cached_solution, reference_snapshots, replay, replaying
from scara_gym import LATEST_ENV_ID
from scara_gym.model.params import DEFAULT_PARAMS

SPEC_BOUND = 1.2217  # s, the spec's minimum time under the environment's rules (continuous time)


def test_shipped_solution_replays_in_the_environment():
    """The C11 target: success, no collision, within 2 % of the spec's bound, above the
    shipped free bound, which itself reproduces the spec's 1.2217 s to 1 ms."""
    data = cached_solution()
    assert data is not None, f"no shipped solution in {SOLUTIONS}"
    assert data["free"]["status"] == data["held"]["status"] == "solved"
    assert abs(data["free"]["time"] - SPEC_BOUND) < 1e-3
    result = replay(np.array(data["held"]["actions"]))
    assert result["success"] and result["collisions"] == 0
    assert data["free"]["time"] <= result["reach_time"] <= 1.02 * SPEC_BOUND
    assert result["reach_time"] == pytest.approx(data["replay"]["reach_time"], abs=1e-9)
    # the replay ends inside the planned steps: the PD fallback is never used
    assert result["steps"] <= len(data["held"]["actions"])
    # the same physics at v2's tighter tolerances: the same arrival to the accuracy targets' 1e-6 s
    tighter = replay(np.array(data["held"]["actions"]), env_id="Scara-C11-v2")
    assert tighter["success"] and tighter["collisions"] == 0
    assert tighter["reach_time"] == pytest.approx(result["reach_time"], abs=1e-6)


def test_optimal_policy_in_the_environment_and_its_mode():
    env = gym.make("Scara-C11-v1", control_mode="voltage")
    policy = OptimalPolicy(env, solve_missing=False)
    first = run_episode(env, policy, seed=0)
    second = run_episode(env, policy, seed=1)
    assert first["success"] and first["collisions"] == 0
    assert first["reach_time"] == second["reach_time"]  # reset() restarts the plan
    with pytest.raises(ValueError, match="control_mode='voltage'"):
        OptimalPolicy(gym.make("Scara-C11-v1", control_mode="pd"))
    with pytest.raises(LookupError, match="no shipped minimum-time solution"):
        run_episode(env, policy, seed=0, options={"target": [1.5, 2.5, 0.25]})


def test_reference_snapshots_are_the_replayed_path():
    data = cached_solution()
    actions = np.array(data["held"]["actions"])
    snapshots = reference_snapshots()
    replayed = replay(actions)
    assert len(snapshots) == replayed["steps"] - 1
    assert [s["episode_steps"] for s in snapshots] == list(range(1, len(snapshots) + 1))
    np.testing.assert_allclose([s["t"] for s in snapshots], 0.01 * np.arange(1, len(snapshots) + 1), atol=1e-12)
    # from the last snapshot, the last planned action reaches the target at the replay's instant
    env = gym.make(LATEST_ENV_ID, control_mode="voltage")  # the id the snapshots were taken on
    env.reset(seed=0)
    env.unwrapped.restore(snapshots[-1])
    _, _, terminated, _, info = env.step(actions[len(snapshots)])
    assert terminated and info["is_success"] and info["reach_time"] == pytest.approx(replayed["reach_time"], abs=1e-12)


def test_the_wider_wall_margin_reference_keeps_its_distance():
    """The C11 solution with an 8 mm wall margin (demo resets' reference): below h_obs its tip
    stays 8 mm or more from the wall plane at every recorded instant, a little slower than the
    1 mm one; an unknown margin is not made up."""
    from agents.cli import run

    data = cached_solution(wall_margin=0.008)
    assert data is not None and data["command"].endswith("--wall-margin 0.008")
    env, policy = replaying(np.array(data["held"]["actions"]), "Scara-C11-v1", data["start"], data["target"],
                            DEFAULT_PARAMS)
    result = run_episode(env, policy, seed=0, record=True)
    _, _, _, wall_distance, height_margin, _ = result["trace"].T
    assert result["success"] and result["collisions"] == 0
    assert np.all(np.abs(wall_distance[height_margin < 0]) >= 0.008 - 1e-6)
    assert cached_solution()["replay"]["reach_time"] < result["reach_time"] < 1.02 * SPEC_BOUND
    assert cached_solution(wall_margin=0.005) is None
    with pytest.raises(LookupError, match="wall margin 0.005 m"):
        reference_snapshots(wall_margin=0.005)
    with pytest.raises(SystemExit):
        run(["optimal", "--wall-margin", "0.02"])


def test_shipped_solution_file_is_complete():
    for path in SOLUTIONS.glob("*.json"):
        data = json.loads(path.read_text())
        assert {"start", "target", "params", "config", "free", "held", "replay", "command"} <= set(data)
        actions = np.array(data["held"]["actions"])
        assert actions.shape[1] == 3 and np.all(np.abs(actions) <= 1 + 1e-7)


def test_every_shipped_solution_replays_in_its_own_condition():
    """The C11 target under the protocol's fixed parameter shifts (scara_gym.benchmark.protocol):
    each shipped solution, replayed with its condition's parameters, succeeds without a
    collision at its recorded time, above that condition's free bound."""
    from scara_gym import DEFAULT_PARAMS
    from scara_gym.benchmark.protocol import CONDITIONS

    for path in sorted(SOLUTIONS.glob("*.json")):
        data = json.loads(path.read_text())
        params = DEFAULT_PARAMS.replace(CONDITIONS[data.get("condition", "c11")].params)
        assert cached_solution(data["start"], data["target"], params, data["config"]["wall_margin"]) == data, path.name
        result = replay(np.array(data["held"]["actions"]), start=data["start"], target=data["target"],
                        params=params)
        assert result["success"] and result["collisions"] == 0, path.name
        assert result["reach_time"] == pytest.approx(data["replay"]["reach_time"], abs=1e-9), path.name
        assert data["free"]["time"] <= result["reach_time"], path.name


@pytest.mark.slow
def test_free_problem_reproduces_the_spec_bound():
    """The continuous-time problem solved from scratch (the heuristic's path as the guess)."""
    pytest.importorskip("casadi")
    from agents.policies.optimal import CollocationConfig, minimum_time

    solution = minimum_time("free", config=CollocationConfig(wall_margin=0.0, band_margin=0.0))
    assert solution.status == "solved"
    assert abs(solution.time - SPEC_BOUND) < 1e-3
    critical_from, above = solution.phase_times
    assert critical_from < above < solution.time  # the three phases in order
