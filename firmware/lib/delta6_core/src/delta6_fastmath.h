// Small float helpers for the solver: flash tables, exact scaling by powers of two, and a
// finite check, all cheaper on the AVR than the general avr-libc routines they replace.
// Assumes IEEE-754 binary32 floats, true for avr-gcc and every host g++ target.
#ifndef DELTA6_FASTMATH_H
#define DELTA6_FASTMATH_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__AVR__)
#include <avr/pgmspace.h>
#define DELTA6_FLASH PROGMEM
#else
#define DELTA6_FLASH
#endif

namespace delta6 {
namespace fastmath {

// Read a float stored with DELTA6_FLASH (program memory on the AVR, plain memory elsewhere).
inline float flash_float(const float* p) {
#if defined(__AVR__)
    return pgm_read_float(p);
#else
    return *p;
#endif
}

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

// x * 2^k, exact, for |k| small: adds k to the exponent instead of calling the float
// multiply (about 150 cycles on the AVR). Zero, subnormal results and overflow fall back
// to the multiply, which handles them correctly.
inline float scale2(float x, int8_t k) {
    uint32_t u = bits_of(x);
    int16_t e = static_cast<int16_t>((u >> 23) & 0xFFu);
    int16_t ne = static_cast<int16_t>(e + k);
    if (e == 0 || e == 0xFF || ne <= 0 || ne >= 0xFF) {
        return k >= 0 ? x * static_cast<float>(1L << k)
                      : x / static_cast<float>(1L << -k);
    }
    u = (u & ~(0xFFul << 23)) | (static_cast<uint32_t>(ne) << 23);
    return float_of(u);
}

// avr-libc maps sqrtf/sinf/cosf onto its 32-bit double functions; these keep every
// expression in float on both targets (no double promotion on the host).
inline float sqrt32(float x) { return static_cast<float>(sqrtf(x)); }
inline float sin32(float x) { return static_cast<float>(sinf(x)); }
inline float cos32(float x) { return static_cast<float>(cosf(x)); }

// True unless x is NaN or +-infinity (exponent all ones): an integer test, no float compare.
inline bool is_finite(float x) { return (bits_of(x) & 0x7F800000ul) != 0x7F800000ul; }

inline float absf(float x) { return float_of(bits_of(x) & 0x7FFFFFFFul); }

// cos and sin of an angle given in encoder counts, by angle addition from two tables:
// angle = q + l with q a multiple of the coarse step (pairs a*cos q, a*sin q, a a constant)
// and l = 0..step-1 counts (pairs cos l, sin l). Exact to float rounding; 4 multiplies.
struct CosSin {
    float c;
    float s;
};

inline CosSin table_cos_sin(const float* coarse, const float* fine, uint16_t biased_count,
                            uint8_t step_shift) {
    uint16_t j = static_cast<uint16_t>(biased_count >> step_shift);
    uint16_t l = static_cast<uint16_t>(biased_count & ((1u << step_shift) - 1u));
    float cq = flash_float(coarse + 2 * j);
    float sq = flash_float(coarse + 2 * j + 1);
    float cl = flash_float(fine + 2 * l);
    float sl = flash_float(fine + 2 * l + 1);
    CosSin out;
    out.c = cq * cl - sq * sl;
    out.s = sq * cl + cq * sl;
    return out;
}

}  // namespace fastmath
}  // namespace delta6

#endif  // DELTA6_FASTMATH_H
