#include "delta6_crc16.h"

namespace delta6 {

namespace {

// The step itself, forced inline into crc16's loop: a call per byte costs half as much again
// as the step (LTO stops inlining crc16Update there once the INFO pieces call it too).
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
inline uint16_t step(uint16_t crc, uint8_t byte) {
  // The eight shift-and-XOR steps of the MSB-first algorithm, folded: x is the byte that
  // leaves the register XOR the input, and 0x1021 = x^12 + x^5 + 1 spreads it back in:
  // crc' = (crc << 8) ^ (x << 12) ^ (x << 5) ^ x, written byte by byte because an 8-bit AVR
  // shifts a 16-bit value one bit per instruction (66 cycles a byte the 16-bit way, 20 so).
  uint8_t x = static_cast<uint8_t>((crc >> 8) ^ byte);
  x ^= static_cast<uint8_t>(x >> 4);
  const uint8_t high = static_cast<uint8_t>(static_cast<uint8_t>(crc) ^
                                            static_cast<uint8_t>(x << 4) ^
                                            static_cast<uint8_t>(x >> 3));
  const uint8_t low = static_cast<uint8_t>(static_cast<uint8_t>(x << 5) ^ x);
  return static_cast<uint16_t>((static_cast<uint16_t>(high) << 8) | low);
}

}  // namespace

uint16_t crc16Update(uint16_t crc, uint8_t byte) { return step(crc, byte); }

uint16_t crc16(const uint8_t* data, uint16_t n, uint16_t crc) {
  for (uint16_t i = 0; i < n; ++i) crc = step(crc, data[i]);
  return crc;
}

}  // namespace delta6
