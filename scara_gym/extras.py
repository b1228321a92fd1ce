"""The install extras (pyproject.toml's optional-dependencies) and the one-line error a missing
one gives: the library's optional imports go through `require`, whose ImportError names
the extra to install, and ``scara-agents`` turns any missing optional module into that line and
exit status 2 (`missing_extra_message`).
"""

from __future__ import annotations

import importlib
from types import ModuleType

EXTRAS = {
    "torch": "train", "stable_baselines3": "train", "tensorboard": "train", "yaml": "train", "tqdm": "train",
    "rich": "train",
    "sbx": "offpolicy", "jax": "offpolicy", "sb3_contrib": "offpolicy",
    "casadi": "control",
    "minari": "datasets", "h5py": "datasets",
    "rliable": "compare", "pandas": "compare",
    "ray": "sweep", "optuna": "sweep",
    "numba_cuda": "cuda", "numba.cuda": "cuda",
    "mkdocs": "docs", "material": "docs", "mkdocstrings": "docs",
    "moviepy": "render",
    "rl_zoo3": "zoo",
}
"""optional module -> the extra that installs it (a dotted name is looked up before its top level)"""


def extra_of(module: str | None) -> str | None:
    """The extra that installs ``module`` (or the package it is part of); None for others."""
    if not module:
        return None
    parts = module.split(".")
    for end in range(len(parts), 0, -1):
        extra = EXTRAS.get(".".join(parts[:end]))
        if extra is not None:
            return extra
    return None


def missing_extra_message(module: str) -> str | None:
    """``torch is not installed: pip install "scara_gym[train]"`` for a module of an extra, else None."""
    extra = extra_of(module)
    if extra is None:
        return None
    return f'{module} is not installed: pip install "scara_gym[{extra}]" (the {extra} extra)'


def require(module: str) -> ModuleType:
    """``module`` imported, or a ModuleNotFoundError (an ImportError) that names the extra to install."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as error:
        missing = error.name or module
        # only the optional module itself (or its package) missing: a broken install deeper down says its own
        if not (module == missing or module.startswith(missing + ".") or missing.startswith(module + ".")):
            raise
        message = missing_extra_message(missing) or missing_extra_message(module)
        if message is None:
            raise
        raise ModuleNotFoundError(message, name=missing) from None
