from scara_gym.benchmark.cli import main


def test_reproduce_prints_the_tables_and_writes_the_figures(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "| restart, dec 5e-5 | 1.4555 s | 1.4560 s |" in out
    assert "| no obstacle (task b) | 1.5719 s | 1.5703 s |" in out
    assert "implicit / explicit" in out
    names = sorted(p.name for p in tmp_path.glob("*.png"))
    assert names == ["task_b_tip_path.png", "task_c_dec_5e-3.png", "task_c_distance.png", "task_c_tip_paths.png"]
    assert all((tmp_path / n).stat().st_size > 10_000 for n in names)


def test_bench_quick_runs_and_reports_ratios(capsys):
    assert main(["bench", "--quick"]) == 0
    out = capsys.readouterr().out
    for section in ("x Pendulum-v1", "| Scara-C11-v0, voltage |", "| voltage | 64 |", "| pd | 64 |",
                    "Integration tolerance", "| 1e-05 | 1e-06 |", "Peak memory", "cold (empty JIT cache)"):
        assert section in out
    assert "scipy solve_ivp RK45" in out and "scara_gym compiled DOPRI5, implicit" in out
    reach_times = [float(line.split("|")[4].strip().rstrip(" s")) for line in out.splitlines()
                   if line.startswith("| scipy") or line.startswith("| scara_gym")]
    assert len(reach_times) == 4
    assert max(reach_times) - min(reach_times) < 1e-5  # same event, same tolerance
