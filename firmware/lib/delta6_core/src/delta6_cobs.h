// Consistent Overhead Byte Stuffing: frames contain no 0x00, so 0x00 delimits them and a
// receiver resynchronises at the next 0x00 after any damage (docs/protocol.md, "Framing").
#ifndef DELTA6_COBS_H
#define DELTA6_COBS_H

#include <stdint.h>

namespace delta6 {

// Longest payload the in-place encoder takes: up to 254 bytes COBS adds exactly one byte.
const uint16_t kCobsMaxInPlace = 254;

// Encode buf[1..n] in place into buf[0..n] (buf[0] is scratch on entry), for n <= 254.
// Returns the encoded length n + 1, or 0 if n is too long. Records are built directly after a
// spare first byte, so the device needs no second buffer.
uint16_t cobsEncodeInPlace(uint8_t* buf, uint16_t n);

// Decode n encoded bytes (no delimiter) in place. Returns the decoded length, or -1 if the
// input is not valid COBS (a 0x00 inside, or a code that runs past the end).
int16_t cobsDecodeInPlace(uint8_t* buf, uint16_t n);

}  // namespace delta6

#endif
