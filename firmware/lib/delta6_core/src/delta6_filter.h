// A second-order Butterworth low-pass per wrench axis, in float32: the filter of the device's
// reported wrench (docs/protocol.md, SET_FILTER). The design is scipy.signal.butter(2, fc,
// fs=rate) (bilinear transform with the cutoff prewarped), rewritten so that float32 rounding
// stays small at low cutoffs and the gain at DC is exactly 1:
//
//   y[n] = y[n-1] + a2 (y[n-1] - y[n-2]) + c (s/4 - y[n-1]),   s = x[n] + 2 x[n-1] + x[n-2]
//
// with c = 1 + a1 + a2 = 4 b0 (the classic b0 = b2 = b1/2, a1, a2): the same transfer function,
// but the products are of small differences instead of large terms that nearly cancel. The
// increment's rounding when it is added to y[n-1] is carried into the next increment (error
// feedback, 2 additions per axis), so rounding does not accumulate at low cutoffs: the output
// stays within 5e-7 of full scale of scipy's float64 lfilter over the whole cutoff range.
// delta6.core.lowpass is the Python reference, bit for bit.
#ifndef DELTA6_FILTER_H
#define DELTA6_FILTER_H

#include <stdint.h>

namespace delta6 {

struct LowPassCoefficients {
  float c;    // 1 + a1 + a2 = 4 b0
  float a2;
};

// The cutoff range the device accepts: kMinCutoffRatio x rate <= cutoff <= kMaxCutoffRatio x rate.
// Below it the poles crowd 1 in float32; above it the bilinear map squeezes the response
// against Nyquist.
const float kMinCutoffRatio = 0.001f;
const float kMaxCutoffRatio = 0.45f;

// Whether the cutoff lies in that range (NaN does not): what designLowPass checks, without
// its tangent.
bool lowPassFits(float cutoff_hz, float rate_hz);
// Coefficients for cutoff_hz at rate_hz; false (and *out untouched) outside the range.
bool designLowPass(float cutoff_hz, float rate_hz, LowPassCoefficients* out);

// Six independent axes. The first sample after configure()/reset() fills the history with
// itself, so the output starts at the input's level with no step response from zero.
class LowPass6 {
 public:
  LowPass6();
  void configure(const LowPassCoefficients& c);
  void reset() { primed_ = false; }
  // Filter w in place.
  void apply(float w[6]);

 private:
  // One axis's history, together: the AVR reaches every field from one pointer (a fifth of
  // the code that five separate arrays take).
  struct Axis {
    float x1, x2, y1, y2, carry;
  };
  LowPassCoefficients k_;
  Axis axis_[6];
  bool primed_;
};

}  // namespace delta6

#endif
