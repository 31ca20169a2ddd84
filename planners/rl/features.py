"""The observation seen from the target: what a parking policy needs, at the scale it needs.

``MirrorPark-v0``'s observation holds the rear axle's pose and the target's in scene
coordinates divided by 10 m. The scene's obstacles are fixed relative to the slot (its
sizes and the road width are in the observation), so the pose relative to the target,
in the target's frame, says everything the absolute pose says, and the last centimetres
that the ISO check judges show up at a scale a small network can resolve: the offsets
enter both in metres / 5 (the whole scene) and squashed at 0.3 m (the slot).
"""

from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from mirrorpark_env.env import POS_SCALE

COARSE = 5.0  # [m] scale of the offsets over the scene
FINE = 0.3  # [m] scale of the squashed offsets inside the slot


class SlotFrameFeatures(BaseFeaturesExtractor):
    """(ex/5, ey/5, tanh(ex/0.3), tanh(ey/0.3), cos, sin of the heading error, then the
    observation's speed, acceleration, steering, road width, slot sizes and type): 15 values,
    ``ex, ey`` the rear axle's offset from the target in the target's frame [m]; then the
    lidar's ranges where the observation holds them."""

    def __init__(self, observation_space: gym.spaces.Dict) -> None:
        lidar = observation_space.spaces.get("lidar")
        rays = 0 if lidar is None else int(lidar.shape[0])
        super().__init__(observation_space, features_dim=15 + rays)
        self.rays = rays

    def forward(self, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        o, g = obs["observation"], obs["desired_goal"]
        dx, dy = (o[:, 0] - g[:, 0]) * POS_SCALE, (o[:, 1] - g[:, 1]) * POS_SCALE
        c, s = g[:, 2], g[:, 3]  # the target's heading
        ex, ey = c * dx + s * dy, -s * dx + c * dy
        ch = o[:, 2] * c + o[:, 3] * s  # cos and sin of (heading - target heading)
        sh = o[:, 3] * c - o[:, 2] * s
        head = torch.stack([ex / COARSE, ey / COARSE, torch.tanh(ex / FINE), torch.tanh(ey / FINE), ch, sh], dim=1)
        parts = [head, o[:, 4:13]] + ([obs["lidar"]] if self.rays else [])
        return torch.cat(parts, dim=1)
