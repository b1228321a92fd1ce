"""A missing install extra: the library's ImportError names it, and every scara-agents
subcommand says it in one line with exit status 2 (the module hidden as sys.modules[name] = None)."""

import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from scara_gym.extras import missing_extra_message, require


def test_require_names_the_extra_of_a_missing_module_and_leaves_others_alone(monkeypatch):
    monkeypatch.setitem(sys.modules, "casadi", None)
    with pytest.raises(ModuleNotFoundError, match=r'casadi is not installed: pip install "scara_gym\[control\]"'):
        require("casadi")
    with pytest.raises(ModuleNotFoundError) as error:
        require("no_such_module_anywhere")
    assert "scara_gym[" not in str(error.value)
    assert missing_extra_message("stable_baselines3.common") == \
        'stable_baselines3.common is not installed: pip install "scara_gym[train]" (the train extra)'


@pytest.mark.parametrize("module, hidden, extra", [
    ("agents.algorithms.torch_ppo", "torch", "train"),
    ("agents.algorithms.bc", "torch", "train"),
    ("scara_gym.integrations.sb3", "stable_baselines3", "train"),
])
def test_importing_an_optional_part_without_its_extra_names_the_extra(module, hidden, extra, monkeypatch):
    monkeypatch.setitem(sys.modules, hidden, None)
    monkeypatch.delitem(sys.modules, module, raising=False)
    with pytest.raises(ImportError, match=rf'{hidden} is not installed: pip install "scara_gym\[{extra}\]"'):
        importlib.import_module(module)


CASES = [
    ("evaluate", ["--policies", "ppo:ppo_pd", "--episodes", "1"], "stable_baselines3", "train"),
    ("train", ["ppo", "--total-timesteps", "16"], "stable_baselines3", "train"),
    ("torch-ppo", ["--total-timesteps", "16"], "torch", "train"),
    ("campaign", ["torch-ppo", "--seeds", "0"], "torch", "train"),
    ("compare", ["--runs", "."], "rliable", "compare"),
    ("curves", [], "rliable", "compare"),
    ("sweep", ["--run", "ppo"], "ray", "sweep"),
    ("optimal", [], "casadi", "control"),
    ("bench", ["--quick"], "torch", "train"),
    ("datasets", ["build", "scara/c11/random-v0", "--episodes", "1"], "minari", "datasets"),
]


@pytest.mark.slow
@pytest.mark.parametrize("command, arguments, hidden, extra", CASES, ids=[c[0] for c in CASES])
def test_every_subcommand_says_the_missing_extra_in_one_line(command, arguments, hidden, extra, tmp_path):
    out = [] if command in ("optimal", "bench", "datasets", "campaign", "compare") else ["--out", str(tmp_path / "o")]
    if command == "campaign":
        arguments = [*arguments, "--runs", str(tmp_path / "runs")]
    if command == "datasets":
        out = ["--out", str(tmp_path / "d")]
    code = (f"import sys\nsys.modules[{hidden!r}] = None\nfrom agents.cli import main\n"
            f"sys.exit(main({[command, *arguments, *out]!r}))")
    root = str(Path(__file__).resolve().parents[1])  # this checkout's package, run from another folder
    env = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300,
                          env=env)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr[-2000:]
    assert lines[-1].startswith(f"scara-agents {command}: error: {hidden} is not installed")
    assert f'pip install "scara_gym[{extra}]"' in lines[-1]
    assert not [line for line in lines if line.startswith("Traceback")]
