"""Per-step learners: the MLP that MAML meta-trains, and our local translation-equivariant policy."""

from __future__ import annotations

import torch
from torch import nn

from indgen_vla.app.blockenv.models.base import FactoredHeads, flat_features, mlp, one_hot_grid


class StepMLPPolicy(nn.Module):
    """A memoryless MLP over the flattened grid and goal scalar (MAML's net).

    Args:
        joint: one softmax over every (r, c, θ) instead of three factored heads. A memoryless policy needs it
            wherever the demonstrations hold two right answers for one state (the oracle's random arm at the
            first grasp): independent row and column argmaxes can combine the row of one tip with the column
            of the other, a blocked or empty cell that the policy then repeats until the budget runs out.
    """

    history = False

    def __init__(self, grid: int, d: int, joint: bool = False):
        super().__init__()
        self.grid, self.joint = grid, joint
        self.enc = mlp(2 * grid * grid + 1, d)
        self.heads = nn.Linear(d, grid * grid * 2) if joint else FactoredHeads(d, grid)

    def forward(self, obs, levels, prev_actions=None):
        h = self.enc(flat_features(obs, levels))
        if self.joint:
            return {"joint": self.heads(h).view(*obs.shape[:2], self.grid, self.grid, 2)}
        return self.heads(h)


class LocalConvPolicy(nn.Module):
    """Ours: scores every (cell, θ) from the cell and its two neighbours along θ's approach axis.

    One small scorer is shared by every cell (translation equivariance) and by both orientations (the
    θ = 0 score is the θ = 1 scorer applied to the transposed grid). Why it extrapolates: a grasp's
    legality and whether the cell is the goal are facts about exactly those three cells, the same at
    every level and position; zero padding makes off-grid cells look empty, as the environment treats
    them. Where it would not: any rule that needs context beyond the approach axis (e.g. a budget that
    forbids wasted removals, or goals defined relative to distant objects).
    """

    history = False

    def __init__(self, channels: int = 32):
        super().__init__()
        self.scorer = nn.Sequential(
            nn.Conv2d(2, channels, kernel_size=(1, 3), padding=(0, 1)), nn.ReLU(),
            nn.Conv2d(channels, channels, 1), nn.ReLU(),
            nn.Conv2d(channels, 1, 1),
        )  # fmt: skip

    def forward(self, obs, levels, prev_actions=None):
        b, t, g, _ = obs.shape
        x = one_hot_grid(obs.reshape(b * t, g, g))  # (BT, 2, G, G)
        left_right = self.scorer(x)[:, 0]
        top_bottom = self.scorer(x.transpose(-1, -2))[:, 0].transpose(-1, -2)
        logits = torch.stack([top_bottom, left_right], dim=-1)  # θ = 0 top/bottom, θ = 1 left/right
        return {"joint": logits.reshape(b, t, g, g, 2)}
