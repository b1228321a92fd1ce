"""The package as a whole: its layout, the source-keyed compiled cache, and an installed copy
that works outside the clone."""

import ast
import hashlib
import importlib.util
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import scara_gym
from scara_gym.model import compilation

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "scara_gym"


def imported_modules(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_the_model_package_imports_neither_gymnasium_nor_torch():
    files = sorted((PACKAGE / "model").glob("*.py"))
    assert len(files) >= 6
    for path in files:
        assert not imported_modules(path) & {"gymnasium", "gym", "torch"}, path.name


def test_every_module_with_compiled_functions_keys_the_cache():
    compiled = sorted(str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py") if "@njit" in p.read_text())
    assert compiled == sorted(set(compiled) & set(compilation.COMPILED_SOURCES))
    assert set(compiled) <= set(compilation.COMPILED_SOURCES)
    assert all((PACKAGE / name).exists() for name in compilation.COMPILED_SOURCES)


def test_the_source_key_changes_with_any_compiled_source(tmp_path):
    for name in ("a.py", "b.py"):
        (tmp_path / name).write_text("VALUE = 1\n")
    before = compilation.source_key(tmp_path, ("a.py", "b.py"))
    (tmp_path / "b.py").write_text("VALUE = 2\n")
    assert compilation.source_key(tmp_path, ("a.py", "b.py")) != before


TOY_CONSTANTS = "VALUE = {value}\n"
TOY_FUNCTION = """
from numba import njit
from toy.constants import VALUE  # folded into the machine code


@njit(cache=True)
def value():
    return VALUE
"""
TOY_RUN = """
import sys
from pathlib import Path
if sys.argv[1] == "keyed":
    from scara_gym.model import compilation

    class Locator(compilation.KeyedInTreeLocator):
        package_dir = Path(sys.argv[2]).resolve()
        sources = ("constants.py", "function.py")

    compilation.install_locators(Locator)
from toy.function import value
print(value())
"""


@pytest.mark.parametrize("mode", ["keyed", "plain numba"])
def test_stale_compiled_code_cannot_run(tmp_path, mode):
    """An edit to a constant that a compiled function folds in from another file: numba alone
    keeps running the stale machine code; the keyed cache recompiles."""
    toy = tmp_path / "toy"
    toy.mkdir()
    (toy / "__init__.py").write_text("")
    (toy / "function.py").write_text(TOY_FUNCTION)

    def run(value):
        (toy / "constants.py").write_text(TOY_CONSTANTS.format(value=value))
        env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}"}
        env.pop("NUMBA_CACHE_DIR", None)
        out = subprocess.run([sys.executable, "-c", TOY_RUN, mode.split()[0], str(toy)], env=env,
                             capture_output=True, text=True, check=True, cwd=tmp_path)
        return int(out.stdout.strip())

    assert run(1) == 1
    assert any((toy / "__pycache__").glob("function.value-*.nbi"))  # cached on disk
    if mode == "keyed":
        assert run(2) == 2
    else:
        assert run(2) == 1  # the stale machine code ran: what the keyed cache prevents


def test_version_command(capsys):
    from scara_gym.benchmark.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert scara_gym.__version__ in capsys.readouterr().out


def _tree_digest(folder: Path) -> str:
    """The names and bytes of every file under ``folder`` but compiled caches (``__pycache__``)."""
    sha = hashlib.sha256()
    for path in sorted(folder.rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts:
            sha.update(str(path.relative_to(folder)).encode() + path.read_bytes())
    return sha.hexdigest()


def _fresh_venv_with_the_wheel(tmp_path: Path) -> tuple[Path, Path]:
    """A wheel built from the checkout, installed into a new venv: (its bin folder, its site-packages).
    The dependencies come from this test's environment through a path file placed after the venv's
    own site-packages, so the test needs no network and the package itself comes from the wheel
    alone (the editable install here is a finder that a plain path entry does not run)."""
    dist, venv = tmp_path / "dist", tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist), str(ROOT)],
                   check=True, capture_output=True, text=True)
    wheel, = dist.glob("scara_gym-*.whl")
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, capture_output=True, text=True)
    python = venv / "bin" / "python"
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               check=True, capture_output=True, text=True).stdout.strip())
    ours = sysconfig.get_paths()
    (site / "_test_dependencies.pth").write_text("\n".join(dict.fromkeys([ours["purelib"], ours["platlib"]])) + "\n")
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
                   check=True, capture_output=True, text=True)
    return venv / "bin", site


@pytest.mark.slow
def test_a_wheel_in_a_fresh_venv_works_outside_the_clone(tmp_path):
    """The wheel in a fresh venv, its console scripts run from a folder outside the clone:
    evaluation of a shipped model by name, a tiny training run, the random tier of a dataset,
    which needs no published runs (the expert tier says in one line how to get them), the seed
    paper's reproduction and a plain function scored under the protocol. Training writes under
    runs/, evaluation and the dataset under their --out only, the home folder gets caches at
    most, and the installed package (the shipped models included) stays as it was."""
    pytest.importorskip("stable_baselines3")
    bin_dir, site = _fresh_venv_with_the_wheel(tmp_path)
    shipped = site / "agents" / "models"
    assert (shipped / "ppo_pd" / "model.zip").exists() and (site / "agents" / "algorithms" / "sb3" / "hyperparams" / "ppo.yml").exists()
    before, installed = _tree_digest(shipped), _tree_digest(site)
    work, home = tmp_path / "elsewhere", tmp_path / "home"
    work.mkdir()
    home.mkdir()
    env = {**os.environ, "HOME": str(home)}
    for name in ("PYTHONPATH", "NUMBA_CACHE_DIR", "SCARA_GYM_PUBLISHED_RUNS", "MINARI_DATASETS_PATH", "XDG_DATA_HOME",
                 "XDG_CACHE_HOME", "XDG_CONFIG_HOME", "VIRTUAL_ENV"):
        env.pop(name, None)

    def run(command, *args):
        """``command`` (python, scara-c11 or scara-agents) of the fresh venv, run in the work folder."""
        return subprocess.run([str(bin_dir / command), *args], cwd=work, env=env, capture_output=True, text=True)

    where = run("python", "-c", "import agents, scara_gym; print(agents.__file__, scara_gym.__file__)")
    assert where.returncode == 0 and where.stdout.count(str(site)) == 2, where.stdout + where.stderr
    evaluated = run("scara-agents", "evaluate", "--policies", "pd", "ppo:ppo_pd", "--episodes", "1", "--out", "out")
    assert evaluated.returncode == 0, evaluated.stderr
    assert compilation.COMPILE_MESSAGE in evaluated.stderr  # a fresh install compiles, and says so
    assert "| ppo (ppo_pd) | 1 | 1.0000 | 0.0000 |" in evaluated.stdout
    assert (work / "out" / "table.md").exists() and (work / "out" / "ppo_pd_results.json").exists()
    trained = run("scara-agents", "train", "ppo-residual", "--env-id", "Scara-C11-v0", "--total-timesteps", "256",
                  "--out", "runs/ppo_pd", "--set", "n_envs=2", "n_steps=64", "batch_size=64")
    assert trained.returncode == 0, trained.stderr
    assert trained.stderr.count(compilation.COMPILE_MESSAGE) <= 1  # the vector env's entry points: once
    assert (work / "runs" / "ppo_pd" / "model.zip").exists()
    again = run("scara-agents", "evaluate", "--policies", "ppo:runs/ppo_pd", "--episodes", "1", "--out", "out")
    assert again.returncode == 0, again.stderr
    assert compilation.COMPILE_MESSAGE not in again.stderr  # cached on disk by the first run
    if importlib.util.find_spec("minari") is not None:
        built = run("scara-agents", "datasets", "build", "scara/c11/random-v0", "--episodes", "5", "--out", "data")
        assert built.returncode == 0, built.stderr
        assert (work / "data" / "scara" / "c11" / "random-v0" / "data").is_dir()
        refused = run("scara-agents", "datasets", "build", "scara/c11/expert-v0", "--episodes", "5", "--out", "data")
        assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1, refused.stderr
        assert "SCARA_GYM_PUBLISHED_RUNS=CLONE/results/runs" in refused.stderr
        assert not (work / "data" / "scara" / "c11" / "expert-v0").exists()
    reproduced = run("scara-c11", "reproduce", "--out", "figures", "--repeats", "1")
    assert reproduced.returncode == 0, reproduced.stderr
    assert any((work / "figures").glob("*.png"))
    scored = run("python", "-c", "import numpy as np\n"
                                 "from scara_gym.benchmark.protocol import evaluate\n"
                                 "def hold(obs):\n    return np.zeros(3)\n"
                                 "result = evaluate('c11-starts', policy=hold, episodes=2)\n"
                                 "print('scored', len(result['success']), int(result['success'].sum()))")
    assert scored.returncode == 0, scored.stderr
    assert "scored 2 " in scored.stdout  # a plain function under the protocol, from outside the clone
    assert {p.name for p in work.iterdir()} <= {"data", "out", "runs", "figures"}
    assert {p.relative_to(home).parts[0] for p in home.rglob("*") if p.is_file()} <= {".cache", ".config"}
    assert _tree_digest(shipped) == before and _tree_digest(site) == installed
