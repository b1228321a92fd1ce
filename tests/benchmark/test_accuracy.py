"""The accuracy property of ``scara-c11 accuracy`` on a fixed sample: the first eight
episode plans of its default seed (two of each action program), in CI."""

import numpy as np
import pytest

import scara_gym
from scara_gym.benchmark import accuracy

SAMPLE = accuracy.plans(8, seed=0)


V1 = scara_gym.ENV_VERSIONS["Scara-C11-v1"]


@pytest.fixture(scope="module")
def exact_rows():
    """At the default tolerances: Scara-C11-v2's."""
    return [accuracy.compare_episode(plan) for plan in SAMPLE]


@pytest.fixture(scope="module")
def v1_rows():
    return [accuracy.compare_episode(plan, V1["rtol"], V1["atol"]) for plan in SAMPLE]


@pytest.fixture(scope="module")
def step_end_rows():
    return [accuracy.compare_episode(plan, V1["rtol"], V1["atol"], exact_switches=False) for plan in SAMPLE]


def test_the_sample_covers_every_program_both_modes_and_the_obstacle():
    assert {plan.program for plan in SAMPLE} == set(accuracy.PROGRAMS)
    assert {plan.env_kwargs["control_mode"] for plan in SAMPLE} == {"pd", "voltage"}
    assert {plan.env_kwargs["obstacle"] for plan in SAMPLE} == {True, False}


def test_the_default_tolerances_are_those_of_the_latest_id_scara_c11_v2():
    v2 = scara_gym.ENV_VERSIONS["Scara-C11-v2"]
    assert scara_gym.LATEST_ENV_ID == "Scara-C11-v2"
    assert (accuracy.DEFAULT_RTOL, accuracy.DEFAULT_ATOL) == (v2["rtol"], v2["atol"]) and v2["exact_switches"]


def test_the_sample_has_a_voltage_jump_at_a_critical_switch(v1_rows):
    assert any(row["voltage_jumps"] for row in v1_rows)


def test_exact_switches_meet_every_target_at_the_default_tolerances(exact_rows):
    for row in exact_rows:
        assert row["unpaired_events"] == 0, row  # every switch of the tight run is found, no other
        assert row["ended_together"], row
        for name, target in accuracy.TARGETS.items():
            assert row[name] <= target, (name, row)
    assert sum(row["events"] for row in exact_rows) > 100  # the sample does switch


def test_v1_meets_the_targets_except_the_currents_after_a_voltage_jump(v1_rows):
    for row in v1_rows:
        assert row["unpaired_events"] == 0, row
        assert row["ended_together"], row
        assert row["q"] <= accuracy.TARGETS["q"], row
        assert row["event_time"] <= accuracy.TARGETS["event_time"], row
        if not row["voltage_jumps"]:  # see the benchmark's note on the voltage jump
            assert row["rate"] <= accuracy.TARGETS["rate"], row
            assert row["current"] <= accuracy.TARGETS["current"], row


def test_switches_seen_only_at_step_ends_miss_some(v1_rows, step_end_rows):
    """What exact switches fix: the same episodes lose events and currents drift."""
    assert sum(row["unpaired_events"] for row in step_end_rows) > 0
    assert max(row["current"] for row in step_end_rows) > max(row["current"] for row in v1_rows)


def test_paired_time_errors_pair_by_kind_axis_and_order():
    events = [(1, 0, 0.10), (2, 0, 0.20), (9, -1, 0.5)]
    reference = [(1, 0, 0.1000004), (2, 0, 0.20), (1, 0, 0.3)]
    worst, unpaired = accuracy._paired_time_errors(events, reference)
    assert worst == pytest.approx(4e-7)
    assert unpaired == 2  # the second (1, 0) and the (9, -1)


def test_accuracy_command_prints_both_tables(capsys):
    from scara_gym.benchmark.cli import main
    assert main(["accuracy", "--episodes", "2"]) == 0
    out = capsys.readouterr().out
    assert "Accuracy with exact switches at rtol 1e-07, atol 1e-09" in out  # Scara-C11-v2's
    assert "switches at step ends (exact_switches=False)" in out
    assert out.count("| event_time [s] | 1e-06 |") == 2


@pytest.mark.parametrize("argv, words", [
    (["accuracy", "--episodes", "0"], "--episodes must be >= 1"),
    (["accuracy", "--rtol", "1.5"], "--rtol must be a finite number in [1e-14, 0.01], got 1.5"),
    (["accuracy", "--atol", "0"], "--atol must be a finite number in [1e-16, 0.01], got 0.0"),
])
def test_accuracy_command_rejects_bad_arguments(argv, words, capsys):
    from scara_gym.benchmark.cli import main
    with pytest.raises(SystemExit):
        main(argv)
    assert words in capsys.readouterr().err


def test_plans_are_reproducible():
    again = accuracy.plans(8, seed=0)
    for a, b in zip(SAMPLE, again):
        assert a.env_kwargs == b.env_kwargs and np.array_equal(a.actions, b.actions)


def test_the_latest_id_meets_every_target_on_a_held_out_voltage_jump_episode():
    """Seed 10's episode 40: outside the seeds (0-5) the tolerances were chosen on, six voltage jumps
    at critical switches, where the current error follows the global position error; the tolerance
    weights {"q": 0.03, "current": 30} miss the current target here (experiments log, 2026-12-03)."""
    plan = accuracy.plans(41, seed=10)[40]
    row = accuracy.compare_episode(plan)
    assert row["voltage_jumps"] > 0 and row["unpaired_events"] == 0 and row["ended_together"], row
    for name, target in accuracy.TARGETS.items():
        assert row[name] <= target, (name, row)


def test_a_start_offset_moves_the_run_under_test_only(monkeypatch):
    """compare_episode(start_offset=...) starts the run under test (the first env reset) that far from
    the plan's start and the reference at it; with no offset and the reference's own tolerances the two
    runs are the same bits."""
    from scara_gym.envs.scara_env import ScaraEnv

    plan = SAMPLE[0]
    starts = []
    reset = ScaraEnv.reset

    def recording_reset(self, *, seed=None, options=None):
        starts.append((self._task.rtol, np.array(options["start"])))
        return reset(self, seed=seed, options=options)

    monkeypatch.setattr(ScaraEnv, "reset", recording_reset)
    offset = np.array([0.0, 0.0, 1e-6])
    moved = accuracy.compare_episode(plan, 1e-7, 1e-9, start_offset=offset)
    (rtol_tested, start_tested), (rtol_reference, start_reference) = starts
    assert (rtol_tested, rtol_reference) == (1e-7, accuracy.REFERENCE_TOLERANCES[0])
    assert np.array_equal(start_tested, plan.options["start"] + offset)
    assert np.array_equal(start_reference, plan.options["start"])
    assert moved["start_offset"] == (0.0, 0.0, 1e-6) and moved["q"] >= 0.5e-6, moved  # q3 starts 1e-6 m off
    same = accuracy.compare_episode(plan, *accuracy.REFERENCE_TOLERANCES, start_offset=np.zeros(3))
    assert all(same[name] == 0.0 for name in accuracy.TARGETS), same


@pytest.mark.parametrize("offset", [1e-9, np.zeros(2), np.array([0.0, np.nan, 0.0])])
def test_a_start_offset_must_be_three_finite_numbers(offset):
    with pytest.raises(ValueError, match="start_offset must be 3 finite numbers"):
        accuracy.compare_episode(SAMPLE[0], start_offset=offset)


def test_the_held_out_episode_s_currents_follow_a_nanoradian_change_of_its_start():
    """Why its current target binds (experiments log, 2026-12-04): the exact solution itself (both runs
    at the reference's tolerances) moves its currents by more than half the 1e-4 A target when the
    start moves by 1e-9 rad, so any integration error of that size anywhere before the jumps shows."""
    plan = accuracy.plans(41, seed=10)[40]
    row = accuracy.compare_episode(plan, *accuracy.REFERENCE_TOLERANCES, start_offset=np.array([1e-9, 0.0, 0.0]))
    assert row["voltage_jumps"] > 0, row
    assert row["current"] > 0.5 * accuracy.TARGETS["current"], row
    # while the same nanoradian leaves the positions and instants well inside their targets
    assert row["q"] < 0.1 * accuracy.TARGETS["q"] and row["event_time"] < 0.5 * accuracy.TARGETS["event_time"], row
