"""Files the agents write and read: written whole or not at all, checked against their
digests, and loaded without running code.

Every file a run writes (models, checkpoints, configs, summaries, cache entries) goes to a
temporary file beside its target and is renamed into place, so that a crash at any instant
leaves either the old file or the new one, never a truncated one. Weights load with
``torch.load(weights_only=True)``, cache entries with ``numpy.load(allow_pickle=False)``: a
file that holds anything but tensors, numbers and plain containers is refused, not run. A
finished model folder (trained, published or shipped) carries a manifest of its files' SHA-256
digests (``SHA256SUMS``). Trust is content, not a name: a manifest lists every file the folder's
policy may load, a manifest that lists nothing trusts nothing, a file the folder holds that its
loader wants but the manifest does not list is refused unread, and every file is read once into
memory, checked against its digest and deserialized from those same bytes (the manifest too:
its digest is taken of the bytes that were parsed), so a file swapped after its check is never
the one loaded (`verify_digests`, `Checked`).

SB3's ``model.zip`` and replay buffers and its ``vecnormalize.pkl`` are pickle by design: loading
one runs whatever code it holds. They load only from a trusted folder (`require_trusted`):
one whose manifest this machine's own runs wrote (recorded in the trust store, `trust_store`,
which is refused when it is a symlink, another user's or writable by others), one shipped with
the package (`SHIPPED_MANIFESTS`) or published beside the published runs (`published_runs`: the
clone's ``results/runs``, or ``$SCARA_GYM_PUBLISHED_RUNS``), or any folder when the user says so
(``--trust``, or ``SCARA_GYM_TRUST=1`` for a program and the workers it starts).

A run folder is claimed by its trainer under its lock (`claim_run_folder`): a folder that
holds a run of other settings, or one written by a newer version, is refused by name; one that holds
the same run needs ``resume`` (continue it) or ``overwrite`` (train it again from scratch).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import io
import json
import os
import re
import shutil
import stat
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from scara_gym.extras import require
from scara_gym.model.checks import UserError


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


def write_json_lines(path: str | Path, value, open_levels: int = 2) -> Path:
    """``value`` as JSON at ``path``, atomically, with its first ``open_levels`` levels one item
    per line and everything below them compact: a large record (the comparison's hundreds of
    entries) stays small on disk and still diffs an entry at a time."""
    def text(item, levels: int) -> str:
        if levels <= 0 or not isinstance(item, (dict, list)) or not item:
            return json.dumps(item, separators=(",", ":"))
        if isinstance(item, dict):
            return "{\n" + ",\n".join(f"{json.dumps(str(k))}:{text(v, levels - 1)}" for k, v in item.items()) + "\n}"
        return "[\n" + ",\n".join(text(v, levels - 1) for v in item) + "\n]"

    return write_atomic(path, text(value, open_levels) + "\n")


def save_torch(value, path: str | Path) -> Path:
    """``torch.save`` of ``value``, atomically."""
    require("torch")
    import torch

    buffer = io.BytesIO()
    torch.save(value, buffer)
    return write_atomic(path, buffer.getvalue())


def load_torch(path: str | Path, map_location="cpu", data: bytes | None = None):
    """``torch.load`` of tensors, numbers and plain containers only (weights_only=True): a file
    with any other object, as a pickle payload would need, is refused with an error naming it.
    ``data``: the file's bytes, already read and checked (`verify_digests`): loaded from
    them, ``path`` only naming the file."""
    import pickle

    require("torch")
    import torch

    try:
        source = path if data is None else io.BytesIO(data)
        return torch.load(source, map_location=map_location, weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, OSError) as error:
        raise UserError(f"{path}: not a weights file this package wrote, refused without running it "
                        f"({type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''})") from None


def save_arrays(path: str | Path, arrays: dict[str, np.ndarray]) -> Path:
    """Numeric arrays as an .npz at ``path``, atomically (object arrays are refused)."""
    buffer = io.BytesIO()
    np.savez(buffer, **{k: np.asarray(v) for k, v in arrays.items()})
    return write_atomic(path, buffer.getvalue())


def load_arrays(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of an .npz, refusing pickled objects (allow_pickle=False)."""
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
        raise UserError(f"{path}: not an array file this package wrote, refused without running it "
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
    before = set(os.listdir(folder)) if folder.is_dir() else None
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
    except BaseException:
        _tidy(folder, before)
        raise
    finally:
        del _HELD[folder]
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()


def _tidy(folder: Path, before: set[str] | None) -> None:
    """After a holder of ``folder`` failed: where all it added is the lock and the run record (a
    mistake refused before anything trained), remove them, and the folder where it made it, so that
    a refused command leaves nothing behind. Anything more (a checkpoint, logs) stays for a resume."""
    added = set(os.listdir(folder)) - (before or set())
    if added - {".lock", RUN_RECORD}:
        return
    for name in added:
        (folder / name).unlink(missing_ok=True)
    if before is None:
        with contextlib.suppress(OSError):
            folder.rmdir()


POLICY_FILES = ("config.json", "model.zip", "model.pt", "vecnormalize.pkl")
"""the files of a finished run that its policy's actions depend on"""
WEIGHTS_FILES = ("config.json", "model.pt")
"""the files a torch run's policy (torch PPO, behaviour cloning) loads: JSON and weights_only weights"""
PICKLE_FILES = ("model.zip", "vecnormalize.pkl", "replay_buffer.pkl")
"""the files of SB3 runs that are pickle by design: loading one runs any code it holds"""
DIGESTS = "SHA256SUMS"
"""a model folder's manifest: ``sha256sum``'s format, one line per file the folder's policy loads"""


def file_digest(path: str | Path) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def write_digests(folder: str | Path, names: Iterable[str]) -> Path:
    """The manifest of ``folder``: the SHA-256 of each of ``names`` that it holds (atomically). A
    manifest that would list nothing is refused: it would vouch for nothing, and a digest of it
    would be the SHA-256 of no bytes, the same for every empty manifest anywhere."""
    folder = Path(folder)
    lines = [f"{file_digest(folder / name)}  {name}\n" for name in sorted(names) if (folder / name).is_file()]
    if not lines:
        raise UserError(f"{folder}: none of {sorted(names)} to list in {DIGESTS}; an empty manifest is never written")
    return write_atomic(folder / DIGESTS, "".join(lines))


def read_once(path: str | Path) -> bytes:
    """A regular file's bytes, read through one descriptor, not through a symlink (ValueError
    naming the path otherwise): what is checked and then used is this one read."""
    path = Path(path)
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as error:
        if path.is_symlink():
            raise UserError(f"{path}: a symlink, refused (a folder's files are its own)") from None
        raise UserError(f"{path}: cannot be read ({error.strerror})") from None
    with os.fdopen(descriptor, "rb") as file:
        if not stat.S_ISREG(os.fstat(file.fileno()).st_mode):
            raise UserError(f"{path}: not a regular file, refused")
        return file.read()


_DIGEST = re.compile(r"[0-9a-f]{64}")


def _listed_name(name: str) -> bool:
    """A name a manifest may list: a relative path inside its folder, no '..', '.', hidden or
    empty part."""
    parts = name.split("/")
    return bool(name) and not name.startswith("/") and all(p and not p.startswith(".") for p in parts)


def read_manifest(folder: str | Path) -> tuple[str, dict[str, str]] | None:
    """``folder``'s manifest, read once: (the SHA-256 of its bytes, name -> SHA-256 of each file
    it lists), or None without one. A line that is not ``DIGEST  NAME`` with a name inside the
    folder, a name listed twice, and a manifest that lists nothing are refused by name."""
    path = Path(folder) / DIGESTS
    if not path.exists() and not path.is_symlink():
        return None
    data = read_once(path)
    listed: dict[str, str] = {}
    try:
        text = data.decode()
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a manifest (not text), refused") from None
    for number, line in enumerate(text.splitlines(), 1):
        digest, separator, name = line.partition("  ")
        if not separator or not _DIGEST.fullmatch(digest) or not _listed_name(name):
            raise UserError(f"{path}, line {number}: not 'SHA-256  NAME' with NAME inside the folder, refused")
        if name in listed:
            raise UserError(f"{path}: lists {name} twice, refused")
        listed[name] = digest
    if not listed:
        raise UserError(f"{path} lists no file: an empty manifest trusts nothing (a manifest lists every file the "
                        "folder may load), refused")
    return hashlib.sha256(data).hexdigest(), listed


@dataclass(frozen=True)
class Checked:
    """A folder's files as they were read once and checked (`verify_digests`): load from
    these bytes, never from the folder again."""

    folder: Path
    files: dict[str, bytes]
    """name -> bytes: every file the manifest lists (without a manifest: the wanted ones the folder holds)"""
    manifest: str | None
    """the SHA-256 of the manifest's bytes, None where the folder has none"""

    def __contains__(self, name: str) -> bool:
        return name in self.files

    def bytes(self, name: str) -> bytes:
        if name not in self.files:
            raise FileNotFoundError(f"{self.folder / name}: missing" +
                                    (f" from {self.folder / DIGESTS}" if self.manifest else ""))
        return self.files[name]

    def json(self, name: str) -> dict:
        """The JSON object (a record: every JSON file of a folder is one) ``name`` holds."""
        return json_record(self.folder / name, self.bytes(name))


def json_record(path: str | Path, data: bytes | str | None = None) -> dict:
    """The JSON object in ``path`` (or in ``data``, its bytes already read): a file that is not
    JSON, or holds anything but an object (``[]``, a number), is refused in one line naming it."""
    try:
        value = json.loads(Path(path).read_bytes() if data is None else data)
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise UserError(f"{path}: not JSON ({error})") from None
    if not isinstance(value, dict):
        raise UserError(f"{path}: holds a JSON {type(value).__name__}, not the object (the record) expected")
    return value


def verify_digests(folder: str | Path, wanted: Iterable[str] = ()) -> Checked:
    """Read ``folder``'s manifest and every file it lists, once each, into memory, every one
    with the SHA-256 its manifest records; returns them (`Checked`). A file listed but
    missing or changed is refused by name, and so is a file of ``wanted`` (what the caller may
    load) that the folder holds and its manifest does not list: a partial manifest trusts nothing
    for it, and it is never read. A folder without a manifest: the files of ``wanted`` it holds,
    unchecked (its loaders run no code: weights_only, JSON; pickle needs `require_trusted`)."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    if manifest is None:
        return Checked(folder, {name: read_once(folder / name) for name in wanted if (folder / name).is_file()}, None)
    digest, listed = manifest
    for name in wanted:
        if name not in listed and ((folder / name).exists() or (folder / name).is_symlink()):
            raise UserError(f"{folder / name}: not listed in {folder / DIGESTS}, which lists every file the folder "
                            "may load: refused unread")
    files = {}
    for name, expected in listed.items():
        path = folder / name
        if not path.exists() and not path.is_symlink():
            raise UserError(f"{path}: listed in {folder / DIGESTS} but missing")
        data = read_once(path)
        if hashlib.sha256(data).hexdigest() != expected:
            raise UserError(f"{path}: its SHA-256 is not the one {folder / DIGESTS} records; the file was changed or "
                            "corrupted, and is refused")
        files[name] = data
    return Checked(folder, files, digest)


# -- trust of pickle files ----------------------------------------------------------------------
TRUST_ENV = "SCARA_GYM_TRUST"
"""set to "1" (as ``--trust`` does for a command and the workers it starts): trust every folder"""
TRUST_STORE_ENV = "SCARA_GYM_TRUST_STORE"
"""a file to keep the trust store in instead of the user's data folder"""
SHIPPED_MANIFESTS = Path(__file__).resolve().parent / "shipped_manifests.txt"
"""the SHA-256 of the manifest of every model folder shipped with the package (``agents/models``),
one per line: those folders are trusted on every machine (package data, read only)"""
PUBLISHED_LIST = "published_manifests.txt"
"""the name of the list of published manifests in a folder of published runs (``results/runs``):
the SHA-256 of every run's manifest, written by ``campaign --publish`` beside the runs it copies
and committed with them"""
PUBLISHED_RUNS_ENV = "SCARA_GYM_PUBLISHED_RUNS"
"""the folder of the published runs (``ENV_ID/MODE/NAME/seedN`` and their PUBLISHED_LIST), for a
package installed outside the clone: ``export SCARA_GYM_PUBLISHED_RUNS=CLONE/results/runs``"""
CHECKOUT_RUNS = Path(__file__).resolve().parents[1] / "results" / "runs"
"""the published runs of the clone the package runs from (none for an installed package)"""
PUBLISHED_MANIFESTS_ENV = "SCARA_GYM_PUBLISHED_MANIFESTS"
"""a list to read and extend instead of the published runs' (the tests' own, so that their
publishes leave the committed list as it is)"""


def published_runs() -> Path | None:
    """The folder of the published runs: ``$SCARA_GYM_PUBLISHED_RUNS``, else the clone's
    ``results/runs`` where the package runs from a clone that has it, else None (an installed
    package: the runs are not part of it)."""
    if os.environ.get(PUBLISHED_RUNS_ENV):
        return Path(os.environ[PUBLISHED_RUNS_ENV])
    return CHECKOUT_RUNS if (CHECKOUT_RUNS / PUBLISHED_LIST).is_file() else None


PUBLISHED_RUNS_MISSING = (
    "the published runs (the repository's results/runs) are not part of the installed package: in a "
    f"clone of the repository pass --runs CLONE/results/runs, or set {PUBLISHED_RUNS_ENV}=CLONE/results/runs")
"""what a command that needs the published runs says where it finds none"""


def require_published_runs(runs: str | Path | None = None) -> Path:
    """``runs`` (a folder the user named) or the published runs (`published_runs`), which must
    exist: UserError saying how to get them otherwise."""
    folder = Path(runs) if runs is not None else published_runs()
    if folder is None:
        raise UserError(f"no published runs found; {PUBLISHED_RUNS_MISSING}")
    if not folder.is_dir():
        raise UserError(f"no folder {str(folder)!r} of published runs; {PUBLISHED_RUNS_MISSING}")
    return folder


class UntrustedFolder(UserError):
    """A folder whose pickle files neither this machine's runs nor the package vouch for."""


def trust_store() -> Path:
    """The file that lists the manifests this machine's own runs wrote (``$SCARA_GYM_TRUST_STORE``,
    else ``$XDG_DATA_HOME/scara_gym/trusted_manifests``, by default under ``~/.local/share``)."""
    if os.environ.get(TRUST_STORE_ENV):
        return Path(os.environ[TRUST_STORE_ENV])
    data = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    return data / "scara_gym" / "trusted_manifests"


def manifest_digest(folder: str | Path) -> str | None:
    """The SHA-256 of ``folder``'s manifest (None without one): it names every file the manifest lists."""
    manifest = Path(folder) / DIGESTS
    return file_digest(manifest) if manifest.is_file() else None


def published_manifests() -> Path | None:
    """The list of published manifests in use: ``$SCARA_GYM_PUBLISHED_MANIFESTS``, else the
    published runs' PUBLISHED_LIST (`published_runs`; None without them)."""
    if os.environ.get(PUBLISHED_MANIFESTS_ENV):
        return Path(os.environ[PUBLISHED_MANIFESTS_ENV])
    runs = published_runs()
    return None if runs is None else runs / PUBLISHED_LIST


def _digests_in(path: Path | None) -> set[str]:
    if path is None or not path.is_file():
        return set()
    return {line.strip() for line in path.read_text().splitlines() if len(line.strip()) == 64}


def _checked_store(descriptor: int, store: Path) -> None:
    """Refuse a trust store that others could write: one line naming it (a store another user may
    change would let them make any folder trusted, and so run code as this user)."""
    status = os.fstat(descriptor)
    if not stat.S_ISREG(status.st_mode):
        problem = "not a regular file"
    elif status.st_uid != os.getuid():
        problem = f"owned by another user (uid {status.st_uid})"
    elif status.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        problem = f"writable by group or others (mode {stat.S_IMODE(status.st_mode):o}; chmod go-w it)"
    else:
        return
    raise UserError(f"{store}: the trust store is {problem}, so others could make any folder trusted; refused "
                    f"(or set {TRUST_STORE_ENV} to a file of your own)")


def _open_store(store: Path, flags: int) -> int | None:
    """A descriptor on the trust store, opened without following a symlink and checked
    (`_checked_store`); None where it does not exist and ``flags`` do not create it."""
    try:
        descriptor = os.open(store, flags | os.O_NOFOLLOW, 0o600)
    except FileNotFoundError:
        return None
    except OSError as error:
        if store.is_symlink():
            raise UserError(f"{store}: the trust store is a symlink, so others could make any folder trusted; "
                            f"refused (or set {TRUST_STORE_ENV} to a file of your own)") from None
        raise UserError(f"{store}: the trust store cannot be opened ({error.strerror})") from None
    try:
        _checked_store(descriptor, store)
    except BaseException:
        os.close(descriptor)
        raise
    return descriptor


def _store_text() -> str:
    """The trust store's text, read through a checked descriptor ('' where there is none)."""
    store = trust_store()
    descriptor = _open_store(store, os.O_RDONLY)
    if descriptor is None:
        return ""
    with os.fdopen(descriptor, "rb") as file:
        return file.read().decode(errors="replace")


def _trusted_here(digest: str) -> bool:
    return digest in {line.strip() for line in _store_text().splitlines()}


def record_trusted(folder: str | Path) -> None:
    """Add ``folder``'s manifest to the trust store: its files are this machine's own. One line
    appended in one write, on a line of its own (a crash leaves the store without that line, or
    with part of it, which matches no manifest). A manifest that lists nothing is refused
    (`read_manifest`): it is never recorded."""
    manifest = read_manifest(folder)
    if manifest is None:
        raise UserError(f"{folder}: no {DIGESTS} to record as trusted")
    digest = manifest[0]
    store = trust_store()
    text = _store_text()
    if digest in {line.strip() for line in text.splitlines()}:
        return
    store.parent.mkdir(parents=True, exist_ok=True)
    cut = bool(text) and not text.endswith("\n")
    descriptor = _open_store(store, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
    try:
        os.write(descriptor, f"{chr(10) if cut else ''}{digest}\n".encode())  # after a line a crash cut short
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def publish_manifest(folder: str | Path, listing: str | Path) -> None:
    """Add ``folder``'s manifest to the list of published manifests ``listing`` (the
    PUBLISHED_LIST of the published runs' folder; ``$SCARA_GYM_PUBLISHED_MANIFESTS`` instead where
    set), keeping it sorted, written atomically: commit it with the published run, which is then
    trusted wherever that folder is the published runs' (`published_runs`). Never a file of the
    installed package. A manifest that lists nothing is refused."""
    manifest = read_manifest(folder)
    if manifest is None:
        raise UserError(f"{folder}: no {DIGESTS} to publish")
    listed = Path(os.environ.get(PUBLISHED_MANIFESTS_ENV) or listing)
    known = _digests_in(listed)
    if manifest[0] not in known:
        write_atomic(listed, "".join(f"{d}\n" for d in sorted(known | {manifest[0]})))


def _vouched(digest: str) -> bool:
    """Whether the package ships the folder of the manifest of this SHA-256, the published runs
    list it, or this machine's runs wrote it."""
    return (digest in _digests_in(SHIPPED_MANIFESTS) or digest in _digests_in(published_manifests())
            or _trusted_here(digest))


def is_trusted(folder: str | Path) -> bool:
    """True when ``folder`` has a manifest that lists files and that the package ships or publishes or this
    machine's runs wrote (its files are checked when they are read: `require_trusted`)."""
    try:
        manifest = read_manifest(folder)
    except ValueError:
        return False
    return manifest is not None and _vouched(manifest[0])


def trust_everything() -> bool:
    """Whether the user trusts every folder (``SCARA_GYM_TRUST=1``, as ``--trust`` sets it)."""
    return os.environ.get(TRUST_ENV) == "1"


def require_trusted(folder: str | Path, trust: bool = False, wanted: Iterable[str] = ()) -> Checked:
    """The files of ``folder`` to unpickle from, read once and checked (`verify_digests`: a
    file of ``wanted`` it holds but its manifest does not list is refused unread), when that
    manifest is trusted (published, or this machine's own) or ``trust`` (or
    `trust_everything`) says so; UntrustedFolder otherwise. Unpickle from the bytes it
    returns, never from the folder again."""
    folder = Path(folder)
    checked = verify_digests(folder, wanted)
    if trust or trust_everything() or (checked.manifest is not None and _vouched(checked.manifest)):
        return checked
    raise UntrustedFolder(
        f"{folder}: its pickle files (SB3's model.zip, replay buffers, vecnormalize.pkl) were not written by a run "
        f"on this machine nor shipped with the package, and loading a pickle runs any code it holds; if you trust "
        f"where the folder came from, pass --trust (or set {TRUST_ENV}=1; in Python, trust=True)")


# -- run folders --------------------------------------------------------------------------------
RUN_FORMAT = 1
"""the layout of the run folders this version writes (``run.json``'s ``run_format``); it reads
those of this format and older ones"""
RUN_RECORD = "run.json"
"""what a run is, written by its trainer before it trains: trainer, algorithm, env, mode, seed and
the settings that must stay the same when it is resumed"""
TRAINED = ("model.zip", "model.pt", "checkpoint.pt", "summary.json", "snapshot/progress.json",
           "snapshot.old/progress.json")
"""what a folder holds once a run has trained in it (before that there is nothing to lose)"""
RUN_ENTRIES = ("config.json", "summary.json", "model.zip", "model.pt", "vecnormalize.pkl", "checkpoint.pt", DIGESTS,
               RUN_RECORD, "evaluation.npz", "snapshot", "snapshot.old", "snapshot.partial", "eval", "tb",
               "checkpoints")
"""the files and folders a trainer writes in a run folder: what ``overwrite`` removes, and only that"""
IDENTITY = ("trainer", "algo", "env_id", "control_mode", "seed")


def holds_run(folder: str | Path) -> bool:
    """True when ``folder`` holds a run that has trained (`TRAINED`)."""
    return any((Path(folder) / name).exists() for name in TRAINED)


def recorded_run(folder: str | Path) -> dict:
    """What the run in ``folder`` is: its run.json, else (runs written before it) what its
    config.json says of `IDENTITY`; a run of a newer format is refused by name."""
    folder = Path(folder)
    if (folder / RUN_RECORD).is_file():
        record = json_record(folder / RUN_RECORD)
    elif (folder / "config.json").is_file():
        config = json_record(folder / "config.json")
        torch_run = config.get("algo") in ("torch-ppo", "bc", "dagger")  # the torch trainers write their algo as their name
        record = {"trainer": config["algo"] if torch_run else "sb3", "algo": config.get("algo", "ppo"),
                  "env_id": config.get("env_id"), "seed": config.get("seed"),
                  "control_mode": config.get("control_mode") if torch_run
                  else config.get("env_kwargs", {}).get("control_mode")}
    else:
        return {}
    written = record.get("run_format", 1)
    if not isinstance(written, int) or written > RUN_FORMAT:
        raise UserError(f"out: {folder} was written by a newer version of scara_gym (run format {written}; this "
                        f"version reads {RUN_FORMAT} and older): train with that version, or give another folder")
    return record


def _plain(value):
    return json.loads(json.dumps(value, default=str))


def _differences(recorded: dict, record: dict) -> list[str]:
    """What differs between two run records, identity first, then each setting, where both say."""
    pairs = [(k, recorded[k], record[k]) for k in IDENTITY if k in recorded and k in record]
    if "settings" in recorded and "settings" in record:
        old, new = recorded["settings"], record["settings"]
        pairs += [(k, old.get(k), new.get(k)) for k in sorted(set(old) | set(new))]
    return [f"{k} {was!r} (this run: {now!r})" for k, was, now in pairs if was != now]


def claim_run_folder(folder: str | Path, run: dict, resume: bool, overwrite: bool) -> bool:
    """The gate every trainer passes under the folder's lock before it trains into ``folder``.
    ``run``: what the new run is (`IDENTITY` and ``settings``, the settings a resumed run must
    share). A folder that holds a trained run (`holds_run`) is emptied with ``overwrite``
    (its RUN_ENTRIES only), refused when it holds another run or one of a newer version, and
    otherwise needs ``resume``. Writes run.json; returns True when a run is there to continue."""
    folder = Path(folder)
    record = {"run_format": RUN_FORMAT, **_plain(run)}
    held = holds_run(folder)
    if held and overwrite:
        for name in RUN_ENTRIES:
            path = folder / name
            if path.is_dir():
                shutil.rmtree(path)
            elif path.exists():
                path.unlink()
    elif held:
        differences = _differences(recorded_run(folder), record)
        if differences:
            raise UserError(f"out: {folder} holds another run ({'; '.join(differences)}); give another "
                            "folder, or overwrite=True (--overwrite) to replace it")
        if not resume:
            raise UserError(f"out: {folder} holds this run already; resume=True (--resume) continues it (a finished "
                            "one: nothing to do), overwrite=True (--overwrite) trains it again from scratch, or give "
                            "another folder")
        write_json(folder / RUN_RECORD, record)
        return True
    write_json(folder / RUN_RECORD, record)
    return False
