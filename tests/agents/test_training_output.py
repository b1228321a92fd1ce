"""The trainers' defaults and what they print: one torch thread per run, a progress line, and
the folder they saved to (the speed behind the default: docs/experiments.md, 2026-12-05)."""

import re
from pathlib import Path

import pytest
import yaml

from agents.algorithms import progress
from agents.algorithms.sb3.hyperparams import HYPERPARAMS
from agents.algorithms.sb3.training import DEFAULT_TORCH_THREADS
from agents.algorithms.torch_ppo_config import Config
from agents.cli import run

LINE = re.compile(r"^steps [\d,]+/[\d,]+ \(\d+%\)  [\d,]+ steps/s  return \S+  success \S+  ETA \S+$")


def test_every_trainer_defaults_to_one_torch_thread():
    assert Config().torch_threads == 1 and DEFAULT_TORCH_THREADS == 1
    for path in sorted(Path(HYPERPARAMS).glob("*.yml")):
        for env_id, blocks in yaml.safe_load(path.read_text()).items():
            for key, block in blocks.items():
                assert block.get("torch_threads", DEFAULT_TORCH_THREADS) == 1, (path.name, env_id, key)


def test_the_progress_line_comes_at_most_every_ten_seconds_and_says_dash_before_any_episode(monkeypatch, capsys):
    clock = iter([0.0, 1.0, 6.0, 11.0, 12.0])
    monkeypatch.setattr(progress.time, "perf_counter", lambda: next(clock))
    shown = progress.Progress(1000)
    first = shown.report(100)
    assert first == "steps 100/1,000 (10%)  100 steps/s  return -  success -  ETA 9s"
    assert shown.report(200, [1.0], [True]) is None  # 5 s after the first
    assert shown.report(600, [1.0, 2.0], [True, False]) == \
        "steps 600/1,000 (60%)  55 steps/s  return 1.5  success 0.50  ETA 7s"
    assert shown.report(1000, final=True).endswith("ETA 0s")
    assert len(capsys.readouterr().out.splitlines()) == 3


def test_a_tiny_torch_ppo_run_prints_its_progress_and_where_it_saved(tmp_path, monkeypatch, capsys):
    import torch

    threads = []
    monkeypatch.setattr(torch, "set_num_threads", threads.append)
    out = tmp_path / "run"
    run(["torch-ppo", "--num-envs", "2", "--num-steps", "8", "--num-minibatches", "1", "--update-epochs", "1",
         "--total-timesteps", "16", "--out", str(out)])
    lines = capsys.readouterr().out.splitlines()
    assert threads == [1]
    assert any(LINE.match(line) and line.startswith("steps 16/16 (100%)") for line in lines), lines
    assert lines[-1] == f"saved to {out}"


@pytest.mark.slow
def test_a_tiny_sb3_run_prints_its_progress_and_where_it_saved(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "ppo"
    run(["train", "ppo", "--out", str(out), "--total-timesteps", "100", "--set", "n_envs=2", "n_steps=50",
         "batch_size=50", "n_epochs=1", "eval_freq=100", "eval_episodes=1", "snapshot_freq=100"])
    lines = capsys.readouterr().out.splitlines()
    assert any(LINE.match(line) and line.startswith("steps 100/100 (100%)") for line in lines), lines
    assert lines[-1] == f"saved to {out}"
