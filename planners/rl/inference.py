"""A trained actor's deterministic action in one direct pass (the ``rl:`` policy's hot path).

``model.predict`` spends most of its time on one observation outside the network: input
checks, building an action distribution to take its mode. For the squashed-Gaussian
actors of SAC and TQC the deterministic action is ``tanh(mu(latent_pi(features)))``,
scaled to the action space; ``actor_pass`` runs exactly those modules on the same float32
tensors, so its action equals ``predict``'s bit for bit (tests/test_rl.py checks it) at
well under half the time, and it hands back the features for a gear head (``gear.py``).
"""

from __future__ import annotations

import numpy as np


def direct(model) -> bool:
    """Whether ``model``'s deterministic action can be taken in one direct pass: a
    squashed-Gaussian actor without state-dependent exploration (SAC, TQC)."""
    actor = getattr(model, "actor", None)
    return (
        actor is not None
        and getattr(model.policy, "squash_output", False)
        and not getattr(actor, "use_sde", True)
        and all(hasattr(actor, m) for m in ("features_extractor", "latent_pi", "mu"))
    )


def actor_pass(model, obs: dict[str, np.ndarray]):
    """The deterministic actions (n, 2) for the rows of ``obs`` (one observation or a batch)
    and the actor's features (a tensor) they came from."""
    import torch

    actor = model.actor
    if actor.training:  # as predict does (no dropout or batch norm here, but be exact)
        model.policy.set_training_mode(False)
    spaces = model.observation_space.spaces
    with torch.inference_mode():
        t = {k: torch.from_numpy(np.asarray(obs[k], dtype=np.float32).reshape(-1, *s.shape)) for k, s in spaces.items()}
        features = actor.features_extractor(t)
        scaled = torch.tanh(actor.mu(actor.latent_pi(features)))
    return model.policy.unscale_action(scaled.numpy()), features


def deterministic_action(model, obs: dict[str, np.ndarray]) -> np.ndarray:
    """``model.predict(obs, deterministic=True)[0]``, through ``actor_pass`` where it applies."""
    if not direct(model):
        return model.predict(obs, deterministic=True)[0]
    actions, _ = actor_pass(model, obs)
    return actions if np.ndim(obs["observation"]) == 2 else actions[0]
