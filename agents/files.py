"""Files the agents write and read: written whole or not at all, checked against their
digests, and loaded without running code.

Every file a run writes (models, checkpoints, configs, summaries, cache entries) goes to a
temporary file beside its target and is renamed into place, so that a crash at any instant
leaves either the old file or the new one, never a truncated one. Weights load with
``torch.load(weights_only=True)``, cache entries with ``numpy.load(allow_pickle=False)``: a
file that holds anything but tensors, numbers and plain containers is refused, not run. A
finished model folder (trained, published or shipped) carries a manifest of its files' SHA-256
digests (``SHA256SUMS``), checked before its policy loads: a changed or corrupted file is refused.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import io
import json
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np


def write_atomic(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` through a temporary file beside it, flushed to disk and renamed
    over the target (the rename is atomic on POSIX and Windows). The temporary file has one name
    per target (``.NAME.partial``; a file has one writer: run folders are locked), so one left by
    a killed writer is overwritten and renamed away by the next write of that file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode() if isinstance(data, str) else data
    temporary = path.with_name(f".{path.name}.partial")
    try:
        with open(temporary, "wb") as file:
            file.write(payload)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    return path


def write_json(path: str | Path, value, indent: int | None = 2) -> Path:
    """``value`` as JSON at ``path``, atomically."""
    return write_atomic(path, json.dumps(value, indent=indent))


def save_torch(value, path: str | Path) -> Path:
    """``torch.save`` of ``value``, atomically."""
    import torch

    buffer = io.BytesIO()
    torch.save(value, buffer)
    return write_atomic(path, buffer.getvalue())


def load_torch(path: str | Path, map_location="cpu"):
    """``torch.load`` of tensors, numbers and plain containers only (weights_only=True): a file
    with any other object, as a pickle payload would need, is refused with an error naming it."""
    import pickle

    import torch

    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, OSError) as error:
        raise ValueError(f"{path}: not a weights file this package wrote, refused without running it "
                         f"({type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''})") from None


def save_arrays(path: str | Path, arrays: dict[str, np.ndarray]) -> Path:
    """Numeric arrays as an .npz at ``path``, atomically (object arrays are refused)."""
    buffer = io.BytesIO()
    np.savez(buffer, **{k: np.asarray(v) for k, v in arrays.items()})
    return write_atomic(path, buffer.getvalue())


def load_arrays(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of an .npz, refusing pickled objects (allow_pickle=False)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (ValueError, OSError, EOFError) as error:
        raise ValueError(f"{path}: not an array file this package wrote, refused without running it "
                         f"({type(error).__name__}: {error})") from None


class RunLocked(RuntimeError):
    """Another live process holds a run folder's lock."""


_HELD: dict[Path, int] = {}
"""the run folders this process holds, with how many nested holds"""


@contextlib.contextmanager
def exclusive(folder: str | Path) -> Iterator[Path]:
    """Hold ``folder``'s lock (``folder/.lock``, its holder's pid inside) while the block runs:
    one writer per run folder. Re-entrant within a process; a folder another live process holds
    raises RunLocked naming that process. The kernel releases the lock when its holder dies, so
    a crashed run's folder is free again at once."""
    folder = Path(folder).resolve()
    if folder in _HELD:
        _HELD[folder] += 1
        try:
            yield folder
        finally:
            _HELD[folder] -= 1
        return
    folder.mkdir(parents=True, exist_ok=True)
    handle = open(folder / ".lock", "a+")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        holder = handle.read().strip() or "unknown"
        handle.close()
        raise RunLocked(f"{folder} is being written by another process (pid {holder}); wait for it or stop it") \
            from None
    handle.seek(0)
    handle.truncate()
    handle.write(f"{os.getpid()}\n")
    handle.flush()
    _HELD[folder] = 1
    try:
        yield folder
    finally:
        del _HELD[folder]
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()


POLICY_FILES = ("config.json", "model.zip", "model.pt", "vecnormalize.pkl")
"""the files of a finished run that its policy's actions depend on"""
DIGESTS = "SHA256SUMS"
"""a model folder's manifest: ``sha256sum``'s format, one line per file the folder's policy loads"""


def file_digest(path: str | Path) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def write_digests(folder: str | Path, names) -> Path:
    """The manifest of ``folder``: the SHA-256 of each of ``names`` that it holds (atomically)."""
    folder = Path(folder)
    lines = [f"{file_digest(folder / name)}  {name}\n" for name in sorted(names) if (folder / name).is_file()]
    return write_atomic(folder / DIGESTS, "".join(lines))


def verify_digests(folder: str | Path) -> None:
    """Where ``folder`` has a manifest, every file it lists must be there with that SHA-256; a file
    changed, corrupted or missing is refused with an error naming it (a folder without one: no check)."""
    folder = Path(folder)
    manifest = folder / DIGESTS
    if not manifest.exists():
        return
    for line in manifest.read_text().splitlines():
        digest, _, name = line.partition("  ")
        path = folder / name
        if not path.is_file():
            raise ValueError(f"{path}: listed in {manifest} but missing")
        if file_digest(path) != digest:
            raise ValueError(f"{path}: its SHA-256 is not the one {manifest} records; the file was changed or "
                             "corrupted, and is refused")
