"""What a learned-model file says about itself: the ONNX ``metadata_props`` that inference
needs (design, base model, window, rate, normalisation) and what it was trained from.

Every key starts with ``delta6.``; values are text (JSON where structured). Reading checks
every field and names the first bad one in one line.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from delta6.core.errors import UserError
from delta6.core.hashes import parse_hash32
from delta6.learning.windows import Normalisation

SCHEMA = "delta6-learned/1"
PREFIX = "delta6."
BASES = ("none", "analytical", "calibration")


def onnx_metadata(path) -> dict[str, str] | None:
    """An ONNX file's ``metadata_props`` (None: not a readable ONNX file)."""
    import onnx
    try:
        proto = onnx.load(str(path), load_external_data=False)
    except Exception:   # onnx raises protobuf's and its own errors for a file that is not ONNX
        return None
    return {p.key: p.value for p in proto.metadata_props}


#: Every key a model card has (after the prefix); calibration and calibration_hash only over a
#: calibration.
KEYS = ("schema", "kind", "design", "design_hash", "base", "window", "rate_hz", "normalisation",
        "hyperparameters", "training", "calibration", "calibration_hash")


def _hash32(text: str, bad) -> int:
    try:
        return parse_hash32(text)
    except ValueError as exc:
        raise bad(str(exc)) from None


class ModelFileError(UserError):
    """A model file is unreadable, not a Delta6 model, or not for this design or calibration."""


@dataclass(frozen=True)
class ModelCard:
    kind: str                   # mlp, lstm, gru, transformer
    design_name: str
    design_hash: int
    base: str                   # none (end-to-end), analytical, calibration
    window: int
    rate_hz: float
    norm: Normalisation
    calibration_name: str = ""
    calibration_hash: int | None = None     # with base "calibration"
    hyperparameters: dict = field(default_factory=dict)
    training: dict = field(default_factory=dict)

    def to_props(self) -> dict[str, str]:
        props = {
            "schema": SCHEMA, "kind": self.kind, "design": self.design_name,
            "design_hash": f"0x{self.design_hash:08x}", "base": self.base,
            "window": str(self.window), "rate_hz": repr(float(self.rate_hz)),
            "normalisation": self.norm.to_json(),
            "hyperparameters": json.dumps(self.hyperparameters),
            "training": json.dumps(self.training),
        }
        if self.base == "calibration":
            props["calibration"] = self.calibration_name
            props["calibration_hash"] = f"0x{self.calibration_hash:08x}"
        return {PREFIX + k: v for k, v in props.items()}

    @classmethod
    def from_props(cls, props: dict[str, str], source: str) -> "ModelCard":
        """Parse ``metadata_props``; ``source`` names the file in messages."""
        own = {k[len(PREFIX):]: v for k, v in props.items() if k.startswith(PREFIX)}
        if own.get("schema") != SCHEMA:
            if "schema" in own:
                raise ModelFileError(f"{source}: model schema {own['schema']!r} is not "
                                     f"supported (this version reads {SCHEMA})")
            if "delta6_model" in props:
                raise ModelFileError(
                    f"{source}: the float network of on-chip model '{props['delta6_model']}' "
                    "(delta6 train --target mcu), not a host estimator: give its .json to "
                    "delta6 evaluate --model, codegen --model or virtual --model")
            raise ModelFileError(f"{source}: an ONNX model, but not a Delta6 learned estimator "
                                 "(no delta6 metadata)")

        def need(key):
            if key not in own:
                raise ModelFileError(f"{source}: metadata {PREFIX}{key} is missing")
            return own[key]

        def bad(key, why):
            return ModelFileError(f"{source}: metadata {PREFIX}{key} {why}")

        for key in own:
            if key not in KEYS:
                # like a design or calibration file: a key this version does not know is refused
                raise bad(key, f"is not a key of {SCHEMA} (known: {', '.join(KEYS)})")
        kind = need("kind")
        if kind not in ("mlp", "lstm", "gru", "transformer"):
            raise bad("kind", f"names no known model ({kind!r})")
        base = need("base")
        if base not in BASES:
            raise bad("base", f"must be one of {', '.join(BASES)}, got {base!r}")
        design_hash = _hash32(need("design_hash"), lambda why: bad("design_hash", why))
        calibration_name, calibration_hash = "", None
        if base == "calibration":
            calibration_name = need("calibration")
            calibration_hash = _hash32(need("calibration_hash"),
                                       lambda why: bad("calibration_hash", why))
        else:
            for key in ("calibration", "calibration_hash"):
                if key in own:
                    raise bad(key, f"belongs to a model over a calibration, not base {base!r}")
        try:
            window = int(need("window"))
            if not 1 <= window <= 10_000:
                raise ValueError
        except ValueError:
            raise bad("window", "must be a whole number of samples in 1..10000") from None
        try:
            rate = float(need("rate_hz"))
            if not 0 < rate < 1e6:
                raise ValueError
        except ValueError:
            raise bad("rate_hz", "must be a positive rate") from None
        try:
            norm = Normalisation.from_json(need("normalisation"))
        except (ValueError, KeyError, TypeError) as exc:
            raise bad("normalisation", f"is unusable ({exc})") from None
        extra = {}
        for key in ("hyperparameters", "training"):
            try:
                extra[key] = json.loads(own.get(key, "{}"))
            except ValueError:
                raise bad(key, "is not JSON") from None
            if not isinstance(extra[key], dict):
                raise bad(key, "must be a JSON object")
        return cls(kind=kind, design_name=need("design"), design_hash=design_hash, base=base,
                   window=window, rate_hz=rate, norm=norm, calibration_name=calibration_name,
                   calibration_hash=calibration_hash, **extra)

    def describe(self) -> str:
        over = {"none": "end-to-end", "analytical": "residual over the analytical model",
                "calibration": f"residual over calibration {self.calibration_name} "
                               f"(0x{self.calibration_hash or 0:08x})"}[self.base]
        return (f"{self.kind}, {over}, design {self.design_name} (0x{self.design_hash:08x}), "
                f"window {self.window} at {self.rate_hz:g} Hz")

