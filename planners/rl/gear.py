"""A learned gear for a standing car (``dagger.gear``): which way to go is chosen, not averaged.

A DAgger learner fitted by regression stalls where it stands: its expert's labels there
split between the hold (re-steering before it moves), forward and back, and a mean or a
median of them is a hold (docs/rl.md). With ``dagger.gear`` the expert's labels at a stand
also carry the gear its path starts in, a small classifier learns that gear from the same
features as the actor, and a fixed rule drives a standing car as the expert's tracker does:
hold while the wheels turn to the actor's steering command, then go in the classified gear.
Moving, the actor's action is used as it is. The rule is part of the policy: a model with
a gear head runs it wherever it is loaded (``rl:``, ``rl-shield:``, DAgger's rollouts).

The head is saved beside the model as ``<model>.gear.pt`` (a state dict and three numbers,
loaded with ``weights_only``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mirrorpark_env.vehicle import VehicleParams
from planners.common.tracker import TrackerConfig

from .inference import actor_pass, deterministic_action, direct

STAND_SPEED = 0.02  # [m/s] the tracker's "standing" (planners/common/tracker.py)
STEER_TOLERANCE = TrackerConfig().steer_tolerance  # [rad] the tracker's standing re-steer is done within this


def gear_path(model_path: str | Path) -> Path:
    """Where the gear head of the model at ``model_path`` lives."""
    p = Path(model_path)
    return p.with_name(p.name.removesuffix(".zip") + ".gear.pt")


def make_head(features_dim: int, hidden: int = 128):
    """An MLP from the actor's features to one logit: > 0 forward, < 0 back."""
    import torch

    return torch.nn.Sequential(
        torch.nn.Linear(features_dim, hidden),
        torch.nn.ReLU(),
        torch.nn.Linear(hidden, hidden),
        torch.nn.ReLU(),
        torch.nn.Linear(hidden, 1),
    )


def standing(obs: dict[str, np.ndarray], params: VehicleParams | None = None) -> np.ndarray:
    """Which rows of a (batched) observation stand still."""
    p = params or VehicleParams.table_ii()
    o = np.asarray(obs["observation"]).reshape(-1, 13)
    return np.abs(o[:, 4] * p.speed_max) <= STAND_SPEED


class GearedModel:
    """A trained model whose standing decisions go through its gear head (module docstring).

    ``predict`` answers as the model's does; everything else is the model's."""

    def __init__(self, model, head, go: tuple[float, float]) -> None:
        self.model = model
        self.head = head
        self.go = go  # normalised acceleration that starts the car (forward, back)
        self.params = VehicleParams.table_ii()
        self._direct = direct(model)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.model, name)

    def gear_logits(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The head's logit for each row of ``obs`` (> 0: forward)."""
        import torch

        with torch.no_grad():
            t, _ = self.model.policy.obs_to_tensor(obs)
            return self._logits(self.model.actor.extract_features(t, self.model.actor.features_extractor))

    def _logits(self, features) -> np.ndarray:
        import torch

        with torch.inference_mode():
            return self.head(features).reshape(-1).cpu().numpy()

    def predict(self, obs: dict[str, np.ndarray], state=None, episode_start=None, deterministic: bool = True):
        if deterministic and self._direct:  # one pass gives the action and the head's features
            acts, features = actor_pass(self.model, obs)  # a fresh array: changed in place below
            acts = np.asarray(acts, dtype=np.float32)
            batched = np.ndim(obs["observation"]) == 2
        else:
            action, state = self.model.predict(obs, state, episode_start, deterministic)
            acts, features = np.array(action, dtype=np.float32).reshape(-1, 2), None
            batched = np.ndim(action) == 2
        stand = standing(obs, self.params)
        if stand.any():
            p = self.params
            o = np.asarray(obs["observation"]).reshape(-1, 13)
            logits = self.gear_logits(obs) if features is None else self._logits(features)
            ready = np.abs((o[:, 6] - acts[:, 1]) * p.max_steer_rad) < STEER_TOLERANCE
            go = np.where(logits > 0, self.go[0], self.go[1]).astype(np.float32)
            acts[:, 0] = np.where(stand, np.where(ready, go, 0.0), acts[:, 0])
        return (acts if batched else acts[0]), state

    def other_gear(self, action: np.ndarray) -> np.ndarray:
        """``action`` (a standing start) in the other gear: the other starting acceleration,
        the same steering."""
        out = np.array(action, dtype=np.float32)
        out[0] = self.go[1] if action[0] > 0 else self.go[0]
        return out

    def save(self, path: str | Path) -> None:
        """The model at ``path`` and its head beside it."""
        import torch

        self.model.save(path)
        torch.save({"head": self.head.state_dict(), "go": list(self.go)}, gear_path(path))


def second_choice(model, action: np.ndarray) -> np.ndarray:
    """A standing start ``action`` of ``model`` in the other gear, the steering kept: a geared
    model's other starting acceleration, else the same command mirrored (``shield.py``)."""
    if isinstance(model, GearedModel):
        return model.other_gear(action)
    return np.array([-action[0], action[1]], dtype=np.float32)


def learner_action(model, obs: dict[str, np.ndarray]) -> np.ndarray:
    """The deterministic action of a trained model, or of a ``GearedModel``, for ``obs``."""
    if isinstance(model, GearedModel):
        return model.predict(obs)[0]
    return deterministic_action(model, obs)


def load_head(model, path: str | Path) -> GearedModel | None:
    """``model`` with the head saved beside ``path``; None where there is none."""
    import torch

    g = gear_path(path)
    if not g.exists():
        return None
    saved = torch.load(g, map_location="cpu", weights_only=True)
    head = make_head(model.actor.features_dim)
    head.load_state_dict(saved["head"])
    head.eval()
    return GearedModel(model, head, tuple(float(v) for v in saved["go"]))


def go_accels(obs: dict[str, np.ndarray], actions: np.ndarray, gears: np.ndarray) -> tuple[float, float]:
    """The median normalised acceleration with which the expert starts forward and back from a
    stand (1 and -1 where the data holds no start of that gear)."""
    stand = standing(obs)
    out = []
    for sign in (1, -1):
        a = actions[stand & (gears == sign) & (sign * actions[:, 0] > 0.05), 0]
        out.append(float(np.median(a)) if len(a) else float(sign))
    return out[0], out[1]


def fit_head(model, head, obs: dict[str, np.ndarray], gears: np.ndarray, cfg, progress: bool = True) -> list[float]:
    """Fit ``head`` (logistic loss) to the gears labelled at standing states (``gears``: +1,
    -1, 0 for none); the mean loss of each epoch (``cfg.bc`` epochs, batch size, rate)."""
    import torch
    from tqdm import tqdm

    rows = np.flatnonzero(gears != 0)
    if not len(rows):
        raise ValueError("dagger.gear: no standing state with a labelled gear to fit the gear head on")
    torch.manual_seed(cfg.seed + 1)
    rng = np.random.default_rng(cfg.seed + 1)
    opt = torch.optim.Adam(head.parameters(), lr=cfg.bc.learning_rate)
    target_all = (gears > 0).astype(np.float32)
    history = []
    head.train()
    for _ in tqdm(range(cfg.bc.epochs), desc="gear head", unit="epoch", disable=not progress):
        order = rng.permutation(rows)
        total = 0.0
        for b0 in range(0, len(order), cfg.bc.batch_size):
            idx = order[b0 : b0 + cfg.bc.batch_size]
            with torch.no_grad():
                t, _ = model.policy.obs_to_tensor({k: v[idx] for k, v in obs.items()})
                f = model.actor.extract_features(t, model.actor.features_extractor)
            loss = torch.nn.functional.binary_cross_entropy_with_logits(
                head(f).reshape(-1), torch.as_tensor(target_all[idx], device=f.device)
            )
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(idx)
        history.append(total / len(rows))
    head.eval()
    return history
