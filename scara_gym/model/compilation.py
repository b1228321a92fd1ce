"""How the compiled core is compiled and cached.

numba keeps machine code on disk (``cache=True``) and checks only the file that defines
a function: an edit to a function it calls or inlines from another file, or to a
constant it folds in, leaves stale machine code running. The locators below key the
cache of every compiled function of this package by the content of *all* its compiled
sources (``COMPILED_SOURCES``), so that any edit to any of them recompiles everything
that may depend on it. They take precedence over numba's own locators for these files
only; numba's choice of directory (``NUMBA_CACHE_DIR``, the package's ``__pycache__``,
or the user-wide cache for read-only installs) is kept.

The first compilation takes about 25 s on a 2-core machine (measured 2026-12-05); a one-line message on
stderr says so when it starts (``COMPILE_MESSAGE``).
"""

from __future__ import annotations

import functools
import hashlib
import sys
from pathlib import Path

from numba.core import caching, event

PACKAGE_DIR = Path(__file__).resolve().parents[1]
# every module of the package that defines compiled functions (a test keeps this list complete)
COMPILED_SOURCES = (
    "model/compilation.py", "model/records.py", "model/dynamics.py", "model/integrator.py",
    "envs/core.py",
)

JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
# for the functions of the integrator's inner loop: a compiled call with array arguments
# costs reference counting on each array, more than the arithmetic of these bodies
JIT_INLINE = dict(JIT, inline="always")
# for the functions that only borrow arrays (the integrator and the environment step: they neither
# allocate nor return a new array): no reference counting (NRT) at all. numba otherwise emits an
# atomic incref/decref pair for every array bound at every inlined call site, whether or not the
# branch holding it runs, which costs more than the integration step's own arithmetic. The
# results are the same bits. A function compiled so must not allocate an array or return one that
# outlives its arguments; those that do (new_workspace, the entry points called from Python, the
# parallel loops) keep JIT.
JIT_BORROW = dict(JIT, _nrt=False)

COMPILE_MESSAGE = ("scara_gym: compiling the model with numba (first use after an install or "
                   "an edit: about 25 s on 2 cores; the machine code is cached on disk)")


@functools.cache
def _digest(files: tuple[tuple[str, float, int], ...]) -> bytes:
    sha = hashlib.sha256()
    for path, _, _ in files:
        sha.update(Path(path).read_bytes())
    return sha.digest()


def source_key(package_dir: Path = PACKAGE_DIR, sources=COMPILED_SOURCES) -> bytes:
    """sha256 over the compiled sources' contents (memoized on their mtime and size)."""
    files = []
    for name in sources:
        path = Path(package_dir) / name
        stat = path.stat()
        files.append((str(path), stat.st_mtime, stat.st_size))
    return _digest(tuple(files))


class _KeyedStamp:
    """Mixin for numba's source-file locators: only this package's files, stamped by the key
    of all compiled sources instead of the defining file alone.
    """

    package_dir = PACKAGE_DIR
    sources = COMPILED_SOURCES

    def get_source_stamp(self):
        return source_key(self.package_dir, self.sources)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            Path(py_file).resolve().relative_to(cls.package_dir)
        except ValueError:
            return None
        return super().from_function(py_func, py_file)


class KeyedUserProvidedLocator(_KeyedStamp, caching.UserProvidedCacheLocator):
    pass


class KeyedInTreeLocator(_KeyedStamp, caching.InTreeCacheLocator):
    pass


class KeyedUserWideLocator(_KeyedStamp, caching.UserWideCacheLocator):
    pass


def install_locators(*locators) -> None:
    """Put keyed locators first in numba's list (idempotent); before any @njit(cache=True)."""
    classes = caching.CacheImpl._locator_classes
    for locator in reversed(locators):
        if locator not in classes:
            classes.insert(0, locator)


class _FirstCompileMessage(event.Listener):
    """Prints COMPILE_MESSAGE once per process, when numba starts compiling (not loading)
    a function of this package.
    """

    def __init__(self) -> None:
        self.printed = False

    def on_start(self, ev) -> None:
        if self.printed:
            return
        dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        if module.startswith("scara_gym."):
            self.printed = True
            print(COMPILE_MESSAGE, file=sys.stderr, flush=True)

    def on_end(self, ev) -> None:
        pass


install_locators(KeyedUserProvidedLocator, KeyedInTreeLocator, KeyedUserWideLocator)
FIRST_COMPILE = _FirstCompileMessage()
event.register("numba:compile", FIRST_COMPILE)
