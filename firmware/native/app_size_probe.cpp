// Size probe of the firmware application's portable part (app.cpp, the solver, the protocol
// core) for an instruction set without a device (avrxmega3, the ATmega4809's): a do-nothing
// board layer and a bare main. Built by delta6.build.appbuild.size_check_app for the avrxmega3
// size check; never run, never part of an image people flash.
#include <stdint.h>

#include "app.h"
#include "board.h"

namespace {
volatile uint8_t sink = 0;
volatile uint32_t clock_us = 0;
}  // namespace

namespace board {

void init() {}
uint8_t resetCause() { return sink; }
uint32_t serialNumber() { return 0; }
uint16_t bootId() { return sink; }
void startSampling(uint16_t rate_hz) { sink = static_cast<uint8_t>(rate_hz); }
uint32_t micros() { return clock_us += 4000; }
void scanEncoders(uint16_t word[6], uint16_t inverse[6]) {
  for (uint8_t j = 0; j < 6; ++j) {
    word[j] = static_cast<uint16_t>(sink << 2 | 1);
    inverse[j] = static_cast<uint16_t>(~word[j]);
  }
}
uint16_t txSpace() { return kTxQueue - 1; }
void markRecordQueued() {}
void txWrite(const uint8_t* data, uint16_t n) {
  for (uint16_t i = 0; i < n; ++i) sink = static_cast<uint8_t>(sink ^ data[i]);
}
int16_t rxRead() { return sink ? -1 : sink; }
bool rxAvailable() { return sink == 0; }
void eepromRead(uint16_t, uint8_t* data, uint16_t n) {
  for (uint16_t i = 0; i < n; ++i) data[i] = 0xFF;
}
void eepromWrite(uint16_t, const uint8_t* data, uint16_t n) {
  for (uint16_t i = 0; i < n; ++i) sink = static_cast<uint8_t>(sink ^ data[i]);
}
void watchdogStart(uint16_t rate_hz) { sink = static_cast<uint8_t>(rate_hz >> 8); }
void watchdogKick() {}
void idle(bool (*pending)()) { sink = pending() ? 1 : 0; }

}  // namespace board

int main() {
  app::setup();
  for (;;) {
    app::onSampleTick();
    app::loop();
  }
}
