// Constant data in program memory on the AVR, plain memory on the host. avr-gcc copies every
// initialised variable, const or not, into the 2 KB of RAM at start-up unless it is declared
// in flash; such data must then be read with the LPM instruction, never through a normal
// pointer. Declare a table or structure with DELTA6_FLASH and read it only through these
// accessors: the same source then runs on the board and natively.
#ifndef DELTA6_FLASH_H
#define DELTA6_FLASH_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#if defined(__AVR__)
#include <avr/pgmspace.h>
#define DELTA6_FLASH PROGMEM
#else
#define DELTA6_FLASH
#endif

namespace delta6 {
namespace flash {

inline uint8_t byte(const uint8_t* p) {
#if defined(__AVR__)
  return pgm_read_byte(p);
#else
  return *p;
#endif
}

inline float f32(const float* p) {
#if defined(__AVR__)
  return pgm_read_float(p);
#else
  return *p;
#endif
}

// n bytes from flash at src to RAM at dst.
inline void copy(void* dst, const void* src, size_t n) {
#if defined(__AVR__)
  memcpy_P(dst, src, n);
#else
  memcpy(dst, src, n);
#endif
}

}  // namespace flash
}  // namespace delta6

#endif  // DELTA6_FLASH_H
