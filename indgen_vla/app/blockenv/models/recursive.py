"""TRM (Tiny Recursive Model) adapted to BlockEnv: each grid is an independent puzzle whose answer y
is refined by a latent z; deep supervision carries (y, z) detached across steps.

Tokens are p×p patches of cells (p = 3 by default): each token reads its cells' one-hot contents and
decodes its cells' (θ) logits, so the answer is still the output grid, at a ninth of the tokens that
one token per cell needs (17 instead of 145 on a 12×12 grid; self-attention and the MLPs scale with it).
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F  # noqa: N812

from indgen_vla.app.blockenv.models.base import K_MAX
from indgen_vla.app.blockenv.models.sequence import PreNormBlock


class TRMPolicy(nn.Module):
    """z ← f(z + x + y) for L cycles, then y ← f(y + z); T−1 outer cycles without gradients and one with.

    Args:
        grid: G; the answer is read as 2 logits (θ) per cell, i.e. joint (r, c, θ) logits.
        d: hidden size. inner: L. outer: T. n_sup: deep-supervision steps (the most used at inference,
            where the halting head stops a puzzle early). patch: p, cells per token side.
    """

    history = False

    def __init__(
        self, grid: int, d: int = 128, inner: int = 2, outer: int = 2, n_sup: int = 2, patch: int = 3
    ):
        super().__init__()
        self.grid, self.inner, self.outer, self.n_sup, self.patch = grid, inner, outer, n_sup, patch
        self.side = -(-grid // patch)  # patches per side; the grid is padded with empty cells to side·p
        self.cell = nn.Linear(3 * patch * patch, d)
        self.pos = nn.Parameter(torch.randn(self.side * self.side + 1, d) * 0.02)
        self.goal = nn.Linear(1, d)
        # 2 bidirectional blocks shared by the z and y updates; positions come from self.pos
        self.f = nn.Sequential(*(PreNormBlock(d, ff_mult=2, rope=False, causal=False) for _ in range(2)))
        self.y0, self.z0 = nn.Parameter(torch.zeros(d)), nn.Parameter(torch.zeros(d))
        self.out = nn.Linear(d, 2 * patch * patch)
        self.halt = nn.Linear(d, 1)

    def embed(self, obs: torch.Tensor, levels: torch.Tensor) -> torch.Tensor:
        """(B, G, G) grids + (B,) levels -> (B, 1 + side², d): a goal token, then one token per patch."""
        b, g, p, s = obs.shape[0], self.grid, self.patch, self.side
        padded = F.pad(obs.long(), (0, s * p - g, 0, s * p - g))
        cells = F.one_hot(padded, 3).float()  # (B, sp, sp, 3)
        patches = cells.view(b, s, p, s, p, 3).permute(0, 1, 3, 2, 4, 5).reshape(b, s * s, p * p * 3)
        goal = self.goal((levels.float() / K_MAX)[:, None])[:, None]
        return torch.cat([goal, self.cell(patches)], dim=1) + self.pos

    def init_carry(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.y0.expand_as(x).clone(), self.z0.expand_as(x).clone()

    def latent_recursion(self, x, y, z):
        for _ in range(self.inner):
            z = self.f(z + x + y)
        return self.f(y + z), z

    def decode(self, y: torch.Tensor) -> torch.Tensor:
        """Answer tokens -> joint logits (B, G, G, 2) read off the output grid (padding cropped)."""
        b, p, s = y.shape[0], self.patch, self.side
        per_patch = self.out(y[:, 1:]).view(b, s, s, p, p, 2)
        full = per_patch.permute(0, 1, 3, 2, 4, 5).reshape(b, s * p, s * p, 2)
        return full[:, : self.grid, : self.grid]

    def deep_recursion(self, x, y, z):
        """One supervision step: returns detached carry, joint logits (B, G, G, 2) and a halting logit."""
        with torch.no_grad():
            for _ in range(self.outer - 1):
                y, z = self.latent_recursion(x, y, z)
        y, z = self.latent_recursion(x, y, z)
        return (y.detach(), z.detach()), self.decode(y), self.halt(y.mean(1)).squeeze(-1)

    def forward(self, obs, levels, prev_actions=None):
        """Inference on (B, T, G, G): every step is an independent puzzle, refined until it halts."""
        b, t = obs.shape[:2]
        flat = obs.reshape(b * t, self.grid, self.grid)
        x = self.embed(flat, levels.repeat_interleave(t))
        y, z = self.init_carry(x)
        answer, halted = None, torch.zeros(b * t, dtype=torch.bool)
        for _ in range(self.n_sup):
            (y, z), logits, halt = self.deep_recursion(x, y, z)
            answer = logits if answer is None else torch.where(halted[:, None, None, None], answer, logits)
            halted |= halt > 0
            if halted.all():
                break
        return {"joint": answer.reshape(b, t, self.grid, self.grid, 2)}
