#include "delta6_crc16.h"

namespace delta6 {

uint16_t crc16Update(uint16_t crc, uint8_t byte) {
  // The eight shift-and-XOR steps of the MSB-first algorithm, folded: x is the byte that
  // leaves the register XOR the input, and 0x1021 = x^12 + x^5 + 1 spreads it back in.
  uint8_t x = static_cast<uint8_t>((crc >> 8) ^ byte);
  x ^= static_cast<uint8_t>(x >> 4);
  return static_cast<uint16_t>((crc << 8) ^ (static_cast<uint16_t>(x) << 12) ^
                               (static_cast<uint16_t>(x) << 5) ^ x);
}

uint16_t crc16(const uint8_t* data, uint16_t n, uint16_t crc) {
  for (uint16_t i = 0; i < n; ++i) crc = crc16Update(crc, data[i]);
  return crc;
}

}  // namespace delta6
