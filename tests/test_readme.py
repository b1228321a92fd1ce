"""Every Python snippet of the README runs on its own (a fresh interpreter, nothing defined
before it), from a folder outside the checkout; the CUDA one where a CUDA GPU is usable."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNIPPETS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)


def _cuda() -> bool:
    try:
        import torch
    except ImportError:
        return False
    return torch.cuda.is_available()


def test_the_readme_has_its_three_quickstart_snippets():
    assert len(SNIPPETS) == 3 and all("import scara_gym" in s for s in SNIPPETS)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_a_readme_snippet_runs_on_its_own(index, tmp_path):
    snippet = SNIPPETS[index]
    if 'device="cuda"' in snippet and not _cuda():
        pytest.skip("the CUDA snippet needs a CUDA GPU")
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([sys.executable, "-c", snippet], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]


@pytest.mark.slow
def test_the_own_controller_page_runs_and_prints_the_row_it_shows(tmp_path):
    page = (ROOT / "docs" / "own-controller.md").read_text()
    code = "\n".join(re.findall(r"```python\n(.*?)```", page, re.S))
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    row = [line for line in done.stdout.splitlines() if line.startswith("| my_controller |")][0]
    assert row.removeprefix("| my_controller |") in page  # the page's table shows what the code prints


def test_user_facing_output_names_no_internal_document():
    from scara_gym.benchmark import reproduce

    assert "spec" not in reproduce.NOTE.lower()
    assert "the ratios depend on the CPU" in Path(reproduce.__file__).read_text()
