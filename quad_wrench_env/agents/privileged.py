"""Policies that keep the observation's ``privileged`` block (the truth, ``docs/tasks.md``) from the actor.

An asymmetric actor-critic (Pinto et al. 2018) trains a critic that also reads what the vehicle cannot
measure, while the actor, the part that flies, reads only the sensors: "Learning to Fly in Seconds"
(Eschmann et al. 2024) gives its critic the true disturbance and rotor speeds. Here the env appends
the truth as one block (``privileged=True``); :class:`PrivilegedCriticPolicy` is SB3's actor-critic
policy with separate feature extractors, the actor's :class:`WithoutColumns` zeroing that block, so no
weight of the actor ever multiplies it.
"""

from __future__ import annotations

from typing import Any

import torch
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import FlattenExtractor


class WithoutColumns(FlattenExtractor):
    """The flattened observation with the columns ``hidden`` = ``(start, stop)`` set to zero."""

    def __init__(self, observation_space: spaces.Space, hidden: tuple[int, int]) -> None:
        super().__init__(observation_space)
        width = get_flattened_obs_dim(observation_space)
        start, stop = hidden
        if not 0 <= start < stop <= width:
            raise ValueError(f"hidden={hidden!r}: columns to hide must lie in [0, {width}) and not be empty")
        mask = torch.ones(width)
        mask[start:stop] = 0.0
        self.register_buffer("mask", mask)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.flatten(observations) * self.mask


class PrivilegedCriticPolicy(ActorCriticPolicy):
    """SB3's ``MlpPolicy`` whose critic reads the whole observation and whose actor reads it without the
    columns ``privileged`` = ``(start, stop)`` (``env.unwrapped.obs_layout["privileged"]``)."""

    def __init__(self, *args: Any, privileged: tuple[int, int], **kwargs: Any) -> None:
        self.privileged = tuple(privileged)
        kwargs["share_features_extractor"] = False
        super().__init__(*args, **kwargs)
        self.features_extractor = self.pi_features_extractor = WithoutColumns(
            self.observation_space, self.privileged
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return {**super()._get_constructor_parameters(), "privileged": self.privileged}
