// Residual engine benchmark and self-check sketch: runs delta6::residual::step of the model in
// generated/delta6_model.h over a pseudo-random stream (random walks of the base wrench and
// the counts, one sample in 64 without a wrench, which resets the history) and reports every
// correction, so a host can check the AVR's integers against the numpy reference
// (delta6.sim.residualbench regenerates the same stream with the same xorshift).
//
// Timing: each step is bracketed by writes of 1 and 2 to GPIOR0 with interrupts off (a 3/4
// pair measures the markers themselves); 0xFF ends the run.
//
// Frames, little-endian, each starting with 0xD6 and a type byte:
//   'I'  uint32 model hash, uint16 samples, uint16 board rate, uint8 stride  (first)
//   'S'  uint8 valid, int16 correction[6]                                   (one per sample)
//   'E'  uint16 peak stack bytes, uint16 static RAM                          (last)
#include <Arduino.h>

#include "bench_support.h"
#include "delta6_residual.h"
#include "generated/delta6_model.h"

#ifndef DELTA6_BENCH_SAMPLES
#define DELTA6_BENCH_SAMPLES 2000
#endif
#ifndef DELTA6_BENCH_BAUD
#define DELTA6_BENCH_BAUD 115200
#endif
#ifndef DELTA6_BENCH_RATE_HZ
#define DELTA6_BENCH_RATE_HZ 250
#endif

namespace {

namespace m = delta6::model;
namespace r = delta6::residual;

using bench::mark;
using bench::next_random;
using bench::send;

// A step of -limit..limit from the high bits of the next random number.
int16_t random_step(uint8_t bits) {
    const int16_t r = static_cast<int16_t>(next_random() >> (16 - bits));
    return static_cast<int16_t>(r - (1 << (bits - 1)));
}

int16_t walk(int16_t x, uint8_t bits, int16_t limit) {
    int32_t y = static_cast<int32_t>(x) + random_step(bits);
    if (y > limit) y = limit;
    if (y < -limit) y = -limit;
    return static_cast<int16_t>(y);
}

int16_t wrench_ring[m::kWrenchHistory ? 6 * m::kHistoryLength : 1];
int16_t count_ring[m::kCountHistory ? 6 * m::kHistoryLength : 1];
int16_t plays[m::kPlayCount ? 6 * m::kPlayCount : 1];
r::State state = {wrench_ring, count_ring, plays, 0, 1, false};

}  // namespace

void setup() {
    bench::paint_stack();
    Serial.begin(DELTA6_BENCH_BAUD);
    r::configure(m::kModel, state, DELTA6_BENCH_RATE_HZ);
    const uint32_t hash = m::kHash;
    const uint16_t samples = DELTA6_BENCH_SAMPLES;
    const uint16_t rate = DELTA6_BENCH_RATE_HZ;
    bench::send_header('I');
    send(&hash, sizeof hash);
    send(&samples, sizeof samples);
    send(&rate, sizeof rate);
    send(&state.stride, 1);
    uint8_t sreg = SREG;
    cli();
    mark(3);
    mark(4);
    SREG = sreg;
    int16_t base[6] = {0, 0, 0, 0, 0, 0};
    int16_t counts[6] = {0, 0, 0, 0, 0, 0};
    for (uint16_t i = 0; i < DELTA6_BENCH_SAMPLES; ++i) {
        for (uint8_t j = 0; j < 6; ++j) {
            base[j] = walk(base[j], 10, 30000);
            counts[j] = walk(counts[j], 4, 1400);
        }
        const uint8_t valid = (next_random() & 63u) != 0;
        int16_t correction[6] = {0, 0, 0, 0, 0, 0};
        if (valid) {
            sreg = SREG;
            cli();
            mark(1);
            r::step(m::kModel, state, base, counts, correction);
            mark(2);
            SREG = sreg;
        } else {
            r::reset(state);
        }
        bench::send_header('S');
        send(&valid, 1);
        send(correction, sizeof correction);
        Serial.flush();
    }
    const uint16_t peak = bench::peak_stack_bytes();
    const uint16_t ram = static_cast<uint16_t>(reinterpret_cast<uint16_t>(&__bss_end) - RAMSTART);
    bench::send_header('E');
    send(&peak, sizeof peak);
    send(&ram, sizeof ram);
    Serial.flush();
    mark(0xFF);
}

void loop() {}
