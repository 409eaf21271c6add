// Small float helpers for the solver: flash tables, exact scaling by powers of two, and a
// finite check, all cheaper on the AVR than the general avr-libc routines they replace.
// Assumes IEEE-754 binary32 floats, true for avr-gcc and every host g++ target.
#ifndef DELTA6_FASTMATH_H
#define DELTA6_FASTMATH_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "delta6_flash.h"

namespace delta6 {
namespace fastmath {

// Read a float stored with DELTA6_FLASH (program memory on the AVR, plain memory elsewhere).
inline float flash_float(const float* p) { return flash::f32(p); }

inline uint32_t bits_of(float x) {
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

inline float float_of(uint32_t u) {
    float x;
    memcpy(&x, &u, sizeof x);
    return x;
}

// x * 2^k for k = +-1, +-2: adds k to the exponent field (in the upper 16 bits) instead of
// calling the float multiply. Zero, subnormal, infinite and NaN inputs, and results that
// would leave the normal range, fall back to the multiply, which handles them correctly.
inline float scale2(float x, int8_t k) {
    const uint32_t u = bits_of(x);
    const uint16_t hi = static_cast<uint16_t>(u >> 16);
    const int16_t exponent = static_cast<int16_t>(hi & 0x7F80u);  // in units of 0x80
    const int16_t shifted = static_cast<int16_t>(exponent + k * 0x80);
    if (exponent == 0 || exponent == 0x7F80 || shifted <= 0 || shifted >= 0x7F80) {
        return x * (k >= 0 ? static_cast<float>(1 << k) : 1.0f / static_cast<float>(1 << -k));
    }
    const uint16_t new_hi = static_cast<uint16_t>(hi + k * 0x80);
    return float_of((static_cast<uint32_t>(new_hi) << 16) | (u & 0xFFFFu));
}

// avr-libc maps sqrtf/sinf/cosf onto its 32-bit double functions; these keep every
// expression in float on both targets (no double promotion on the host).
inline float sqrt32(float x) { return static_cast<float>(sqrtf(x)); }
inline float sin32(float x) { return static_cast<float>(sinf(x)); }
inline float cos32(float x) { return static_cast<float>(cosf(x)); }

// x >= bound for a positive finite bound, NaN and +inf excluded: finite non-negative floats
// order like their bit patterns, so this is an integer compare (no float library call).
inline bool at_least(float x, float bound) {
    const int32_t bx = static_cast<int32_t>(bits_of(x));
    return bx >= static_cast<int32_t>(bits_of(bound)) && bx < 0x7F800000L;
}

// True unless x is NaN or +-infinity (exponent all ones): an integer test, no float compare.
inline bool is_finite(float x) { return (bits_of(x) & 0x7F800000ul) != 0x7F800000ul; }

inline float absf(float x) { return float_of(bits_of(x) & 0x7FFFFFFFul); }

// cos and sin of an angle given in encoder counts, by angle addition from two tables:
// the angle is q + l with q a multiple of 64 counts and l = 0..63 counts. ``biased`` is the
// count plus a multiple of 64 that makes it non-negative (the coarse table starts there).
// Coarse triples: a cos q, a sin q, a (cos q + sin q) for a constant a; fine triples:
// cos l, sin l - cos l, cos l + sin l. With those sums precomputed the complex product
// (cos q + i sin q)(cos l + i sin l) takes 3 multiplies and 2 additions (Gauss), exact to
// a few float roundings.
inline void table_cos_sin(const float* coarse, const float* fine, uint16_t biased,
                          float* cos_out, float* sin_out) {
    // biased >> 6 as the high byte of biased << 2: avr-gcc shifts by 6 in a loop otherwise.
    const uint8_t j = static_cast<uint8_t>(static_cast<uint16_t>(biased << 2) >> 8);
    const uint8_t l = static_cast<uint8_t>(biased & 63u);
    const float* cq = coarse + 3 * j;
    const float* cl = fine + 3 * l;
    const float k1 = flash_float(cl) * flash_float(cq + 2);
    *cos_out = k1 - flash_float(cq + 1) * flash_float(cl + 2);
    *sin_out = k1 + flash_float(cq) * flash_float(cl + 1);
}

// (a, b) <- (c a + s b, c b - s a): a plane rotation by -angle (the statics of both solvers).
inline void rotate_back(float c, float s, float& a, float& b) {
    const float a1 = c * a + s * b;
    b = c * b - s * a;
    a = a1;
}

}  // namespace fastmath
}  // namespace delta6

#endif  // DELTA6_FASTMATH_H
