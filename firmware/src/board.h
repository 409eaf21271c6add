// The board layer: everything the application needs from the hardware, one implementation per
// MCU (board_atmega328p.cpp, board_atmega4809.cpp). The application (app.cpp) and the
// portable core see only these functions, so the same logic runs on the Nano Every, on the
// classic Nano and, as the ATmega328P image, in the emulator.
#ifndef DELTA6_BOARD_H
#define DELTA6_BOARD_H

#include <stdint.h>

#if defined(__AVR__)
#include <avr/io.h>
#endif

namespace board {

// The UART's rate: 500000 baud divides 16 MHz exactly on both MCUs (docs/protocol.md).
const uint32_t kBaud = 500000;

// Pins, UART, and whatever the MCU needs before the loop runs. Interrupts stay as the Arduino
// core left them (enabled).
void init();
// Why the MCU last reset, as the ATmega4809's RSTCTRL.RSTFR bits (the 328P's MCUSR is mapped):
// 0x01 power-on, 0x02 brown-out, 0x04 reset pin, 0x08 watchdog, 0x10 software, 0x20 UPDI.
uint8_t resetCause();
// A board identifier for the info record (the 4809's factory serial number folded to 32 bits;
// 0 on the 328P, which has none).
uint32_t serialNumber();
// This boot session's identifier for the info and telemetry records: a counter in RAM that no
// start-up code clears, stepped at every boot, so a reset (watchdog, pin, brown-out) gives a
// value the previous boot did not have; after power-on it starts from whatever the RAM held.
uint16_t bootId();

// (Re)start the sample timer at rate_hz; its interrupt calls app::onSampleTick() once per
// period with interrupts enabled (UART interrupts may preempt it).
void startSampling(uint16_t rate_hz);
uint32_t micros();

// Clock in one frame from all six encoders at once: word[j], inverse[j] of encoder j + 1.
void scanEncoders(uint16_t word[6], uint16_t inverse[6]);

// Interrupt-driven UART. The transmit queue holds kTxQueue - 1 bytes.
const uint16_t kTxQueue = 256;
uint16_t txSpace();
void txWrite(const uint8_t* data, uint16_t n);
// The timing marker D6_MARK_RECORD_QUEUED with the bytes waiting in the transmit queue in
// GPIOR1, both written with interrupts off so that the two agree.
void markRecordQueued();
int16_t rxRead();            // the next received byte, or -1
bool rxAvailable();

void eepromRead(uint16_t address, uint8_t* data, uint16_t n);
// Blocks about 3.4 ms per changed byte on the 328P; keeps the watchdog fed meanwhile.
void eepromWrite(uint16_t address, const uint8_t* data, uint16_t n);

// Watchdog: a timeout long enough for a few periods at rate_hz (250 ms from 10 Hz up, 2 s
// below); kick it once per processed sample.
void watchdogStart(uint16_t rate_hz);
void watchdogKick();

// Sleep until the next interrupt, unless pending() says there is work; pending() runs with
// interrupts off, so no wake-up is lost between the check and the sleep.
void idle(bool (*pending)());

#if defined(DELTA6_TEST_HOOKS)
// Test builds: the virtual board holds this pin low to make the loop hang (watchdog test).
bool testHangRequested();
#endif

// A timing marker for the emulator (board_contract.h): one `out` to GPIOR0; nothing else
// changes. The memory clobbers keep the compiler from moving loads and stores across it.
inline void mark(uint8_t value) {
#if defined(GPIOR0)
  asm volatile("" ::: "memory");
  GPIOR0 = value;
  asm volatile("" ::: "memory");
#else
  (void)value;
#endif
}

// A marker with an argument in GPIOR1 (written first).
inline void mark(uint8_t value, uint8_t argument) {
#if defined(GPIOR1)
  GPIOR1 = argument;
#else
  (void)argument;
#endif
  mark(value);
}

}  // namespace board

#endif  // DELTA6_BOARD_H
