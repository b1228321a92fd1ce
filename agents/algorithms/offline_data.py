"""Offline data read safely: a Minari dataset loaded without running any code it names, its
environment made from the package's own registry, and every episode checked before it is used.

A Minari dataset's ``metadata.json`` names an ``env_spec.entry_point``, which Minari imports and
calls (``recover_environment()``, and ``minari.load_dataset`` where the metadata holds no
space): whoever can write a dataset could then run code as its reader. `load` and
`environment` never do; behaviour cloning (agents.algorithms.bc) and the datasets' replay
(agents.experiments.datasets) read datasets through them, and `checked_episodes` refuses
values that are not finite or lie outside their spaces.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.files import verify_digests
from scara_gym.extras import require
from scara_gym.model.checks import UserError
from scara_gym.registration import ENV_IDS

DATASET_FILES = ("data/metadata.json", "data/main_data.hdf5")
"""a dataset's files (Minari's HDF5 layout), listed in the manifest of the datasets the package builds"""


def _environment(name: str, metadata: dict) -> gym.Env:
    """The environment a dataset's metadata records, made from the package's own registry by its id:
    the entry point the metadata names is compared with that id's, never imported."""
    try:
        spec = json.loads(metadata["env_spec"])
        env_id, entry_point, kwargs = spec["id"], spec["entry_point"], spec.get("kwargs") or {}
    except (KeyError, TypeError, ValueError):
        raise UserError(f"dataset {name}: its metadata records no environment (env_spec with id and entry_point); "
                        "refused") from None
    if env_id not in ENV_IDS:
        raise UserError(f"dataset {name}: its environment {env_id!r} is not one of the package's {list(ENV_IDS)}; "
                        "refused, its entry point never imported")
    ours = gym.spec(env_id).entry_point
    if entry_point != ours:
        raise UserError(f"dataset {name}: its env_spec names entry point {entry_point!r} for {env_id!r}, not the "
                        f"package's {ours!r}: refused, never imported")
    if not isinstance(kwargs, dict):
        raise UserError(f"dataset {name}: its env_spec's kwargs are not a mapping; refused")
    try:
        return gym.make(env_id, **kwargs)
    except (TypeError, ValueError) as error:
        raise UserError(f"dataset {name}: its environment's arguments are refused ({error})") from None


def _spaces(name: str, metadata: dict, env: gym.Env) -> tuple:
    """(observation space, action space) of a dataset: its metadata's, which must be its environment's."""
    require("minari")
    from minari.serialization import deserialize_space

    spaces = []
    for key, own in (("observation_space", env.observation_space), ("action_space", env.action_space)):
        if key not in metadata:  # Minari would build the environment of the metadata's entry point to learn it
            spaces.append(own)
            continue
        try:
            recorded = deserialize_space(metadata[key])
        except Exception as error:  # noqa: BLE001  (any malformed space: refused in one line)
            raise UserError(f"dataset {name}: its {key} cannot be read ({type(error).__name__}); refused") from None
        if recorded != own:
            raise UserError(f"dataset {name}: its {key} {recorded} is not its environment's {own}; refused")
        spaces.append(recorded)
    return tuple(spaces)


def load(name: str):
    """The Minari dataset ``name`` from Minari's data folder, loaded without running any code it
    names: its files checked against its manifest where it has one (the datasets the package
    builds), its environment made from the package's registry (`_environment`) and its spaces
    checked against that environment's. FileNotFoundError where it is not there."""
    require("minari")
    import minari
    from minari.dataset._storages import get_minari_storage
    from minari.storage import get_dataset_path

    folder = Path(get_dataset_path(name))
    if not (folder / "data" / "metadata.json").is_file():
        raise FileNotFoundError(f"no dataset {name!r} in Minari's data folder ({datasets_root()}); build it with "
                                f"scara-agents datasets build {name}")
    checked = verify_digests(folder, DATASET_FILES)
    try:
        metadata = checked.json("data/metadata.json")
    except ValueError:
        raise UserError(f"dataset {name}: {folder / 'data' / 'metadata.json'} is not JSON; refused") from None
    if not isinstance(metadata, dict) or metadata.get("data_format") != "hdf5":
        raise UserError(f"dataset {name}: not an HDF5 dataset (data_format "
                        f"{metadata.get('data_format') if isinstance(metadata, dict) else None!r}); refused")
    observation_space, action_space = _spaces(name, metadata, _environment(name, metadata))
    try:  # the HDF5 file opened here: a truncated or corrupted one is refused in one line
        import h5py

        h5py.File(folder / "data" / "main_data.hdf5", "r").close()
        storage = get_minari_storage("hdf5")(folder / "data", observation_space, action_space,
                                             jpeg_encoding=bool(metadata.get("jpeg_encoding", True)))
        return minari.MinariDataset(storage)
    except (OSError, KeyError, ValueError) as error:
        raise _unreadable(name, folder, error) from None


def _unreadable(name: str, folder: Path, error: Exception) -> ValueError:
    return ValueError(f"dataset {name}: {folder / 'data' / 'main_data.hdf5'} cannot be read "
                      f"({str(error).splitlines()[0] if str(error) else type(error).__name__}); refused")


def checked_episodes(dataset, env: gym.Env):
    """Every episode of a MinariDataset, each checked against ``env``'s spaces (`check_episode`);
    a data file that cannot be read is refused in one line naming the dataset."""
    iterator = dataset.iterate_episodes()
    while True:
        try:
            episode = next(iterator)
        except StopIteration:
            return
        except (OSError, KeyError) as error:
            raise _unreadable(dataset.id, dataset.storage.data_path.parent, error) from None
        check_episode(dataset.id, episode, env.observation_space, env.action_space)
        yield episode


def environment(dataset) -> gym.Env:
    """The environment of a MinariDataset, from the package's own registry (never the entry point
    its metadata names: Minari's ``recover_environment()`` imports and calls that), its spaces
    checked against the dataset's."""
    metadata = dataset.storage.metadata
    env = _environment(dataset.id, metadata)
    if env.observation_space != dataset.observation_space or env.action_space != dataset.action_space:
        raise UserError(f"dataset {dataset.id}: its spaces are not its environment's ({env.spec.id}); refused")
    return env


def check_episode(name: str, episode, observation_space, action_space) -> None:
    """Refuse an episode whose observations or actions are not finite or lie outside their space,
    in one line naming the dataset, the episode, the field and the first step."""
    for field, values, space in (("observations", episode.observations, observation_space),
                                 ("actions", episode.actions, action_space)):
        values = np.asarray(values, dtype=np.float64)
        outside = (values < space.low) | (values > space.high)
        for problem, bad in (("a value that is not finite", ~np.isfinite(values)),
                             (f"a value outside the {field[:-1]} space {_bounds(space)}", outside)):
            if bad.any():
                step = int(np.argwhere(bad)[0][0])
                raise UserError(f"dataset {name}, episode {episode.id}: {field} hold {problem} (step {step}); refused")


def _bounds(space) -> str:
    low, high = np.unique(space.low), np.unique(space.high)
    if len(low) == 1 and len(high) == 1:
        return f"[{low[0]:g}, {high[0]:g}]"
    return "bounds"


def datasets_root() -> Path:
    """Minari's local data folder: MINARI_DATASETS_PATH, else ~/.minari/datasets."""
    return Path(os.environ.get("MINARI_DATASETS_PATH") or Path.home() / ".minari" / "datasets")
