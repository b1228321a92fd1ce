# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""Minari's two writers for the random tier, side by side: DataCollector (needs JAX: pip install
"minari[create]") and create_dataset_from_buffers from the package's own loop (docs/datasets.md).

    python lab/minari_writers.py

DataCollector records no infos here: with record_infos=True it fails on this env, whose step infos
differ from its reset info and carry reach_time only on success."""
import os
import tempfile
import time

import minari
import numpy as np

from agents.experiments import datasets as D


def collector(n, root):
    os.environ["MINARI_DATASETS_PATH"] = root
    env = minari.DataCollector(D.make_env("c11"), record_infos=False)
    policy = D.RandomActions(env, 0)
    started = time.perf_counter()
    for seed in range(n):
        obs, _ = env.reset(seed=seed)
        while True:
            obs, r, term, trunc, info = env.step(policy(obs).astype(np.float32))
            if term or trunc: break
    env.create_dataset("scara/dc/random-v0", algorithm_name="random", author="x", author_email="x", code_permalink="x", description="x")
    return time.perf_counter() - started

def buffers(n, root):
    os.environ["MINARI_DATASETS_PATH"] = root
    env = D.make_env("c11")
    started = time.perf_counter()
    b = D.episode_buffers(env, D.RandomActions(env, 0), range(n))
    minari.create_dataset_from_buffers("scara/bf/random-v0", b, env=env, algorithm_name="random", author="x",
                                       author_email="x", code_permalink="x", description="x", data_format="hdf5")
    return time.perf_counter() - started

n = 100
for round_ in range(2):
    for f in (collector, buffers):
        with tempfile.TemporaryDirectory() as root:
            t = f(n, root)
            print(f"round {round_} {f.__name__}: {t:.2f} s for {n * 300} steps, {t / (n * 300) * 1e6:.0f} us/step")
