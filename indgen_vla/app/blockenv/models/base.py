"""Shared pieces of the BlockEnv learners: input encoding and the output format (the method table: ``blockenv.methods``).

Every model maps an episode prefix to per-step action logits, either factored (three heads over rows,
columns and θ, as the paper's baselines) or joint over (row, column, θ) for the grid-structured models.
"""

from __future__ import annotations

import torch
from torch import nn

K_MAX = 10  # normaliser of the goal scalar g = k / k_max (the paper lets baselines see it)


def one_hot_grid(obs: torch.Tensor) -> torch.Tensor:
    """(..., G, G) int grid -> (..., 2, G, G) float planes: occupied, goal (empty and off-grid are 0).

    Occupancy rather than "distractor" keeps the grasp rule (free neighbours) one pattern whatever
    the neighbour is, which a local model needs to see the same rule at every level.
    """
    return torch.stack([(obs != 0).float(), (obs == 2).float()], dim=-3)


def flat_features(obs: torch.Tensor, levels: torch.Tensor) -> torch.Tensor:
    """(B, T, G, G) grids + (B,) levels -> (B, T, 2G² + 1): flattened planes and the goal scalar."""
    b, t = obs.shape[:2]
    planes = one_hot_grid(obs).flatten(2)
    g = (levels.float() / K_MAX)[:, None, None].expand(b, t, 1)
    return torch.cat([planes, g], dim=-1)


class FactoredHeads(nn.Module):
    """Three independent linear heads: rows, columns, orientation."""

    def __init__(self, d: int, grid: int):
        super().__init__()
        self.rows, self.cols, self.theta = nn.Linear(d, grid), nn.Linear(d, grid), nn.Linear(d, 2)

    def forward(self, h: torch.Tensor) -> dict[str, torch.Tensor]:
        return {"rows": self.rows(h), "cols": self.cols(h), "theta": self.theta(h)}


def mlp(d_in: int, d: int, d_out: int | None = None) -> nn.Sequential:
    return nn.Sequential(nn.Linear(d_in, d), nn.ReLU(), nn.Linear(d, d_out or d), nn.ReLU())
