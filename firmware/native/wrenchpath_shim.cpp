// C ABI over the low-pass filter and the tool transform of the firmware core, for the ctypes
// tests (tests/firmware/test_wrenchpath_native.py).
#include <stddef.h>
#include <stdint.h>

#include "delta6_filter.h"
#include "delta6_toolframe.h"

extern "C" {

// c and a2 of the design; returns 0 when the cutoff is out of range.
int d6_design_lowpass(float cutoff_hz, float rate_hz, float* c, float* a2) {
  delta6::LowPassCoefficients k;
  if (!delta6::designLowPass(cutoff_hz, rate_hz, &k)) return 0;
  *c = k.c;
  *a2 = k.a2;
  return 1;
}

// n samples of 6 axes through a fresh filter with the given coefficients, in place.
void d6_run_lowpass(float c, float a2, size_t n, float* w) {
  delta6::LowPassCoefficients k = {c, a2};
  delta6::LowPass6 f;
  f.configure(k);
  for (size_t i = 0; i < n; ++i) f.apply(w + 6 * i);
}

// n wrenches moved into the tool frame, in place; returns 0 for a non-finite frame.
int d6_tool_frame(const float* translation, const float* rpy, size_t n, float* w) {
  delta6::ToolFrame t;
  if (!delta6::makeToolFrame(translation, rpy, &t)) return 0;
  for (size_t i = 0; i < n; ++i) delta6::applyToolFrame(t, w + 6 * i);
  return 1;
}
}
