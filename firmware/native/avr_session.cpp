// A scripted protocol session on the AVR, for the emulator (simavr through delta6.avrsim):
// boot, samples while stopped, start, wrench samples, wrench+raw samples, a tare, tared
// samples, get info, get telemetry. Every call is bracketed by GPIOR0 markers (the emulator
// stamps them with the cycle count) and everything the device sends goes out on UART0
// between calls (so the timed code never waits for the UART). tests/avr_session.py runs the
// same script on the native build and requires the same bytes; tools/bench_protocol.py
// reports the cycles. Never part of the firmware image.
#include <avr/io.h>

#include "delta6_device.h"
#include "delta6_version.h"

namespace {

volatile uint32_t now_us = 0;

class CaptureHardware : public delta6::Hardware {
 public:
  uint16_t txSpace() override { return static_cast<uint16_t>(sizeof(buf_) - len_); }
  void txWrite(const uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) buf_[len_++] = data[i];
  }
  void eepromRead(uint16_t, uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) data[i] = 0xFF;  // erased
  }
  void eepromWrite(uint16_t, const uint8_t*, uint16_t) override {}
  uint32_t micros() override { return now_us; }
  void sampleRateChanged(uint16_t) override {}

  void flush() {
    for (uint16_t i = 0; i < len_; ++i) {
      while (!(UCSR0A & (1 << UDRE0))) {
      }
      UDR0 = buf_[i];
    }
    len_ = 0;
  }

 private:
  uint8_t buf_[400];
  uint16_t len_ = 0;
};

CaptureHardware hardware;
const delta6::Identity identity = {"delta6", 0x535534AF,
                                   {15.03f, 15.03f, 25.1f, 0.3805f, 0.3347f, 0.4266f},
                                   0.5236f, 1365,
                                   {delta6::kFirmwareVersionMajor, delta6::kFirmwareVersionMinor,
                                    delta6::kFirmwareVersionPatch},
                                   500000, 2000, 0, 0};
const delta6::Config defaults = {500, 1, false, {0, 0, 0, 0, 0, 0},
                                 {1200, 5400, 9800, 14100, 300, 16000}};
delta6::Device device(hardware, identity, defaults);
delta6::Sample sample;

void mark(uint8_t value) { GPIOR0 = value; }

void samples(uint8_t count, uint8_t marker) {
  for (uint8_t k = 0; k < count; ++k) {
    sample.time_us += 2000;
    sample.wrench[0] += 0.0137f;
    sample.wrench[2] -= 0.021f;
    sample.wrench[4] += 0.0003f;
    now_us = sample.time_us;
    mark(marker);
    device.onSample(sample);
    mark(static_cast<uint8_t>(marker + 1));
    hardware.flush();
  }
}

void command(const uint8_t* frame, uint8_t n, uint8_t marker) {
  for (uint8_t i = 0; i + 1 < n; ++i) device.onByte(frame[i]);
  mark(marker);
  device.onByte(frame[n - 1]);  // the delimiter: parse, execute, answer
  mark(static_cast<uint8_t>(marker + 1));
  hardware.flush();
}

// delta6.protocol.encode_command(START, 0x22, 500), (SET_MODE, 0x24, 2), (TARE, 0x25, 10),
// (GET_INFO, 0x20), (GET_TELEMETRY, 0x2b).
const uint8_t kStart[] = {0x07, 0x82, 0x22, 0xf4, 0x01, 0x93, 0x12, 0x00};
const uint8_t kRaw[] = {0x06, 0x84, 0x24, 0x02, 0xc1, 0x66, 0x00};
const uint8_t kTare[] = {0x04, 0x85, 0x25, 0x0a, 0x03, 0x67, 0x40, 0x00};
const uint8_t kInfo[] = {0x05, 0x80, 0x20, 0x22, 0xf5, 0x00};
const uint8_t kTelemetry[] = {0x05, 0x8b, 0x2b, 0x4f, 0x64, 0x00};

}  // namespace

int main() {
  UBRR0 = 0;  // the emulator transmits at any rate
  UCSR0A = 1 << U2X0;
  UCSR0B = 1 << TXEN0;
  for (uint8_t i = 0; i < 6; ++i) {
    sample.counts[i] = static_cast<uint16_t>(defaults.zero_counts[i] + 100 * i);
    sample.wrench[i] = 1.5f * static_cast<float>(i + 1) - 4.0f;
  }
  sample.solver_ok = true;
  sample.loop_time_us = 900;
  sample.temperature_centi = delta6::proto::kTemperatureUnknown;

  mark(80);
  device.begin(0);
  mark(81);
  hardware.flush();
  samples(20, 10);                        // stopped
  command(kStart, sizeof kStart, 50);
  samples(50, 20);                        // wrench
  command(kRaw, sizeof kRaw, 52);
  samples(50, 30);                        // wrench + raw
  command(kTare, sizeof kTare, 54);
  samples(10, 56);                        // averaging
  samples(50, 40);                        // wrench + raw, tared
  command(kInfo, sizeof kInfo, 60);
  command(kTelemetry, sizeof kTelemetry, 62);
  while (!(UCSR0A & (1 << TXC0))) {
  }
  mark(0xFF);
  for (;;) {
  }
}
