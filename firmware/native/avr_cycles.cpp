// Cycle costs of the protocol core on the ATmega328P, for the emulator (simavr): Timer 1
// counts CPU cycles around each call and the results go out on the UART as one line of
// "name cycles" pairs. tools/bench_protocol.py builds and runs it. Never part of the firmware.
//
// The command frames below are what delta6.protocol.encode_command produces (the benchmark
// checks the device acknowledged them: "mode 2 tare 1" at the end of the line).
#include <avr/io.h>
#include <stdio.h>

#include "delta6_device.h"

namespace {

int uartPut(char c, FILE*) {
  while (!(UCSR0A & (1 << UDRE0))) {
  }
  UDR0 = c;
  return 0;
}
FILE uart;

class CountingHardware : public delta6::Hardware {
 public:
  uint16_t txSpace() override { return 512; }  // the link never limits: costs only
  void txWrite(const uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) sink_ ^= data[i];
  }
  void eepromRead(uint16_t, uint8_t* data, uint16_t n) override {
    for (uint16_t i = 0; i < n; ++i) data[i] = 0xFF;
  }
  void eepromWrite(uint16_t, const uint8_t*, uint16_t) override {}
  uint32_t micros() override { return 0; }
  void sampleRateChanged(uint16_t) override {}
  volatile uint8_t sink_ = 0;
};

CountingHardware hardware;
const delta6::Identity identity = {"delta6", 0x535534AF,
                                   {15.03f, 15.03f, 25.1f, 0.3805f, 0.3347f, 0.4266f},
                                   0.5236f, {0, 1, 0}, 500000, 2000, 0, 0};
const delta6::Config defaults = {500, 1, false, {0, 0, 0, 0, 0, 0},
                                 {1200, 5400, 9800, 14100, 300, 16000}};
delta6::Device device(hardware, identity, defaults);
delta6::Sample sample;

uint16_t command(const uint8_t* frame, uint8_t n) {
  for (uint8_t i = 0; i + 1 < n; ++i) device.onByte(frame[i]);
  TCNT1 = 0;
  device.onByte(frame[n - 1]);  // the delimiter: parse, execute, answer
  return TCNT1;
}

uint16_t samples(uint8_t reps) {
  uint32_t total = 0;
  for (uint8_t r = 0; r < reps; ++r) {
    sample.time_us += 2000;
    sample.wrench[0] += 0.0137f;
    sample.wrench[2] -= 0.021f;
    sample.wrench[4] += 0.0003f;
    TCNT1 = 0;
    device.onSample(sample);
    total += TCNT1;
  }
  return static_cast<uint16_t>(total / reps);
}

const uint8_t kStart[] = {0x07, 0x82, 0x22, 0xf4, 0x01, 0x93, 0x12, 0x00};
const uint8_t kRaw[] = {0x06, 0x84, 0x24, 0x02, 0xc1, 0x66, 0x00};
const uint8_t kTare[] = {0x04, 0x85, 0x25, 0x0a, 0x03, 0x67, 0x40, 0x00};
const uint8_t kInfo[] = {0x05, 0x80, 0x20, 0x22, 0xf5, 0x00};
const uint8_t kTelemetry[] = {0x05, 0x8b, 0x2b, 0x4f, 0x64, 0x00};

}  // namespace

int main() {
  UBRR0 = 0;  // 2 Mbaud with U2X at 16 MHz: the emulator does not care
  UCSR0A = 1 << U2X0;
  UCSR0B = 1 << TXEN0;
  fdev_setup_stream(&uart, uartPut, NULL, _FDEV_SETUP_WRITE);
  stdout = &uart;
  TCCR1A = 0;
  TCCR1B = 1;  // Timer 1 at the CPU clock

  TCNT1 = 0;
  device.begin(0);
  const uint16_t begin = TCNT1;
  for (uint8_t i = 0; i < 6; ++i) {
    sample.counts[i] = static_cast<uint16_t>(defaults.zero_counts[i] + 100 * i);
    sample.wrench[i] = 1.5f * static_cast<float>(i + 1) - 4.0f;
  }
  sample.solver_ok = true;
  sample.loop_time_us = 900;
  sample.temperature_centi = delta6::proto::kTemperatureUnknown;

  const uint16_t stopped = samples(50);
  const uint16_t start = command(kStart, sizeof kStart);
  const uint16_t wrench = samples(50);
  const uint16_t mode = command(kRaw, sizeof kRaw);
  const uint16_t raw = samples(50);
  command(kTare, sizeof kTare);
  samples(10);
  const uint16_t tared = samples(50);
  const uint16_t info = command(kInfo, sizeof kInfo);
  const uint16_t telemetry = command(kTelemetry, sizeof kTelemetry);
  printf("begin %u stopped %u wrench %u raw %u raw_tared %u start %u set_mode %u get_info %u "
         "get_telemetry %u mode %u tare %u\n", begin, stopped, wrench, raw, tared, start, mode,
         info, telemetry, device.mode(), device.config().tare_active ? 1 : 0);
  for (;;) {
  }
}
