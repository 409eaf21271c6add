// Solver benchmark and self-check sketch: runs delta6::solve_counts over a fixed, spread-out
// set of encoder deltas inside (and at the corners of) the design's joint box and reports
// every input, status and wrench over the serial port, so a host can check what the AVR
// computed against the Python reference. tools/bench_solver_avr.py runs it in simavr.
//
// Timing: each solve is bracketed by writes of 1 and 2 to GPIOR0 with interrupts off; the
// simulator timestamps those writes (tools/simavr/delta6_sim.c). After the last frame the
// sketch writes 0xFF to GPIOR0 (end of run) and idles.
//
// Frame per solve, little-endian: 0xD6 0x5A, int16 delta[6], uint8 status, float wrench[6].
#include <Arduino.h>

#include "delta6_solver.h"
#include "generated/delta6_design.h"

#ifndef DELTA6_BENCH_SOLVES
#define DELTA6_BENCH_SOLVES 512
#endif
#ifndef DELTA6_BENCH_BAUD
#define DELTA6_BENCH_BAUD 115200
#endif

namespace {

constexpr uint8_t kMarkStart = 1;
constexpr uint8_t kMarkStop = 2;
constexpr uint8_t kMarkCalibrateStart = 3;
constexpr uint8_t kMarkCalibrateStop = 4;
constexpr uint8_t kMarkEnd = 0xFF;

// The memory clobbers keep the compiler from moving the solver's loads and stores (and so
// its work, which sits between them) across a marker.
inline void mark(uint8_t value) {
    asm volatile("" ::: "memory");
#ifdef GPIOR0
    GPIOR0 = value;
#else
    (void)value;
#endif
    asm volatile("" ::: "memory");
}

uint16_t lcg_state = 0xACE1u;

// Uniform-ish in [-limit, limit] from a 16-bit xorshift (deterministic run to run).
int16_t random_delta(int16_t limit) {
    lcg_state ^= static_cast<uint16_t>(lcg_state << 7);
    lcg_state ^= static_cast<uint16_t>(lcg_state >> 9);
    lcg_state ^= static_cast<uint16_t>(lcg_state << 8);
    const uint32_t span = 2u * static_cast<uint32_t>(limit) + 1u;
    return static_cast<int16_t>(static_cast<int32_t>((lcg_state * span) >> 16) - limit);
}

// Case i: 0 = rest, 1..64 = the 64 corners of the box, then random points.
void make_case(uint16_t i, int16_t delta[6]) {
    const int16_t limit = delta6::design::kJointLimitCounts;
    for (uint8_t j = 0; j < 6; ++j) {
        if (i == 0) {
            delta[j] = 0;
        } else if (i <= 64) {
            delta[j] = ((i - 1) >> j) & 1 ? limit : static_cast<int16_t>(-limit);
        } else {
            delta[j] = random_delta(limit);
        }
    }
}

void send_frame(const int16_t delta[6], uint8_t status, const float wrench[6]) {
    const uint8_t sync[2] = {0xD6, 0x5A};
    Serial.write(sync, sizeof sync);
    Serial.write(reinterpret_cast<const uint8_t*>(delta), 6 * sizeof(int16_t));
    Serial.write(status);
    Serial.write(reinterpret_cast<const uint8_t*>(wrench), 6 * sizeof(float));
    Serial.flush();  // nothing may interrupt the next timed solve
}

}  // namespace

void setup() {
    Serial.begin(DELTA6_BENCH_BAUD);
    uint8_t sreg = SREG;
    cli();
    mark(kMarkCalibrateStart);
    mark(kMarkCalibrateStop);
    SREG = sreg;
    for (uint16_t i = 0; i < DELTA6_BENCH_SOLVES; ++i) {
        int16_t delta[6];
        float wrench[6];
        make_case(i, delta);
        sreg = SREG;
        cli();
        mark(kMarkStart);
        const uint8_t status = delta6::solve_counts(delta6::design::kSolverConstants, delta, wrench);
        mark(kMarkStop);
        SREG = sreg;
        send_frame(delta, status, wrench);
    }
    mark(kMarkEnd);
}

void loop() {}
