// The ERCK-05SPI encoder frame: what one read returns and how it is checked.
//
// A read (docs/firmware.md, "Encoder bus"): the master sends the 16-bit command kCommand
// (0x55 then 0xFF, most significant bit first) on the sensor's half-duplex data line, releases
// the line, and clocks in 32 bits: a 16-bit word and its bitwise inverse. The pair is intact
// when word + inverse + 1 == 0 (mod 2^16). The two low bits of the word are a status: 01 is a
// valid angle (count = word >> 2, 14 bits, 0..16383 over one turn); 10 is an error with bit 4
// set for a field too strong and bit 5 for a field too weak. Anything else is refused: a
// sensor that does not answer leaves the line at its pull-up (all ones) or stuck low (all
// zeros), and neither pair passes the inverse check.
//
// Portable C++ (no Arduino, no heap): the board layer shifts the bits in, this decides.
#ifndef DELTA6_ENCODER_H
#define DELTA6_ENCODER_H

#include <stdint.h>

namespace delta6 {
namespace encoder {

const uint16_t kCommand = 0x55FF;
const uint8_t kCommandBits = 16;
const uint8_t kResponseBits = 32;   // word, then its inverse

const uint16_t kStatusMask = 0x0003;
const uint16_t kStatusValid = 0x0001;
const uint16_t kStatusError = 0x0002;
const uint16_t kFieldTooStrong = 1u << 4;
const uint16_t kFieldTooWeak = 1u << 5;

// Why a read failed (0: it did not).
enum ReadFault : uint8_t {
  kReadOk = 0,
  kReadBitError = 1,      // the inverse does not match: corrupted bits or no answer
  kReadFieldStrong = 2,   // the sensor reports a magnet too close
  kReadFieldWeak = 3,     // the sensor reports a magnet too far
  kReadSensorError = 4,   // error status without a known cause, or an undefined status
};

// Check one frame. On success writes the 14-bit count; on failure leaves *count alone.
inline ReadFault decodeFrame(uint16_t word, uint16_t inverse, uint16_t* count) {
  if (static_cast<uint16_t>(word + inverse + 1u) != 0) return kReadBitError;
  const uint16_t status = word & kStatusMask;
  if (status == kStatusValid) {
    *count = static_cast<uint16_t>(word >> 2);
    return kReadOk;
  }
  if (status == kStatusError) {
    if (word & kFieldTooStrong) return kReadFieldStrong;
    if (word & kFieldTooWeak) return kReadFieldWeak;
  }
  return kReadSensorError;
}

// The word a healthy sensor sends for a count (0..16383): the reference for tests.
inline uint16_t validWord(uint16_t count) {
  return static_cast<uint16_t>((count << 2) | kStatusValid);
}

}  // namespace encoder
}  // namespace delta6

#endif  // DELTA6_ENCODER_H
