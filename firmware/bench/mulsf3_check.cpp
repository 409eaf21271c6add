// The fast float multiply (firmware/src/fast_mulsf3.S, linked in as __mulsf3) against avr-libc's
// (firmware/bench/mulsf3_reference.S) on DELTA6_CHECK_PAIRS pseudo-random pairs, bit for bit:
// any bit patterns (zeros, subnormals, infinities, NaNs), normal operands whose products fall
// around the ends of the normal range, and short mantissas whose products land exactly on
// rounding ties, and pairs whose product rounds up to the next power of two. Reports over the UART (polled): "MUL", the pairs, the mismatches, and the
// first mismatch's a, b, fast and reference bits (uint32 little-endian), then 0xFF to GPIOR0.
// Run by tests/sim/test_fast_mulsf3.py; no Arduino core.
#include <avr/io.h>
#include <stdint.h>
#include <string.h>

#ifndef DELTA6_CHECK_PAIRS
#define DELTA6_CHECK_PAIRS 20000UL
#endif

extern "C" float delta6_reference_mulsf3(float a, float b);

namespace {

uint32_t state = 0x2545F491UL;

uint32_t next() {   // xorshift32
  state ^= state << 13;
  state ^= state >> 17;
  state ^= state << 5;
  return state;
}

float as_float(uint32_t u) {
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
}

uint32_t bits(float f) {
  uint32_t u;
  memcpy(&u, &f, sizeof u);
  return u;
}

// An operand of the kind k: 0 any bits, 1 a normal number with exponent e, 2 the same with a
// mantissa of 13 significant bits (their 25- or 26-bit products end on rounding ties often).
uint32_t operand(uint8_t kind, uint8_t exponent) {
  uint32_t u = next();
  if (kind == 0) return u;
  u = (u & 0x807FFFFFUL) | (static_cast<uint32_t>(exponent) << 23);
  if (kind == 2) u &= 0xFFFFF800UL;
  return u;
}

void put(uint8_t b) {
  while (!(UCSR0A & _BV(UDRE0))) {
  }
  UDR0 = b;
}

void put32(uint32_t v) {
  for (uint8_t i = 0; i < 4; ++i) put(static_cast<uint8_t>(v >> (8 * i)));
}

volatile float sink;

}  // namespace

int main() {
  UBRR0 = 0;
  UCSR0A = _BV(U2X0);
  UCSR0B = _BV(TXEN0);
  uint32_t mismatches = 0;
  uint32_t first[4] = {0, 0, 0, 0};
  for (uint32_t i = 0; i < DELTA6_CHECK_PAIRS; ++i) {
    const uint8_t kind = static_cast<uint8_t>(i % 4);
    // Exponents whose sum sweeps the normal range's ends (ea + eb - 127 from about -30 to
    // about 290) as well as its middle.
    const uint8_t ea = static_cast<uint8_t>(1 + next() % 254);
    uint8_t eb;
    const uint8_t pick = static_cast<uint8_t>(next() & 3);
    if (pick == 0) {
      eb = static_cast<uint8_t>(1 + next() % 254);
    } else {
      int16_t target = pick == 1 ? static_cast<int16_t>(next() % 8) - 4 + 1
                       : pick == 2 ? static_cast<int16_t>(next() % 8) - 4 + 254
                                   : static_cast<int16_t>(next() % 200) + 27;
      int16_t e = static_cast<int16_t>(target + 127 - ea);
      eb = static_cast<uint8_t>(e < 1 ? 1 : (e > 254 ? 254 : e));
    }
    const float a = as_float(operand(kind == 3 ? 1 : kind, ea));
    // Kind 3: b next to 2 / a, so that the product is just below 2 (a mantissa of all ones
    // that may round up into the next binade).
    const float b = kind == 3 ? as_float(bits(2.0f / a) - (next() & 3))
                              : as_float(operand(kind, eb));
    volatile float va = a, vb = b;
    const float fast = va * vb;
    const float reference = delta6_reference_mulsf3(va, vb);
    sink = fast;
    if (bits(fast) != bits(reference)) {
      if (mismatches == 0) {
        first[0] = bits(a);
        first[1] = bits(b);
        first[2] = bits(fast);
        first[3] = bits(reference);
      }
      ++mismatches;
    }
  }
  put('M');
  put('U');
  put('L');
  put32(DELTA6_CHECK_PAIRS);
  put32(mismatches);
  for (uint8_t i = 0; i < 4; ++i) put32(first[i]);
  while (!(UCSR0A & _BV(TXC0))) {
  }
  GPIOR0 = 0xFF;
  for (;;) {
  }
}
