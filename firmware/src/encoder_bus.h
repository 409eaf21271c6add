// The six ERCK-05SPI encoders read in parallel on one shared clock (docs/firmware.md,
// "Encoder bus"). Included by each board file with its Pins class, which provides fast port
// access (single instructions, no digitalWrite):
//   selectAll() / deselectAll()   all six chip selects low / high
//   clockHigh() / clockLow()      the shared clock
//   driveData(bits) / writeData(bits) / releaseData()   data lines: outputs, set, back to
//                                 inputs with pull-ups; bit j of `bits` is encoder j + 1
//   readData()                    one port read: bit j is encoder j + 1's data line
//
// Timing. No timing figures of the ERCK-05SPI are public; we assume an SSI-like slave and keep
// generous margins (the virtual board checks every one of these, tools/simavr/virtual_board):
//   - the sensor latches its angle when selected and needs kSelectSetupNs before the first
//     clock edge;
//   - command bits: the master sets the data while the clock is low, the sensor samples on
//     the rising edge; clock high and low each at least kHalfPeriodNs (<= 500 kHz);
//   - turnaround: the master releases the line before the 16th falling edge; the sensor drives
//     each response bit within kDataValidNs after a falling edge and the master samples at the
//     next rising edge, a full low phase later;
//   - the sensor releases the line when deselected.
// Interrupts may stretch any phase (the timer interrupt that runs this is preemptible by the
// UART's); only minimum times matter to a clocked slave.
#ifndef DELTA6_ENCODER_BUS_H
#define DELTA6_ENCODER_BUS_H

#include <stdint.h>

#include "board_contract.h"
#include "delta6_encoder.h"

// The portable core keeps its own copy of the command (it cannot include the board layer).
static_assert(delta6::encoder::kCommand == D6_ENCODER_COMMAND &&
                  delta6::encoder::kCommandBits == D6_ENCODER_COMMAND_BITS,
              "delta6_encoder.h and board_contract.h disagree on the encoder command");

namespace bus {

const uint32_t kHalfPeriodNs = D6_BUS_HALF_PERIOD_NS;
const uint32_t kSelectSetupNs = D6_BUS_SELECT_SETUP_NS;
const uint32_t kDataValidNs = D6_BUS_DATA_VALID_NS;   // what we assume of the sensor
static_assert(kDataValidNs < kHalfPeriodNs, "a response bit must be valid before the sample");
const uint8_t kAllSix = 0x3F;

template <uint32_t Ns>
inline void delayNs() {
  // Rounded up: waits at least Ns.
  __builtin_avr_delay_cycles((F_CPU / 1000000UL * Ns + 999UL) / 1000UL);
}

// The fewest cycles the bit shuffling below can take: six 16-bit shifts that take in a bit
// each need at least three single-cycle instructions (lsr, rol, rol) whatever the compiler
// makes of them.
const uint32_t kShuffleMinCycles = 18;
// What the high phase still waits beyond the shuffling (0 at 16 MHz, a few cycles at 20 MHz).
const uint32_t kShuffleNs = kShuffleMinCycles * 1000UL / (F_CPU / 1000000UL);
const uint32_t kHighAfterShuffleNs = kHalfPeriodNs > kShuffleNs ? kHalfPeriodNs - kShuffleNs : 0;

// Clock in 16 bits from all six sensors: w[j] gets encoder j + 1's bits, most significant bit
// first. The bit shuffling runs in the high phase of the clock, where it counts towards the
// phase instead of adding to the scan (the sensor holds its bit until the falling edge); six
// words in registers, one test-and-set per bit. The empty asm with the words as operands
// keeps the compiler from moving the shuffling past the falling edge.
template <class Pins>
inline void clockIn16(uint16_t* w) {
  uint16_t w0 = 0, w1 = 0, w2 = 0, w3 = 0, w4 = 0, w5 = 0;
  for (uint8_t i = 0; i < 16; ++i) {
    delayNs<kHalfPeriodNs>();      // low phase: the sensor put this bit out at the falling edge
    Pins::clockHigh();
    const uint8_t s = Pins::readData();
    // None of the shuffling before the rising edge (the shifts do not need the bit and could
    // be hoisted): it is what fills the high phase. The clobber orders it after the port read.
    asm volatile("" : "+r"(w0), "+r"(w1), "+r"(w2), "+r"(w3), "+r"(w4), "+r"(w5) : : "memory");
    w0 = static_cast<uint16_t>(w0 << 1);
    w1 = static_cast<uint16_t>(w1 << 1);
    w2 = static_cast<uint16_t>(w2 << 1);
    w3 = static_cast<uint16_t>(w3 << 1);
    w4 = static_cast<uint16_t>(w4 << 1);
    w5 = static_cast<uint16_t>(w5 << 1);
    if (s & 0x01) w0 |= 1;
    if (s & 0x02) w1 |= 1;
    if (s & 0x04) w2 |= 1;
    if (s & 0x08) w3 |= 1;
    if (s & 0x10) w4 |= 1;
    if (s & 0x20) w5 |= 1;
    asm volatile("" : "+r"(w0), "+r"(w1), "+r"(w2), "+r"(w3), "+r"(w4), "+r"(w5));
    delayNs<kHighAfterShuffleNs>();   // the rest of the high phase, if any
    Pins::clockLow();              // the sensor moves on to the next bit
  }
  w[0] = w0;
  w[1] = w1;
  w[2] = w2;
  w[3] = w3;
  w[4] = w4;
  w[5] = w5;
}

template <class Pins>
void scan(uint16_t word[6], uint16_t inverse[6]) {
  Pins::selectAll();               // the sensors latch their angles now
  Pins::driveData(kAllSix);        // the first command bit (0x55: msb 0) follows at once
  delayNs<kSelectSetupNs>();
  uint16_t command = D6_ENCODER_COMMAND;
  for (uint8_t i = 0; i < D6_ENCODER_COMMAND_BITS; ++i) {
    Pins::writeData((command & 0x8000u) ? kAllSix : 0);
    command = static_cast<uint16_t>(command << 1);
    delayNs<kHalfPeriodNs>();      // data setup before the rising edge
    Pins::clockHigh();
    delayNs<kHalfPeriodNs>();
    if (i == D6_ENCODER_COMMAND_BITS - 1) {
#if defined(DELTA6_TEST_LATE_RELEASE)
      // Test builds only: release the line too late, so that the virtual board's contention
      // detector has something to find (tests/sim/test_virtual_board.py).
      Pins::clockLow();
      delayNs<kDataValidNs + 500>();
      Pins::releaseData();
      continue;
#endif
      Pins::releaseData();   // turnaround: before the falling edge that lets the sensor drive
    }
    Pins::clockLow();
  }
  clockIn16<Pins>(word);
  clockIn16<Pins>(inverse);
  Pins::deselectAll();
}

}  // namespace bus

#endif  // DELTA6_ENCODER_BUS_H
