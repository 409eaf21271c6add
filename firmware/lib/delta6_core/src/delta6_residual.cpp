#include "delta6_residual.h"

#include "delta6_flash.h"

#include <math.h>
#include <string.h>

namespace delta6 {
namespace residual {

namespace {

// int8 x int8 -> int16: one MULS on the AVR (avr-gcc 5.4 otherwise widens to a 16 x 16 call).
inline int16_t mul8(int8_t a, int8_t b) {
#if defined(__AVR__)
    int16_t product;
    asm("muls %1, %2\n\tmovw %0, r0\n\tclr __zero_reg__" : "=r"(product) : "d"(a), "d"(b));
    return product;
#else
    return static_cast<int16_t>(a * b);
#endif
}

// Arithmetic right shift by 0..31 with the whole bytes moved first (the AVR shifts a 32-bit
// value one bit per loop turn, so 24 bits would cost ~150 cycles).
inline int32_t shiftRight(int32_t x, uint8_t s) {
    if (s & 16) x >>= 16;
    if (s & 8) x >>= 8;
    return x >> (s & 7);
}

// 16 x 16 -> 32 multiplies through avr-gcc's widening signed helper, never a 32 x 32 one.
inline int32_t mulS16(int16_t a, int16_t b) { return static_cast<int32_t>(a) * b; }
// a * b for unsigned a: 2 (a / 2) b + (a mod 2) b, both products in 31 bits.
inline int32_t mulU16S16(uint16_t a, int16_t b) {
    const int32_t half = mulS16(static_cast<int16_t>(a >> 1), b);
    return half + half + ((a & 1u) ? b : 0);
}

inline int16_t saturate16(int32_t v) {
    return static_cast<int16_t>(v > 32767 ? 32767 : (v < -32768 ? -32768 : v));
}

inline int8_t saturate8(int32_t v, int8_t lo) {
    return static_cast<int8_t>(v > 127 ? 127 : (v < lo ? lo : v));
}

// Ring entry `periods` model periods before the newest one.
inline const int16_t* past(const int16_t* ring, const State& s, uint8_t length, int16_t periods) {
    int16_t back = static_cast<int16_t>(periods * s.stride);
    int16_t index = static_cast<int16_t>(s.head) - back;
    if (index < 0) index = static_cast<int16_t>(index + length);
    return ring + 6 * index;
}

// The int8 input vector of the first layer; advances the plays.
void features(const Model& model, State& s, const int16_t base[6], const int16_t counts[6],
              int8_t* x) {
    int16_t* play = s.plays;
    for (uint8_t g = 0; g < model.feature_count; ++g) {
        Feature f;
        flash::copy(&f, &model.features[g], sizeof f);
        int16_t v[6];
        if (f.kind == kFeatureWrench) {
            memcpy(v, base, sizeof v);
        } else if (f.kind == kFeatureCounts) {
            memcpy(v, counts, sizeof v);
        } else if (f.kind == kFeaturePlay) {
            for (uint8_t i = 0; i < 6; ++i) {
                const int32_t lo = static_cast<int32_t>(counts[i]) - f.param;
                const int32_t hi = static_cast<int32_t>(counts[i]) + f.param;
                if (play[i] < lo) play[i] = static_cast<int16_t>(lo);
                if (play[i] > hi) play[i] = static_cast<int16_t>(hi);
                v[i] = saturate16(static_cast<int32_t>(counts[i]) - play[i]);
            }
            play += 6;
        } else {   // the steps
            const int16_t* ring = f.kind == kFeatureWrenchStep ? s.wrench_ring : s.count_ring;
            const int16_t* now =
                past(ring, s, model.history_length, static_cast<int16_t>(f.param - 1));
            const int16_t* then = past(ring, s, model.history_length, f.param);
            for (uint8_t i = 0; i < 6; ++i) {
                v[i] = saturate16(static_cast<int32_t>(now[i]) - then[i]);
            }
        }
        for (uint8_t i = 0; i < 6; ++i) {
            *x++ = saturate8(requantize16(v[i], f.multiplier[i], f.shift[i]), -127);
        }
    }
}

}  // namespace

// floor((x + 2^(s-1)) / 2^s) = floor((floor(x / 2^(s-1)) + 1) / 2): the half is added after
// the shift, so no 2^(s-1) is ever built (a one-bit-per-turn loop on the AVR).
int32_t requantize16(int16_t value, int16_t m, uint8_t shift) {
    const int32_t p = mulS16(value, m);   // |p| <= 2^30
    return (shiftRight(p, static_cast<uint8_t>(shift - 1)) + 1) >> 1;
}

int32_t requantize32(int32_t acc, int16_t m, uint8_t shift) {
    // acc * m = hi * m * 2^16 + lo * m, both products in 31 bits. For s >= 17:
    // floor(acc * m / 2^(s-1)) = floor((hi * m + floor(lo * m / 2^16)) / 2^(s-17)) (a floor of
    // a floor is the floor of the quotient), then the half as in requantize16. For s = 16 the
    // half goes to the low product.
    const int16_t hi = static_cast<int16_t>(acc >> 16);
    const uint16_t lo = static_cast<uint16_t>(acc);
    const int32_t p = mulS16(hi, m);
    const int32_t q = mulU16S16(lo, m);
    if (shift <= 16) return p + ((q + (static_cast<int32_t>(1) << 15)) >> 16);
    return (shiftRight(p + (q >> 16), static_cast<uint8_t>(shift - 17)) + 1) >> 1;
}

uint8_t strideFor(const Model& model, uint16_t board_rate_hz) {
    const uint32_t r = model.rate_hz ? model.rate_hz : 1;
    uint32_t stride = (2u * static_cast<uint32_t>(board_rate_hz) + r) / (2u * r);
    if (stride < 1) stride = 1;
    if (stride > kMaxStride) stride = kMaxStride;
    return static_cast<uint8_t>(stride);
}

void configure(const Model& model, State& state, uint16_t board_rate_hz) {
    state.stride = strideFor(model, board_rate_hz);
    state.head = 0;
    state.primed = false;
}

void step(const Model& model, State& s, const int16_t base[6], const int16_t counts[6],
          int16_t correction[6]) {
    const uint8_t length = model.history_length;
    if (!s.primed) {   // from rest: the whole past equals this sample, the plays centred on it
        for (uint8_t k = 0; k < length; ++k) {
            if (model.wrench_history) memcpy(s.wrench_ring + 6 * k, base, 6 * sizeof(int16_t));
            if (model.count_history) memcpy(s.count_ring + 6 * k, counts, 6 * sizeof(int16_t));
        }
        for (uint8_t p = 0; p < model.play_count; ++p) {
            memcpy(s.plays + 6 * p, counts, 6 * sizeof(int16_t));
        }
        s.head = 0;
        s.primed = true;
    } else if (length) {
        s.head = static_cast<uint8_t>(s.head + 1 == length ? 0 : s.head + 1);
        if (model.wrench_history) memcpy(s.wrench_ring + 6 * s.head, base, 6 * sizeof(int16_t));
        if (model.count_history) memcpy(s.count_ring + 6 * s.head, counts, 6 * sizeof(int16_t));
    }
    int8_t a[kMaxWidth];
    int8_t b[kMaxWidth];
    features(model, s, base, counts, a);
    int8_t* in = a;
    int8_t* out = b;
    for (uint8_t l = 0; l < model.layer_count; ++l) {
        Layer layer;
        flash::copy(&layer, &model.layers[l], sizeof layer);
        const int8_t* w = layer.weights;
        const uint8_t inputs = layer.inputs;
        for (uint8_t o = 0; o < layer.outputs; ++o) {
            int32_t acc = flash::i32(layer.bias + o);
            const int8_t* x = in;
            // Two products fit an int16 (|w|, |x| <= 127): one 32-bit addition per pair.
            uint8_t j = inputs;
            for (; j >= 2; j = static_cast<uint8_t>(j - 2)) {
                const int8_t w0 = flash::i8(w++);
                const int8_t w1 = flash::i8(w++);
                const int16_t pair = static_cast<int16_t>(mul8(w0, x[0]) + mul8(w1, x[1]));
                x += 2;
                acc += pair;
            }
            if (j) acc += mul8(flash::i8(w++), *x);
            const int32_t y = requantize32(acc, flash::i16(layer.multiplier + o),
                                           flash::byte(layer.shift + o));
            if (layer.relu) {
                out[o] = saturate8(y, 0);
            } else {
                correction[o] = saturate16(y);
            }
        }
        int8_t* t = in;
        in = out;
        out = t;
    }
}

void quantizeInput(const Model& model, const float wrench[6], int16_t base[6]) {
    for (uint8_t i = 0; i < 6; ++i) {
        float v = wrench[i] * flash::f32(model.input_scale + i);
        // Saturate first (also keeps lroundf in range); a NaN never reaches here: the solver
        // gives a wrench only when it is finite.
        if (!(v < 32767.0f)) v = 32767.0f;
        if (!(v > -32768.0f)) v = -32768.0f;
        base[i] = static_cast<int16_t>(lroundf(v));
    }
}

void applyOutput(const Model& model, const int16_t correction[6], float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) {
        wrench[i] += static_cast<float>(correction[i]) * flash::f32(model.output_step + i);
    }
}

}  // namespace residual
}  // namespace delta6
