"""Expert demonstrations: a planner's closed-loop episodes as arrays, and as a Minari dataset.

``mirrorpark collect`` (``evaluation/collect.py``) runs the episodes, each written whole to
``OUT/episodes/<case_id>.npz``, so an interrupted collection resumes without redoing or
losing episodes; the Minari dataset is then built from all of them in ``OUT/minari/`` (rebuilt on every
run, so it always holds every recorded episode). Load it with
``MINARI_DATASETS_PATH=OUT/minari`` and ``minari.load_dataset("mirrorpark/<planner>-v0")``,
or from its path with ``minari.MinariDataset("OUT/minari/mirrorpark/<planner>-v0/data")``.

Per step it holds the observation (the env's ``Dict``), the normalised action, the reward,
termination, truncation (also where the policy gave up and the car stood), and the infos
that matter: ``is_success``, ``collision``, ``min_margin`` (the smallest ISO margin) and
``heading_error_deg``. Each episode's options name its scenario (``{"scenario": case_id}``),
so ``env.reset(options=...)`` replays it; the dataset's description names the planner.
"""

from __future__ import annotations

import os
import re
import shutil
import warnings
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

from mirrorpark_env.scenario import Scenario

from ..base import Policy, run_episode

INFO_KEYS = ("is_success", "collision", "min_margin", "heading_error_deg")


def record_episode(env, policy: Policy, sc: Scenario) -> dict[str, np.ndarray]:
    """One closed-loop episode of ``policy`` on ``sc`` in ``env``, as arrays (observations n + 1)."""
    record: list[tuple] = []
    run_episode(env, policy, sc, record=record)
    obs0, info0 = record[0]
    steps = record[1:]
    out: dict[str, np.ndarray] = {}
    for key in obs0:
        out[f"obs/{key}"] = np.stack([obs0[key]] + [s[1][key] for s in steps])
    out["actions"] = np.asarray([s[0] for s in steps], np.float32)
    out["rewards"] = np.asarray([s[2] for s in steps], float)
    out["terminations"] = np.asarray([s[3] for s in steps], bool)
    out["truncations"] = np.asarray([s[4] for s in steps], bool)
    for key, values in _infos([info0] + [s[5] for s in steps]).items():
        out[f"info/{key}"] = values
    return out


def _infos(infos: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """The recorded infos as (n + 1, 1) arrays (Minari's storage wants a trailing axis)."""
    return {
        "is_success": np.array([[i["is_success"]] for i in infos], bool),
        "collision": np.array([[i["collision"]] for i in infos], bool),
        "min_margin": np.array([[min(i["margins"].values())] for i in infos], float),
        "heading_error_deg": np.array([[i["heading_error_deg"]] for i in infos], float),
    }


def dataset_id(planner: str) -> str:
    return f"mirrorpark/{re.sub(r'[^A-Za-z0-9_-]+', '_', planner)}-v0"


def build_dataset(planner: str, files: list[Path], root: Path):
    """The Minari dataset of these episode files, (re)built under ``root``."""
    import minari
    from minari.data_collector import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage

    buffers = []
    for k, f in enumerate(files):
        with np.load(f) as z:
            buffers.append(
                EpisodeBuffer(
                    id=k,
                    options={"scenario": f.stem},
                    observations={key[4:]: z[key] for key in z.files if key.startswith("obs/")},
                    actions=z["actions"],
                    rewards=z["rewards"].tolist(),
                    terminations=z["terminations"].tolist(),
                    truncations=z["truncations"].tolist(),
                    infos={key[5:]: z[key] for key in z.files if key.startswith("info/")},
                )
            )
    did = dataset_id(planner)
    shutil.rmtree(root / did, ignore_errors=True)
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root.resolve())
    try:
        # Minari 0.5 re-measures the whole dataset folder after every episode it writes
        # (``get_size`` walks every file), which makes a build quadratic in the episodes:
        # 1,500 episodes took 91 s. The size is measured once, at the end, instead.
        with warnings.catch_warnings(), mock.patch.object(MinariStorage, "get_size", lambda self: 0.0):
            warnings.simplefilter("ignore", UserWarning)  # author e-mail and eval env: not ours to give
            dataset = minari.create_dataset_from_buffers(
                did,
                buffers,
                env="MirrorPark-v0",
                algorithm_name=planner,
                description=f"MirrorPark-v0 episodes of the {planner!r} planner on {len(files)} cases "
                "(each episode's options name its scenario); recorded with `mirrorpark collect`.",
                data_format="arrow",
            )
        dataset.storage.update_metadata({"dataset_size": dataset.storage.get_size()})
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old
    return root / did
