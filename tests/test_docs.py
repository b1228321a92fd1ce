"""The docs: the generated pages are fresh, the README is short and its commands as CI runs
them, and the site builds with every warning an error."""

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _generator():
    spec = importlib.util.spec_from_file_location("gen_pages", ROOT / "docs" / "gen_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_generated_page_is_fresh():
    pages = _generator().pages()
    import scara_gym

    assert {p.stem for p in pages if p.parent.name == "envs"} >= set(scara_gym.ENV_IDS)
    stale = [str(p.relative_to(ROOT)) for p, text in pages.items() if not p.exists() or p.read_text() != text]
    assert not stale, f"run python docs/gen_pages.py: stale {stale}"


def test_an_id_page_carries_its_registration_and_its_card():
    import inspect

    from scara_gym.envs.scara_env import ScaraEnv

    page = _generator().env_page("Scara-C11-v2")
    assert "`rtol=1e-07`" in page and "`exact_switches=True`" in page and "300 steps" in page
    assert inspect.getdoc(ScaraEnv).partition("\n\n")[2] in page


def test_the_readme_is_short_and_gives_ci_its_test_command():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    commands = re.findall(r"```bash\n(python3 -m venv .*)\n```", readme)
    assert len(commands) >= 2 and "scara-c11 reproduce" in commands[0]
    ci = (ROOT / ".ci" / "run").read_text()
    assert commands[1] in ci  # CI runs exactly the README's test command


def test_no_document_points_outside_the_repository():
    texts = [ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "docs" / "envs").glob("*.md")]
    for path in texts:
        text = path.read_text()
        assert "shared/" not in text and "../shared" not in text, path


@pytest.mark.slow
def test_the_site_builds_with_warnings_as_errors(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    mkdocs = shutil.which("mkdocs") or sys.executable
    command = [mkdocs] if mkdocs != sys.executable else [sys.executable, "-m", "mkdocs"]
    result = subprocess.run([*command, "build", "--strict", "--site-dir", str(tmp_path / "site")], cwd=ROOT,
                            capture_output=True, text=True, timeout=600, env={**__import__("os").environ,
                                                                              "NO_MKDOCS_2_WARNING": "1"})
    assert result.returncode == 0, result.stdout + result.stderr
    for page in ("index.html", "envs/Scara-C11-v2/index.html", "comparison/index.html", "api/index.html"):
        assert (tmp_path / "site" / page).exists(), page


def test_the_published_results_are_small_and_hold_no_model():
    """docs/results keeps JSON, Markdown and figures under 2 MB in all; trained runs live in
    results/runs, beside the docs, where the loader finds them."""
    files = [p for p in (ROOT / "docs" / "results").rglob("*") if p.is_file()]
    assert files and {p.suffix for p in files} <= {".json", ".md", ".png"}
    assert sum(p.stat().st_size for p in files) < 2_000_000
