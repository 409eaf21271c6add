// Cycle cost of the reported wrench's processing on the AVR: the low-pass filter (six axes) and
// the tool transform, each bracketed by GPIOR0 markers (1/2 filter, 3/4 tool transform, 5/6 the
// markers alone) over a run of varied wrenches; tools/bench_wrenchpath.py runs it in simavr.
// Writes 0xFF at the end. No Arduino core: main() is the whole program.
#include <avr/io.h>
#include <stdint.h>

#include "delta6_filter.h"
#include "delta6_toolframe.h"

namespace {

inline void mark(uint8_t value) {
  asm volatile("" ::: "memory");
  GPIOR0 = value;
  asm volatile("" ::: "memory");
}

volatile float sink;

}  // namespace

int main() {
  delta6::LowPassCoefficients k;
  delta6::designLowPass(10.0f, 250.0f, &k);
  delta6::LowPass6 filter;
  filter.configure(k);
  const float p[3] = {0.01f, -0.02f, 0.15f};
  const float rpy[3] = {0.1f, -0.2f, 1.5f};
  delta6::ToolFrame tool;
  delta6::makeToolFrame(p, rpy, &tool);
  float w[6] = {1.5f, -2.25f, 12.0f, 0.125f, -0.3f, 0.01f};
  for (uint16_t n = 0; n < 200; ++n) {
    for (uint8_t i = 0; i < 6; ++i) w[i] = w[i] * -0.9f + static_cast<float>(n & 7) * 0.37f;
    mark(1);
    filter.apply(w);
    mark(2);
    mark(3);
    delta6::applyToolFrame(tool, w);
    mark(4);
    mark(5);
    mark(6);
    sink = w[0] + w[5];
  }
  mark(0xFF);
  for (;;) {
  }
}
