#include "delta6_cobs.h"

namespace delta6 {

uint16_t cobsEncodeInPlace(uint8_t* buf, uint16_t n) {
  if (n > kCobsMaxInPlace) return 0;
  // Walk the payload; every 0x00 becomes the distance to the next 0x00 (or the end), written
  // into the previous code slot. The first code slot is buf[0].
  uint16_t code_at = 0;
  for (uint16_t i = 1; i <= n; ++i) {
    if (buf[i] == 0) {
      buf[code_at] = static_cast<uint8_t>(i - code_at);
      code_at = i;
    }
  }
  buf[code_at] = static_cast<uint8_t>(n + 1 - code_at);
  return static_cast<uint16_t>(n + 1);
}

int16_t cobsDecodeInPlace(uint8_t* buf, uint16_t n) {
  uint16_t in = 0;
  uint16_t out = 0;
  while (in < n) {
    const uint8_t code = buf[in];
    if (code == 0 || in + code > n) return -1;
    // Copying forward never overtakes the read position: out <= in always.
    for (uint8_t k = 1; k < code; ++k) {
      const uint8_t b = buf[in + k];
      if (b == 0) return -1;
      buf[out++] = b;
    }
    in = static_cast<uint16_t>(in + code);
    // A block shorter than 255 ends in an implicit zero, except at the very end.
    if (code != 0xFF && in < n) buf[out++] = 0;
  }
  return static_cast<int16_t>(out);
}

}  // namespace delta6
