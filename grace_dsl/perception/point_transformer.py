"""A small Point Transformer in plain torch: the learned estimator's encoder and heads.

Why this shape: the paper's encoder groups 2048 points into 128 groups of 32 and runs attention
over the groups; a 2-core CPU trains that in hours, not minutes. Here a cloud of 512-1024 points
is cut into ``groups`` farthest-point-sampled groups of ``group_size`` nearest neighbours, each
embedded by a shared point MLP with a max pool (a token per group), and ``blocks`` vector
self-attention layers (Zhao et al., 2021: subtraction relation, a learned position encoding,
attention over each token's ``k`` nearest tokens, one weight per channel group) mix the tokens.
Max- and mean-pooled tokens feed a shared MLP trunk, then one small MLP head per parameter, and
a pose head (the concept frame's rotation as two columns, its origin's offset from the centroid).

Everything is ordinary torch (no CUDA extensions, no compiled ops), so it runs wherever the CPU
wheel does. This module is only imported when torch is installed (``grace_dsl.perception``
never imports it at import time).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import torch
from torch import Tensor, nn


@dataclass(frozen=True)
class ModelConfig:
    """The network's size; stored in a weights file, so a loader rebuilds the same network."""

    n_params: int
    groups: int = 32  # tokens per cloud (farthest-point centres)
    group_size: int = 16  # points per token
    dim: int = 48  # token width
    blocks: int = 2  # vector self-attention layers
    heads: int = 4  # channel groups sharing one attention weight
    k: int = 8  # tokens each token attends to
    trunk: int = 96  # width of the shared MLP after pooling
    head: int = 24  # width of each parameter's head
    pose: bool = True  # also regress the concept frame (rotation 6D + origin offset)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @staticmethod
    def from_dict(d: dict[str, Any]) -> ModelConfig:
        return ModelConfig(**d)


def farthest_point_sample(xyz: Tensor, m: int) -> Tensor:
    """Indices (B, m) of ``m`` points spread over each cloud (B, N, 3), greedy farthest-first.

    Deterministic: it starts at the point farthest from the centroid, not at a random one."""
    b, n, _ = xyz.shape
    m = min(m, n)
    idx = torch.zeros(b, m, dtype=torch.long, device=xyz.device)
    centroid = xyz.mean(dim=1, keepdim=True)
    far = ((xyz - centroid) ** 2).sum(-1).argmax(-1)
    dist = torch.full((b, n), float("inf"), device=xyz.device, dtype=xyz.dtype)
    rows = torch.arange(b, device=xyz.device)
    for i in range(m):
        idx[:, i] = far
        d = ((xyz - xyz[rows, far].unsqueeze(1)) ** 2).sum(-1)
        dist = torch.minimum(dist, d)
        far = dist.argmax(-1)
    return idx


def gather(x: Tensor, idx: Tensor) -> Tensor:
    """``x`` (B, N, C) at ``idx`` (B, ...) -> (B, ..., C)."""
    b = x.shape[0]
    flat = idx.reshape(b, -1)
    out = torch.gather(x, 1, flat.unsqueeze(-1).expand(-1, -1, x.shape[-1]))
    return out.reshape(*idx.shape, x.shape[-1])


def knn(query: Tensor, points: Tensor, k: int) -> Tensor:
    """Indices (B, M, k) of the ``k`` nearest ``points`` (B, N, 3) to each query (B, M, 3)."""
    d = torch.cdist(query, points)
    return d.topk(min(k, points.shape[1]), dim=-1, largest=False).indices


class GroupEmbed(nn.Module):
    """FPS centres, k-NN groups around them, a shared point MLP and a max pool per group."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.groups, self.size = cfg.groups, cfg.group_size
        self.mlp = nn.Sequential(nn.Linear(3, 32), nn.ReLU(), nn.Linear(32, cfg.dim))
        self.pos = nn.Sequential(nn.Linear(3, cfg.dim), nn.ReLU(), nn.Linear(cfg.dim, cfg.dim))

    def forward(self, centres: Tensor, local: Tensor) -> Tensor:
        """Tokens (B, G, dim) from the centres (B, G, 3) and the groups around them (B, G, S, 3)."""
        return self.mlp(local).max(dim=2).values + self.pos(centres)


def group(xyz: Tensor, cfg: ModelConfig) -> tuple[Tensor, Tensor, Tensor]:
    """A cloud's (B, N, 3) centres (B, G, 3), groups relative to their centre (B, G, S, 3) and
    each centre's ``k`` nearest centres (B, G, k). No learned weights: training computes it once
    per cloud instead of once per step."""
    with torch.no_grad():
        centres = gather(xyz, farthest_point_sample(xyz, cfg.groups))
        local = gather(xyz, knn(centres, xyz, cfg.group_size)) - centres.unsqueeze(2)
        return centres, local, knn(centres, centres, cfg.k)


class VectorAttention(nn.Module):
    """Point Transformer vector self-attention over each token's k nearest tokens.

    y_i = sum_j softmax_j(gamma(phi(x_i) - psi(x_j) + delta_ij)) * (alpha(x_j) + delta_ij),
    delta_ij = theta(p_i - p_j); the weight is per channel group (``heads``), not per channel,
    which keeps gamma small. The position encoding ``delta`` comes in from the network, which
    computes it once for all blocks (a shared theta, half the block's cost on this CPU)."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        d, self.heads, self.k = cfg.dim, cfg.heads, cfg.k
        self.norm = nn.LayerNorm(d)
        self.qkv = nn.Linear(d, 3 * d)
        self.gamma = nn.Sequential(nn.Linear(d, d), nn.ReLU(), nn.Linear(d, cfg.heads))
        self.out = nn.Linear(d, d)
        self.ff = nn.Sequential(
            nn.LayerNorm(d), nn.Linear(d, 2 * d), nn.ReLU(), nn.Linear(2 * d, d)
        )

    def forward(self, x: Tensor, neighbours: Tensor, delta: Tensor) -> Tensor:
        b, g, d = x.shape
        q, key, v = self.qkv(self.norm(x)).chunk(3, dim=-1)
        rel = q.unsqueeze(2) - gather(key, neighbours) + delta  # subtraction relation
        w = torch.softmax(self.gamma(rel), dim=2)  # (B, G, k, heads)
        vals = (gather(v, neighbours) + delta).reshape(b, g, -1, self.heads, d // self.heads)
        y = (w.unsqueeze(-1) * vals).sum(dim=2).reshape(b, g, d)
        x = x + self.out(y)
        return x + self.ff(x)


class PointTransformer(nn.Module):
    """Cloud (B, N, 3), centred and scaled -> (params (B, P), pose (B, 9) or None).

    ``params`` are the normalized parameters (0 and 1 at the ends of their ranges); ``pose``
    holds the concept frame's x and y axes and its origin's offset from the centroid, in the
    cloud's frame and scale."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        if cfg.dim % cfg.heads:
            raise ValueError(f"dim {cfg.dim} is not a multiple of heads {cfg.heads}")
        self.cfg = cfg
        self.embed = GroupEmbed(cfg)
        self.theta = nn.Sequential(nn.Linear(3, cfg.dim), nn.ReLU(), nn.Linear(cfg.dim, cfg.dim))
        self.blocks = nn.ModuleList(VectorAttention(cfg) for _ in range(cfg.blocks))
        self.trunk = nn.Sequential(
            nn.LayerNorm(2 * cfg.dim), nn.Linear(2 * cfg.dim, cfg.trunk), nn.ReLU()
        )
        self.heads = nn.ModuleList(self._head(1) for _ in range(cfg.n_params))
        self.pose = self._head(9) if cfg.pose else None

    def _head(self, out: int) -> nn.Module:
        cfg = self.cfg
        return nn.Sequential(nn.Linear(cfg.trunk, cfg.head), nn.ReLU(), nn.Linear(cfg.head, out))

    def forward(self, xyz: Tensor) -> tuple[Tensor, Tensor | None]:
        return self.encode(*group(xyz, self.cfg))

    def encode(
        self, centres: Tensor, local: Tensor, neighbours: Tensor
    ) -> tuple[Tensor, Tensor | None]:
        """The network after ``group``: what a training step runs."""
        x = self.embed(centres, local)
        delta = self.theta(centres.unsqueeze(2) - gather(centres, neighbours))  # (B, G, k, d)
        for block in self.blocks:
            x = block(x, neighbours, delta)
        feat = self.trunk(torch.cat([x.max(dim=1).values, x.mean(dim=1)], dim=-1))
        params = torch.cat([h(feat) for h in self.heads], dim=-1)
        return params, None if self.pose is None else self.pose(feat)


def rotation_from_6d(six: Tensor) -> Tensor:
    """Two predicted axes (B, 6) -> rotation matrices (B, 3, 3) by Gram-Schmidt."""
    a, b = six[:, :3], six[:, 3:6]
    x = a / a.norm(dim=-1, keepdim=True).clamp_min(1e-8)
    b = b - (x * b).sum(-1, keepdim=True) * x
    y = b / b.norm(dim=-1, keepdim=True).clamp_min(1e-8)
    return torch.stack([x, y, torch.cross(x, y, dim=-1)], dim=-1)


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
