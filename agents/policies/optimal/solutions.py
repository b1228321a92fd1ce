"""The shipped minimum-time solutions (package data, ``agents/optimal_solutions/*.json``) and their lookup."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from agents.files import json_record
from agents.policies.optimal.transcription import CollocationConfig
from scara_gym import DEFAULT_PARAMS, ScaraParams

SOLUTIONS = Path(__file__).resolve().parents[2] / "optimal_solutions"


def cached_solution(start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3), params: ScaraParams = DEFAULT_PARAMS,
                    wall_margin: float = CollocationConfig.wall_margin) -> dict | None:
    """The shipped held solution for this start, target, parameter set and wall margin, if there is one."""
    for path in sorted(SOLUTIONS.glob("*.json")):
        data = json_record(path)
        if (np.allclose(data["start"], start, atol=1e-12) and np.allclose(data["target"], target, atol=1e-12)
                and data["params"] == params_key(params) and data["config"]["wall_margin"] == wall_margin):
            return data
    return None


def params_key(params: ScaraParams) -> dict:
    record = params.to_record()
    return {name: np.asarray(record[name]).tolist() for name in record.dtype.names
            if name not in ("target", "dec")}
