"""A trained stable-baselines3 model as a policy (``--planner rl:PATH``).

Loading a model file unpickles Python objects, which can run arbitrary code: load only
files you trust, and only the one the user names (nothing here looks for models).
"""

from __future__ import annotations

import json
import time
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from mirrorpark_env.lidar import Lidar
from mirrorpark_env.scenario import ScenarioGeometry

from ..base import PlanStats, Policy
from .gear import learner_action, second_choice


def _train_json(model_path: Path) -> dict[str, Any]:
    meta = model_path.with_name("train.json")
    return json.loads(meta.read_text()) if meta.exists() else {}


def trained_lidar(model_path: str | Path) -> dict[str, Any] | None:
    """The lidar (rays, max_range) the model at ``model_path`` observed in training, from
    its train.json; None without one."""
    lidar = _train_json(Path(model_path)).get("config", {}).get("lidar", {})
    return lidar if lidar.get("rays") else None


@lru_cache(maxsize=4)
def load_model(path: str):
    """The model at ``path`` (SAC or TQC, as its train.json says), with its gear head where
    one is saved beside it (``gear.py``); cached per process."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"rl model: no such file {str(p)!r} (pass the model.zip that train-rl wrote)")
    algo = _train_json(p).get("algo", "sac")
    lidar = trained_lidar(p)
    env_config = {"lidar": lidar} if lidar else {}
    try:
        import gymnasium as gym

        import mirrorpark_env  # noqa: F401

        from .config import algo_class

        Algo = algo_class(algo)
    except ImportError:
        raise ValueError("rl model: needs the rl extra: pip install torch==2.13.0 && pip install -e '.[rl]'") from None
    try:
        # A model trained with HER needs an env to rebuild its buffer; only its spaces are used.
        model = Algo.load(p, env=gym.make("MirrorPark-v0", config=env_config), device="cpu")
    except Exception as err:  # noqa: BLE001  (a bad file: one clear line)
        raise ValueError(f"rl model: cannot load {str(p)!r} as {algo.upper()}: {err}") from None
    from .gear import load_head

    return load_head(model, p) or model  # a gear head beside it decides the standing gear (gear.py)


class RLPolicy(Policy):
    """Acts with a trained model's deterministic action; one ``PlanStats`` per decision."""

    def __init__(self, path: str | Path) -> None:
        super().__init__()
        self.path = str(Path(path).resolve())
        self.model = load_model(self.path)
        self.lidar_config = trained_lidar(self.path)  # what observation() adds where the env gives none
        self.name = f"rl:{path}"

    def reset(self, geometry: ScenarioGeometry) -> None:
        self.stats = []
        self.gave_up = False
        self.geometry = geometry
        cfg = self.lidar_config
        self._lidar = Lidar(geometry.obstacles, cfg["rays"], cfg["max_range"]) if cfg else None
        self._centre = geometry.vehicle.center_offset

    def observation(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> dict[str, np.ndarray]:
        """``obs`` as the model saw it in training: a model trained with a lidar ring gets its
        ranges, measured as the env measures them, where the env gives none."""
        if self._lidar is None or "lidar" in obs:
            return obs
        changed = self.changed_scene(info, self.geometry)
        if changed is not None:  # a late obstacle: the ring sees it from now on
            self.geometry = changed
            self._lidar = Lidar(changed.obstacles, self.lidar_config["rays"], self.lidar_config["max_range"])
        s = info["vehicle_state"]
        return {**obs, "lidar": self._lidar.read_body(s.x, s.y, s.theta, self._centre)}

    def second_choice(self, action: np.ndarray) -> np.ndarray:
        """The learner's standing start ``action`` in the other gear, for a filter that blocks
        it (``shield.py``; ``gear.second_choice``)."""
        return second_choice(self.model, action)

    def act(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        t0 = time.perf_counter()
        action = learner_action(self.model, self.observation(obs, info))
        self.stats.append(PlanStats(time.perf_counter() - t0, "ok"))
        return np.asarray(action, dtype=np.float32)
