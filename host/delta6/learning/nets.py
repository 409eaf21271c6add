"""The networks (torch): a window of standardised readings (B, T_w, 6) -> a standardised
wrench (B, 6). Shapes follow the paper's Fig. 4; the recurrent nets and the Transformer read
out their last time step."""
from __future__ import annotations

import torch
from torch import nn

from delta6.learning.presets import Net

N_IN = N_OUT = 6


class WindowMLP(nn.Module):
    """The whole window flattened into fully connected layers (our baseline; not in the paper)."""

    def __init__(self, net: Net, window: int):
        super().__init__()
        layers: list[nn.Module] = [nn.Flatten()]
        width_in = window * N_IN
        for _ in range(net.layers):
            layers += [nn.Linear(width_in, net.width), nn.GELU()]
            if net.dropout:
                layers.append(nn.Dropout(net.dropout))
            width_in = net.width
        layers.append(nn.Linear(width_in, N_OUT))
        self.body = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.body(x)


class Recurrent(nn.Module):
    """Stacked LSTM or GRU; the last hidden state through a linear layer."""

    def __init__(self, net: Net, window: int):
        super().__init__()
        cell = {"lstm": nn.LSTM, "gru": nn.GRU}[net.kind]
        self.rnn = cell(N_IN, net.width, net.layers, batch_first=True,
                        dropout=net.dropout if net.layers > 1 else 0.0)
        self.head = nn.Linear(net.width, N_OUT)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out, _ = self.rnn(x)
        return self.head(out[:, -1, :])


class Transformer(nn.Module):
    """Each reading embedded to d_model plus a learned position, self-attention layers, the last
    time step through a linear layer (the paper's Section V.B)."""

    def __init__(self, net: Net, window: int):
        super().__init__()
        self.embed = nn.Linear(N_IN, net.width)
        self.position = nn.Parameter(torch.zeros(1, window, net.width))
        nn.init.normal_(self.position, std=0.02)
        layer = nn.TransformerEncoderLayer(net.width, net.heads, net.ff_width, net.dropout,
                                           batch_first=True, norm_first=True)
        self.encoder = nn.TransformerEncoder(layer, net.layers, enable_nested_tensor=False)
        self.head = nn.Linear(net.width, N_OUT)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.encoder(self.embed(x) + self.position)
        return self.head(h[:, -1, :])


def build(net: Net, window: int) -> nn.Module:
    if net.kind == "mlp":
        return WindowMLP(net, window)
    if net.kind in ("lstm", "gru"):
        return Recurrent(net, window)
    if net.kind == "transformer":
        return Transformer(net, window)
    raise ValueError(f"unknown model {net.kind!r}")


def parameter_count(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())
