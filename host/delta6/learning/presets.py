"""Network sizes and training recipes (plain data: no torch needed to read them).

``paper`` is Table IV of the paper with its recipe of Section V.B (Adam at 1e-3, MSE, batch 32,
at most 150 epochs, early stopping with a patience of 10 on a 10 % held-out tail); the paper
has no MLP, ours gets two hidden layers of 256. ``default`` is small enough to train in minutes
on two CPU cores and to run a window in well under a millisecond.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

KINDS = ("mlp", "lstm", "gru", "transformer")


@dataclass(frozen=True)
class Net:
    """Architecture. ``width``: hidden size d_h (LSTM, GRU, MLP) or d_model (Transformer)."""

    kind: str
    width: int
    layers: int
    dropout: float = 0.0
    heads: int = 0            # Transformer only
    ff_width: int = 0         # Transformer only: width of the feed-forward block


@dataclass(frozen=True)
class Recipe:
    """Training. One epoch visits ``epoch_fraction`` of the training windows, drawn afresh."""

    lr: float = 1e-3
    batch: int = 32
    max_epochs: int = 150
    patience: int = 10
    holdout: float = 0.1
    epoch_fraction: float = 1.0
    lr_decay_patience: int = 0          # 0: constant learning rate
    max_minutes: float | None = None    # wall-clock budget; the best checkpoint is kept


@dataclass(frozen=True)
class Preset:
    name: str
    net: Net
    recipe: Recipe = field(default_factory=Recipe)

    def as_dict(self) -> dict:
        return {"preset": self.name, "net": asdict(self.net), "recipe": asdict(self.recipe)}

    def with_recipe(self, **changes) -> "Preset":
        return replace(self, recipe=replace(self.recipe, **changes))


_PAPER_RECIPE = Recipe(lr=1e-3, batch=32, max_epochs=150, patience=10, holdout=0.1)
_DEFAULT_RECIPE = Recipe(lr=2e-3, batch=512, max_epochs=40, patience=6, holdout=0.1,
                         epoch_fraction=0.5, lr_decay_patience=2)

PRESETS: dict[str, dict[str, Preset]] = {
    "paper": {
        "mlp": Preset("paper", Net("mlp", 256, 2, 0.2), _PAPER_RECIPE),
        "lstm": Preset("paper", Net("lstm", 128, 2, 0.3), _PAPER_RECIPE),
        "gru": Preset("paper", Net("gru", 128, 2, 0.2), _PAPER_RECIPE),
        "transformer": Preset("paper", Net("transformer", 64, 2, 0.2, heads=4, ff_width=256),
                              _PAPER_RECIPE),
    },
    "default": {
        "mlp": Preset("default", Net("mlp", 128, 2), _DEFAULT_RECIPE),
        "lstm": Preset("default", Net("lstm", 48, 1), _DEFAULT_RECIPE),
        "gru": Preset("default", Net("gru", 48, 1), _DEFAULT_RECIPE),
        "transformer": Preset("default", Net("transformer", 32, 2, heads=2, ff_width=64),
                              _DEFAULT_RECIPE),
    },
}


def preset(name: str, kind: str) -> Preset:
    if kind not in KINDS:
        raise ValueError(f"unknown model {kind!r} (one of {', '.join(KINDS)})")
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r} (one of {', '.join(PRESETS)})")
    return PRESETS[name][kind]
