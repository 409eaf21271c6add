// A scripted protocol session on the AVR, for the emulator (simavr through delta6.sim.avrsim):
// boot, samples while stopped, start, wrench samples, wrench+raw samples, a tare, tared
// samples, get info, get telemetry. Every call is bracketed by GPIOR0 markers (the emulator
// stamps them with the cycle count) and everything the device sends goes out on UART0
// between calls (so the timed code never waits for the UART). delta6.sim.avrsession runs
// the same script on the native build and requires the same bytes; tools/bench_protocol.py
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
const delta6::Identity identity DELTA6_FLASH = {"delta6", 0x535534AF,
                                   {15.03f, 15.03f, 25.1f, 0.3805f, 0.3347f, 0.4266f},
                                   0.5236f, 1365,
                                   {delta6::kFirmwareVersionMajor, delta6::kFirmwareVersionMinor,
                                    delta6::kFirmwareVersionPatch},
                                   500000, 2000, 0, 0, nullptr, 0, nullptr, 0, 0};
const delta6::Config defaults DELTA6_FLASH = {500, 1, false, {0, 0, 0, 0, 0, 0},
                                 {1200, 5400, 9800, 14100, 300, 16000},
                                 0.0f, {0, 0, 0}, {0, 0, 0}, {0, 0, 0, 0, 0, 0}};
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

// A command frame (type, request id, its argument if it has one) made by the core's own
// encoder, before the timed spans; delta6.sim.avrsession sends the same commands encoded by
// the host's, and the two runs must answer alike.
struct CommandFrame {
  uint8_t bytes[delta6::proto::kMaxCommandSize + delta6::proto::kFrameOverhead];
  uint8_t n;
};

CommandFrame frameCommand(uint8_t type, uint8_t request_id, uint16_t arg) {
  namespace proto = delta6::proto;
  CommandFrame f;
  uint8_t* p = f.bytes + 1;
  p[0] = type;
  p[1] = request_id;
  const uint8_t size = proto::commandSize(type);
  const uint8_t arg_bytes = static_cast<uint8_t>(size - 2);  // after type and request id
  if (arg_bytes == 1) p[2] = static_cast<uint8_t>(arg);
  if (arg_bytes == 2) proto::putU16(p + 2, arg);
  f.n = static_cast<uint8_t>(proto::finishFrame(f.bytes, size));
  return f;
}

void command(const CommandFrame& frame, uint8_t marker) {
  for (uint8_t i = 0; i + 1 < frame.n; ++i) device.onByte(frame.bytes[i]);
  mark(marker);
  device.onByte(frame.bytes[frame.n - 1]);  // the delimiter: parse, execute, answer
  mark(static_cast<uint8_t>(marker + 1));
  hardware.flush();
}

}  // namespace

int main() {
  UBRR0 = 0;  // the emulator transmits at any rate
  UCSR0A = 1 << U2X0;
  UCSR0B = 1 << TXEN0;
  delta6::Config loaded;  // the defaults live in flash
  delta6::flash::copy(&loaded, &defaults, sizeof loaded);
  for (uint8_t i = 0; i < 6; ++i) {
    sample.counts[i] = static_cast<uint16_t>(loaded.zero_counts[i] + 100 * i);
    sample.wrench[i] = 1.5f * static_cast<float>(i + 1) - 4.0f;
  }
  sample.solver_ok = true;
  sample.loop_time_us = 900;
  sample.temperature_centi = delta6::proto::kTemperatureUnknown;

  namespace proto = delta6::proto;
  const CommandFrame start = frameCommand(proto::kCmdStart, 0x22, 500);
  const CommandFrame raw = frameCommand(proto::kCmdSetMode, 0x24, proto::kModeWrenchRaw);
  const CommandFrame tare = frameCommand(proto::kCmdTare, 0x25, 10);
  const CommandFrame info = frameCommand(proto::kCmdGetInfo, 0x20, 0);
  const CommandFrame telemetry = frameCommand(proto::kCmdGetTelemetry, 0x2B, 0);

  mark(80);
  device.begin(0);
  mark(81);
  hardware.flush();
  samples(20, 10);                        // stopped
  command(start, 50);
  samples(50, 20);                        // wrench
  command(raw, 52);
  samples(50, 30);                        // wrench + raw
  command(tare, 54);
  samples(10, 56);                        // averaging
  samples(50, 40);                        // wrench + raw, tared
  command(info, 60);
  command(telemetry, 62);
  while (!(UCSR0A & (1 << TXC0))) {
  }
  mark(0xFF);
  for (;;) {
  }
}
