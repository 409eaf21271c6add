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

inline int8_t i8(const int8_t* p) {
#if defined(__AVR__)
  return static_cast<int8_t>(pgm_read_byte(p));
#else
  return *p;
#endif
}

inline int16_t i16(const int16_t* p) {
#if defined(__AVR__)
  return static_cast<int16_t>(pgm_read_word(p));
#else
  return *p;
#endif
}

inline int32_t i32(const int32_t* p) {
#if defined(__AVR__)
  return static_cast<int32_t>(pgm_read_dword(p));
#else
  return *p;
#endif
}

// A pointer stored in flash (a table of tables): 16 bits on the AVR.
inline const float* table(const float* const* p) {
#if defined(__AVR__)
  return reinterpret_cast<const float*>(pgm_read_word(p));
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
