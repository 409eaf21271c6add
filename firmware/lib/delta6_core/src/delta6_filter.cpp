#include "delta6_filter.h"

#include <math.h>
#include <string.h>

#include "delta6_fastmath.h"

namespace delta6 {

bool lowPassFits(float cutoff_hz, float rate_hz) {
  return rate_hz > 0.0f && cutoff_hz >= kMinCutoffRatio * rate_hz &&
         cutoff_hz <= kMaxCutoffRatio * rate_hz;
}

bool designLowPass(float cutoff_hz, float rate_hz, LowPassCoefficients* out) {
  if (!lowPassFits(cutoff_hz, rate_hz)) return false;
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
  memset(axis_, 0, sizeof(axis_));
}

void LowPass6::configure(const LowPassCoefficients& c) {
  k_ = c;
  primed_ = false;
}

void LowPass6::apply(float w[6]) {
  for (uint8_t i = 0; i < 6; ++i) {
    Axis& a = axis_[i];
    const float x = w[i];
    if (!primed_) {
      a.x1 = a.x2 = a.y1 = a.y2 = x;
      a.carry = 0.0f;
    }
    // s / 4 by the exponent: exact, as a multiply by 0.25 is, for a tenth of its cycles.
    const float quarter_sum = fastmath::scale2((x + a.x1) + (a.x1 + a.x2), -2);
    const float step = (k_.a2 * (a.y1 - a.y2) + k_.c * (quarter_sum - a.y1)) + a.carry;
    const float y = a.y1 + step;
    a.carry = step - (y - a.y1);  // what the addition rounded away
    a.x2 = a.x1;
    a.x1 = x;
    a.y2 = a.y1;
    a.y1 = y;
    w[i] = y;
  }
  primed_ = true;
}

}  // namespace delta6
