"""Always-on measurement realism: what the rig records of the plant.

* The encoders are 14-bit absolute encoders: the angle comes in counts of 2 pi / 2^14.
* The reference F/T sensor measures in its own frame {T} with white noise; the rig maps its
  reading to {E} by eq. (14) (``model.sensor_to_e``), which also carries the force noise into
  the moments through the lever arm.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from delta6.core import model
from delta6.twin.fields import FieldError, flag, number, vector
from delta6.twin.statics import rotation_from_vector

#: Where each setting sits in an :meth:`Measurement.as_dict` record (a truth file's names).
_RECORD_NAMES = {"force_noise_n": "reference_noise.force_sd_n",
                 "moment_noise_nm": "reference_noise.moment_sd_nm",
                 "sensor_turn_rad": "sensor_frame.turn_rad",
                 "sensor_offset_m": "sensor_frame.p_t_m"}


@dataclass(frozen=True)
class Measurement:
    quantize: bool = True
    encoder_bits: int = 14
    force_noise_n: float = 0.012      # standard deviation per force axis, in {T}
    moment_noise_nm: float = 2e-4     # standard deviation per moment axis, in {T}
    # {T} -> {E} of eq. (14): the sensor faces the Delta6 (turned half a turn about x), its
    # measurement origin a few centimetres from {E}.
    sensor_turn_rad: tuple[float, float, float] = (np.pi, 0.0, 0.0)
    sensor_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.03)

    def check(self) -> None:
        """A :class:`~delta6.twin.fields.FieldError` naming the first unusable setting."""
        flag("quantize", self.quantize)
        number("encoder_bits", self.encoder_bits, 4, 24, integer=True)
        number("force_noise_n", self.force_noise_n, 0.0)
        number("moment_noise_nm", self.moment_noise_nm, 0.0)
        vector("sensor_turn_rad", self.sensor_turn_rad, 3)
        vector("sensor_offset_m", self.sensor_offset_m, 3)

    @property
    def count_rad(self) -> float:
        return 2 * np.pi / 2**self.encoder_bits

    def sensor_rotation(self) -> np.ndarray:
        return rotation_from_vector(np.asarray(self.sensor_turn_rad, dtype=float))

    def encoders(self, angle: np.ndarray) -> np.ndarray:
        if not self.quantize:
            return angle
        return np.round(angle / self.count_rad) * self.count_rad

    def reference(self, wrench_e: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The reference sensor's reading, mapped to {E} by eq. (14)."""
        r_te = self.sensor_rotation()
        p_t = np.asarray(self.sensor_offset_m, dtype=float)
        in_t = model.e_to_sensor(wrench_e, r_te, p_t)
        sd = np.array([self.force_noise_n] * 3 + [self.moment_noise_nm] * 3)
        in_t = in_t + rng.standard_normal(in_t.shape) * sd
        return model.sensor_to_e(in_t, r_te, p_t)

    def as_dict(self) -> dict:
        return {"encoder_bits": self.encoder_bits, "quantize": self.quantize,
                "encoder_count_rad": self.count_rad,
                "reference_noise": {"force_sd_n": self.force_noise_n,
                                    "moment_sd_nm": self.moment_noise_nm, "frame": "T"},
                "sensor_frame": {"turn_rad": [float(v) for v in self.sensor_turn_rad],
                                 "r_te": self.sensor_rotation().tolist(),
                                 "p_t_m": list(self.sensor_offset_m),
                                 "mapping": "eq. (14), model.sensor_to_e"}}

    @classmethod
    def from_dict(cls, record: dict) -> "Measurement":
        """The settings an :meth:`as_dict` record describes (a truth file's ``measurement``),
        checked: a :class:`~delta6.twin.fields.FieldError` names the record's field."""
        noise, frame = record["reference_noise"], record["sensor_frame"]
        raw = cls(quantize=record["quantize"], encoder_bits=record["encoder_bits"],
                  force_noise_n=noise["force_sd_n"], moment_noise_nm=noise["moment_sd_nm"],
                  sensor_turn_rad=frame["turn_rad"], sensor_offset_m=frame["p_t_m"])
        try:
            raw.check()
        except FieldError as exc:
            raise exc.renamed(_RECORD_NAMES) from None
        return replace(raw, sensor_turn_rad=tuple(map(float, raw.sensor_turn_rad)),
                       sensor_offset_m=tuple(map(float, raw.sensor_offset_m)))
