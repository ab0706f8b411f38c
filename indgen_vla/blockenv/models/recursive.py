"""TRM (Tiny Recursive Model) adapted to BlockEnv: each grid is an independent puzzle whose answer y
(one token per cell) is refined by a latent z; deep supervision carries (y, z) detached across steps."""

from __future__ import annotations

import torch
from torch import nn

from indgen_vla.blockenv.models.base import K_MAX


class Block(nn.Module):
    """Pre-norm bidirectional self-attention + MLP over cell tokens."""

    def __init__(self, d: int, heads: int = 4):
        super().__init__()
        self.n1, self.n2 = nn.LayerNorm(d), nn.LayerNorm(d)
        self.attn = nn.MultiheadAttention(d, heads, batch_first=True)
        self.ff = nn.Sequential(nn.Linear(d, 2 * d), nn.GELU(), nn.Linear(2 * d, d))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.n1(x)
        x = x + self.attn(h, h, h, need_weights=False)[0]
        return x + self.ff(self.n2(x))


class TRMPolicy(nn.Module):
    """z ← f(z + x + y) for L cycles, then y ← f(y + z); T−1 outer cycles without gradients and one with.

    Args:
        grid: G; the answer is read as 2 logits (θ) per cell token, i.e. joint (r, c, θ) logits.
        d: hidden size. inner: L. outer: T. n_sup: deep-supervision steps (also used at inference).
    """

    history = False

    def __init__(self, grid: int, d: int = 64, inner: int = 2, outer: int = 2, n_sup: int = 2):
        super().__init__()
        self.grid, self.inner, self.outer, self.n_sup = grid, inner, outer, n_sup
        self.cell = nn.Embedding(3, d)
        self.pos = nn.Parameter(torch.randn(grid * grid + 1, d) * 0.02)
        self.goal = nn.Linear(1, d)
        self.f = nn.Sequential(Block(d), Block(d))  # 2 blocks shared by the z and y updates
        self.y0, self.z0 = nn.Parameter(torch.zeros(d)), nn.Parameter(torch.zeros(d))
        self.out = nn.Linear(d, 2)
        self.halt = nn.Linear(d, 1)

    def embed(self, obs: torch.Tensor, levels: torch.Tensor) -> torch.Tensor:
        cells = self.cell(obs.long().flatten(1))  # (B, G², d)
        goal = self.goal((levels.float() / K_MAX)[:, None])[:, None]
        return torch.cat([goal, cells], dim=1) + self.pos

    def init_carry(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.y0.expand_as(x).clone(), self.z0.expand_as(x).clone()

    def latent_recursion(self, x, y, z):
        for _ in range(self.inner):
            z = self.f(z + x + y)
        return self.f(y + z), z

    def deep_recursion(self, x, y, z):
        """One supervision step: returns detached carry, joint logits (B, G, G, 2) and a halting logit."""
        with torch.no_grad():
            for _ in range(self.outer - 1):
                y, z = self.latent_recursion(x, y, z)
        y, z = self.latent_recursion(x, y, z)
        logits = self.out(y[:, 1:]).view(-1, self.grid, self.grid, 2)
        return (y.detach(), z.detach()), logits, self.halt(y.mean(1)).squeeze(-1)

    def forward(self, obs, levels, prev_actions=None):
        """Inference on (B, T, G, G): every step is an independent puzzle, refined n_sup times."""
        b, t = obs.shape[:2]
        flat = obs.reshape(b * t, self.grid, self.grid)
        x = self.embed(flat, levels.repeat_interleave(t))
        y, z = self.init_carry(x)
        for _ in range(self.n_sup):
            (y, z), logits, _ = self.deep_recursion(x, y, z)
        return {"joint": logits.view(b, t, self.grid, self.grid, 2)}
