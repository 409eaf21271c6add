#include "delta6_filter.h"

#include <math.h>

#include "delta6_fastmath.h"

namespace delta6 {

bool designLowPass(float cutoff_hz, float rate_hz, LowPassCoefficients* out) {
  if (!(rate_hz > 0.0f) || !(cutoff_hz >= kMinCutoffRatio * rate_hz) ||
      !(cutoff_hz <= kMaxCutoffRatio * rate_hz)) {
    return false;
  }
  const float k = tanf(3.14159265f * (cutoff_hz / rate_hz));
  const float sqrt2_k = 1.41421356f * k;
  const float kk = k * k;
  const float n = 1.0f / (1.0f + sqrt2_k + kk);
  out->c = 4.0f * kk * n;
  out->a2 = (1.0f - sqrt2_k + kk) * n;
  return true;
}

LowPass6::LowPass6() : primed_(false) {
  k_.c = 1.0f;
  k_.a2 = 0.0f;
  for (uint8_t i = 0; i < 6; ++i) x1_[i] = x2_[i] = y1_[i] = y2_[i] = carry_[i] = 0.0f;
}

void LowPass6::configure(const LowPassCoefficients& c) {
  k_ = c;
  primed_ = false;
}

void LowPass6::apply(float w[6]) {
  if (!primed_) {
    for (uint8_t i = 0; i < 6; ++i) {
      x1_[i] = x2_[i] = y1_[i] = y2_[i] = w[i];
      carry_[i] = 0.0f;
    }
    primed_ = true;
  }
  for (uint8_t i = 0; i < 6; ++i) {
    const float x = w[i];
    // s / 4 by the exponent: exact, as a multiply by 0.25 is, for a tenth of its cycles.
    const float quarter_sum = fastmath::scale2((x + x1_[i]) + (x1_[i] + x2_[i]), -2);
    const float step = (k_.a2 * (y1_[i] - y2_[i]) + k_.c * (quarter_sum - y1_[i])) + carry_[i];
    const float y = y1_[i] + step;
    carry_[i] = step - (y - y1_[i]);  // what the addition rounded away
    x2_[i] = x1_[i];
    x1_[i] = x;
    y2_[i] = y1_[i];
    y1_[i] = y;
    w[i] = y;
  }
}

}  // namespace delta6
