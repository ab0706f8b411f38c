"""History-conditioned baselines: LSTM, causal Transformers (learned or rotary positions), Goal/Act, Ind."""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F  # noqa: N812

from indgen_vla.app.blockenv.models.base import FactoredHeads, flat_features, mlp, one_hot_grid

MAX_LEN = 48


class RNNPolicy(nn.Module):
    """Goal-conditioned 2-layer LSTM; the hidden state carries the episode."""

    history = True

    def __init__(self, grid: int, d: int):
        super().__init__()
        self.enc = mlp(2 * grid * grid + 1, d)
        self.lstm = nn.LSTM(d, d, num_layers=2, batch_first=True)
        self.heads = FactoredHeads(d, grid)

    def forward(self, obs, levels, prev_actions=None):
        h, _ = self.lstm(self.enc(flat_features(obs, levels)))
        return self.heads(h)


def rotate_half(x: torch.Tensor) -> torch.Tensor:
    x1, x2 = x[..., : x.shape[-1] // 2], x[..., x.shape[-1] // 2 :]
    return torch.cat([-x2, x1], dim=-1)


def rope(q: torch.Tensor, k: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rotary position embedding over the time axis (dim -2) of (B, H, T, Dh) queries and keys."""
    t, dh = q.shape[-2], q.shape[-1]
    inv = 1.0 / (10000 ** (torch.arange(0, dh, 2, device=q.device).float() / dh))
    ang = torch.arange(t, device=q.device).float()[:, None] * inv[None]
    cos, sin = torch.cat([ang.cos(), ang.cos()], -1), torch.cat([ang.sin(), ang.sin()], -1)
    return q * cos + rotate_half(q) * sin, k * cos + rotate_half(k) * sin


class PreNormBlock(nn.Module):
    """Pre-norm self-attention + MLP; rotary positions and a causal mask for histories, neither for puzzles (TRM)."""

    def __init__(self, d: int, heads: int = 4, ff_mult: int = 4, rope: bool = True, causal: bool = True):
        super().__init__()
        self.h, self.rope, self.causal = heads, rope, causal
        self.n1, self.n2 = nn.LayerNorm(d), nn.LayerNorm(d)
        self.qkv, self.proj = nn.Linear(d, 3 * d), nn.Linear(d, d)
        self.ff = nn.Sequential(nn.Linear(d, ff_mult * d), nn.GELU(), nn.Linear(ff_mult * d, d))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, t, d = x.shape
        q, k, v = self.qkv(self.n1(x)).view(b, t, 3, self.h, d // self.h).permute(2, 0, 3, 1, 4)
        if self.rope:
            q, k = rope(q, k)
        a = F.scaled_dot_product_attention(q, k, v, is_causal=self.causal)
        x = x + self.proj(a.transpose(1, 2).reshape(b, t, d))
        return x + self.ff(self.n2(x))


class TransformerPolicy(nn.Module):
    """Causal Transformer over the whole observation history; the action is read at the last position.

    Args:
        rope: rotary positions in pre-norm blocks instead of learned absolute embeddings (post-norm).
        goal_act: prepend o_0 as a goal token and append the previous action (in [0, 1]^3) to each token.
    """

    history = True

    def __init__(self, grid: int, d: int, rope: bool = False, goal_act: bool = False, layers: int = 2):
        super().__init__()
        self.grid, self.rope, self.goal_act = grid, rope, goal_act
        d_in = 2 * grid * grid + 1 + (3 if goal_act else 0)
        self.enc = mlp(d_in, d)
        if rope:
            self.blocks = nn.ModuleList(PreNormBlock(d) for _ in range(layers))
            self.norm = nn.LayerNorm(d)
        else:
            self.pos = nn.Parameter(torch.randn(MAX_LEN, d) * 0.02)
            layer = nn.TransformerEncoderLayer(d, 4, 4 * d, dropout=0.0, batch_first=True)
            self.encoder = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        if goal_act:
            self.goal_tag = nn.Parameter(torch.zeros(d))
        self.heads = self._heads(d)

    def _heads(self, d: int) -> nn.Module:
        return FactoredHeads(d, self.grid)

    def trunk(self, obs, levels, prev_actions=None) -> torch.Tensor:
        feats = flat_features(obs, levels)
        if self.goal_act:
            prev = torch.zeros(*obs.shape[:2], 3) if prev_actions is None else prev_actions.float()
            scale = torch.tensor([self.grid - 1, self.grid - 1, 1.0])
            feats = torch.cat([feats, prev / scale], dim=-1)
        x = self.enc(feats)
        if self.goal_act:  # o_0 as a goal token the model can always attend back to
            x = torch.cat([x[:, :1] + self.goal_tag, x], dim=1)
        if self.rope:
            for blk in self.blocks:
                x = blk(x)
            x = self.norm(x)
        else:
            t = x.shape[1]
            mask = torch.triu(torch.full((t, t), float("-inf")), diagonal=1)
            x = self.encoder(x + self.pos[:t], mask=mask, is_causal=True)
        return x[:, 1:] if self.goal_act else x

    def forward(self, obs, levels, prev_actions=None):
        return self.heads(self.trunk(obs, levels, prev_actions))


class IndPolicy(TransformerPolicy):
    """Ind: RoPE Transformer + per-cell/orientation legality head + factored joint (r, c, θ) head.

    At inference unoccupied cells are masked to -inf (``mask``) and ``gate_scale`` · log σ(legal) is added to
    the pick logits (the additive legality gate; 0 turns it off). ``legal_head`` says where the legality
    logits come from: a linear read-out of the trunk's embedding of the flattened grid ('global', the
    paper's "head" on its Transformer), a small convolution shared by every cell over the current grid
    ('local'), or the sum of both ('both').
    """

    def __init__(
        self, grid: int, d: int, gate_scale: float = 1.0, mask: bool = True, legal_head: str = "global"
    ):
        self.legal_head = legal_head
        super().__init__(grid, d, rope=True)
        self.gate_scale, self.mask = gate_scale, mask
        if legal_head != "global":
            self.local_legal = nn.Sequential(
                nn.Conv2d(2, 32, 3, padding=1),
                nn.ReLU(),
                nn.Conv2d(32, 32, 1),
                nn.ReLU(),
                nn.Conv2d(32, 2, 1),
            )

    def _heads(self, d: int) -> nn.Module:
        g = self.grid
        heads = {"cell": nn.Linear(d, g * g), "theta": nn.Linear(d, g * g * 2)}
        if self.legal_head != "local":
            heads["legal"] = nn.Linear(d, g * g * 2)
        return nn.ModuleDict(heads)

    def forward(self, obs, levels, prev_actions=None):
        h = self.trunk(obs, levels, prev_actions)
        b, t = h.shape[:2]
        g = self.grid
        joint = (self.heads["cell"](h)[..., None] + self.heads["theta"](h).view(b, t, g * g, 2)).view(
            b, t, g, g, 2
        )
        legal = self.heads["legal"](h).view(b, t, g, g, 2) if "legal" in self.heads else 0.0
        if (
            self.legal_head != "global"
        ):  # zero padding: off-grid cells read as empty, as the environment has them
            conv = self.local_legal(one_hot_grid(obs.flatten(0, 1)))  # (BT, 2, G, G)
            legal = legal + conv.permute(0, 2, 3, 1).reshape(b, t, g, g, 2)
        return {"joint": joint, "legal": legal}

    def gate(self, out: dict, obs: torch.Tensor) -> torch.Tensor:
        """Inference-time logits: legality added as a scaled log-probability gate, unoccupied cells masked."""
        logits = out["joint"]
        if self.gate_scale:
            logits = logits + self.gate_scale * F.logsigmoid(out["legal"])
        if self.mask:
            logits = logits.masked_fill(~(obs != 0)[..., None].expand_as(logits), -math.inf)
        return logits
