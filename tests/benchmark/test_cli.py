import pytest

from scara_gym.benchmark.cli import main

pytestmark = pytest.mark.slow  # reproduce and bench --quick: about a minute each

# the reach-time table and the form difference row, as `scara-c11 reproduce` printed them
# before the "One house" restructuring (commit e1f5cf0): behaviour unchanged, to the digit
RECORDED_REACH_TABLE = """\
| case | seed | ours: target reached | critical from | q3 reaches h_obs | collision |
|---|---|---|---|---|---|
| no obstacle (task b) | 1.5719 s | 1.5703 s | - | - | no |
| plain PD, wall, no avoidance | - (not in seed) | 1.5703 s | - | - | yes, at 0.3597 s |
| restart, dec 5e-5 | 1.4555 s | 1.4560 s | 0.3492 s | 0.5273 s | no |
| continuous, dec 5e-5 | 1.7736 s (path swings round) | 1.4367 s | 0.3492 s | 0.5273 s | no |
| restart, dec 5e-3 | collision | 1.4543 s | 0.3492 s | 0.5273 s | no |
| continuous, dec 5e-3 | reaches target (time not given) | 1.4350 s | 0.3492 s | 0.5273 s | no |"""
RECORDED_DIFFERENCE_ROW = "| max relative difference of the trajectories | | 1.9e-12 | 6.0e-09 |"


def test_reproduce_prints_the_tables_and_writes_the_figures(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "| restart, dec 5e-5 | 1.4555 s | 1.4560 s |" in out
    assert "| no obstacle (task b) | 1.5719 s | 1.5703 s |" in out
    assert "implicit / explicit" in out
    assert RECORDED_REACH_TABLE in out and RECORDED_DIFFERENCE_ROW in out
    names = sorted(p.name for p in tmp_path.glob("*.png"))
    assert names == ["task_b_tip_path.png", "task_c_dec_5e-3.png", "task_c_distance.png", "task_c_tip_paths.png"]
    assert all((tmp_path / n).stat().st_size > 10_000 for n in names)


def test_bench_quick_runs_and_reports_ratios(capsys):
    assert main(["bench", "--quick"]) == 0
    out = capsys.readouterr().out
    for section in ("x Pendulum-v1", "| Scara-C11-v0, voltage |", "| Scara-C11-v1, pd |",
                    "| Scara-C11-v0 | voltage | 64 |", "| Scara-C11-v1 | pd | 64 |",
                    "Where a step's time goes, one env via gym.make (pd mode", "(voltage mode",
                    "| env id | steps/s | total | Python | right-hand sides | switch search |",
                    "Integration tolerance", "| 1e-05 | 1e-06 |", "Peak memory", "cold (empty JIT cache)",
                    "GPU: "):
        assert section in out
    assert "scipy solve_ivp RK45" in out and "scara_gym compiled DOPRI5, implicit" in out
    reach_times = [float(line.split("|")[4].strip().rstrip(" s")) for line in out.splitlines()
                   if line.startswith("| scipy") or line.startswith("| scara_gym")]
    assert len(reach_times) == 4
    assert max(reach_times) - min(reach_times) < 1e-5  # same event, same tolerance


@pytest.mark.parametrize("argv, says", [(["accuracy", "--seed", "-1"], "--seed must be >= 0, got -1"),
                                        (["accuracy", "--episodes", "0"], "--episodes must be >= 1, got 0")])
def test_a_mistake_ends_in_one_line_with_status_2(argv, says, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and says in err and "Traceback" not in err
