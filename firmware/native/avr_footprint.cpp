// Footprint check of the protocol core on the AVR: a minimal program that uses every entry
// point of delta6::Device with a do-nothing board layer, linked for the ATmega328P so that
// avr-size reports the flash and static RAM the core costs. Built by the tests and
// tools/bench_protocol.py; never part of the firmware image.
#include <stdint.h>

#include "delta6_device.h"

namespace {

class NullHardware : public delta6::Hardware {
 public:
  uint16_t txSpace() override { return 256; }
  void txWrite(const uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) sink_ ^= data[i];
  }
  void eepromRead(uint16_t, uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) data[i] = 0xFF;
  }
  void eepromWrite(uint16_t, const uint8_t*, uint16_t) override {}
  uint32_t micros() override { return ++clock_; }
  void sampleRateChanged(uint16_t rate_hz) override { sink_ ^= static_cast<uint8_t>(rate_hz); }
  volatile uint8_t sink_ = 0;
  uint32_t clock_ = 0;
};

NullHardware hardware;
const delta6::Identity identity = {"delta6", 0x535534AF, {15.03f, 15.03f, 25.1f, 0.38f, 0.33f, 0.43f},
                                   0.5236f, {0, 1, 0}, 500000, 2000, 0, 0};
const delta6::Config defaults = {200, 1, false, {0, 0, 0, 0, 0, 0}, {0, 0, 0, 0, 0, 0}};
delta6::Device device(hardware, identity, defaults);

}  // namespace

int main() {
  device.begin(0);
  volatile uint8_t in = 0;
  delta6::Sample s = {};
  for (;;) {
    s.time_us += 2000;
    s.wrench[0] = static_cast<float>(in);
    device.onSample(s);
    device.onByte(in);
  }
}
