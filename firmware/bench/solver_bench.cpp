// Solver benchmark and self-check sketch: runs delta6::solve_counts over a fixed, spread-out
// set of encoder deltas in the design's joint box (rest, the 64 corners, then pseudo-random
// points) and reports every input, status and wrench over the serial port, so a host can
// check what the AVR computed against the Python reference (tools/bench_solver_avr.py runs
// it in simavr; delta6.sim.solverbench decodes it). Built with DELTA6_BENCH_CALIBRATED (and a
// generated/delta6_calibration.h) it runs delta6::solve_calibrated along a random walk instead.
//
// Timing: each solve is bracketed by writes of 1 and 2 to GPIOR0 with interrupts off; the
// simulator timestamps those writes (tools/simavr/delta6_sim.c). A 3/4 pair measures the
// cost of the markers themselves. After the last frame the sketch writes 0xFF (end of run).
//
// Frames, little-endian, each starting with 0xD6 and a type byte:
//   'I'  uint32 design hash, uint16 number of solves, char name[24]      (first)
//   'S'  int16 delta[6], uint8 status, float wrench[6]                  (one per solve)
//   'E'  uint16 peak stack bytes (high-water mark), uint16 static RAM   (last)
#include <Arduino.h>
#include <string.h>

#include "bench_support.h"
#include "delta6_solver.h"
#include "generated/delta6_design.h"
#ifdef DELTA6_BENCH_CALIBRATED
#include "delta6_calibrated.h"
#include "generated/delta6_calibration.h"
#endif

#ifndef DELTA6_BENCH_SOLVES
#define DELTA6_BENCH_SOLVES 512
#endif
#ifndef DELTA6_BENCH_BAUD
#define DELTA6_BENCH_BAUD 115200
#endif

#if defined(RAMSTART)
#define DELTA6_RAM_START RAMSTART
#else
#define DELTA6_RAM_START INTERNAL_SRAM_START  // megaAVR 0-series headers
#endif

namespace {

constexpr uint8_t kMarkStart = 1;
constexpr uint8_t kMarkStop = 2;
constexpr uint8_t kMarkCalibrateStart = 3;
constexpr uint8_t kMarkCalibrateStop = 4;
constexpr uint8_t kMarkEnd = 0xFF;

using bench::mark;
using bench::send_header;

// Uniform-ish in [-limit, limit] from a 16-bit xorshift (the same points on every run).
int16_t random_delta(int16_t limit) {
    const uint16_t r = bench::next_random();
    const uint32_t span = 2u * static_cast<uint32_t>(limit) + 1u;
    return static_cast<int16_t>(static_cast<int32_t>((r * span) >> 16) - limit);
}

#ifdef DELTA6_BENCH_CALIBRATED
// The calibrated model carries a history, so its cases are a path: rest, then a random walk
// in the box (steps of up to 6 counts, with reversals, and a jump of up to 255 counts in one
// sample of 64), sampled at 250 Hz.
constexpr float kBenchPeriodS = 0.004f;
delta6::CalibrationState calibration_state;

void make_case(uint16_t i, int16_t delta[6]) {
    const int16_t limit = delta6::design::kJointLimitCounts;
    for (uint8_t j = 0; j < 6; ++j) {
        if (i == 0) {
            delta[j] = 0;
            continue;
        }
        const int16_t jump = (i & 63u) == 0 ? 255 : 6;
        int16_t x = static_cast<int16_t>(delta[j] + random_delta(jump));
        delta[j] = x > limit ? limit : (x < -limit ? static_cast<int16_t>(-limit) : x);
    }
}

uint8_t solve(const int16_t delta[6], float wrench[6]) {
    return delta6::solve_calibrated(delta6::design::kSolverConstants,
                                    delta6::calibration::kCalibrationConstants,
                                    calibration_state, delta, wrench);
}
#else
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

uint8_t solve(const int16_t delta[6], float wrench[6]) {
    return delta6::solve_counts(delta6::design::kSolverConstants, delta, wrench);
}
#endif

void send_info() {
    char name[24];
    memset(name, 0, sizeof name);
    strncpy(name, delta6::design::kName, sizeof name - 1);
    const uint32_t hash = delta6::design::kHash;
    const uint16_t solves = DELTA6_BENCH_SOLVES;
    send_header('I');
    bench::send(&hash, sizeof hash);
    bench::send(&solves, sizeof solves);
    bench::send(name, sizeof name);
}

void send_solve(const int16_t delta[6], uint8_t status, const float wrench[6]) {
    send_header('S');
    bench::send(delta, 6 * sizeof(int16_t));
    bench::send(&status, 1);
    bench::send(wrench, 6 * sizeof(float));
    Serial.flush();  // nothing may interrupt the next timed solve
}

void send_end(uint16_t peak_stack) {
    const uint16_t static_ram = static_cast<uint16_t>(reinterpret_cast<uint16_t>(&__bss_end) -
                                                      DELTA6_RAM_START);
    send_header('E');
    bench::send(&peak_stack, sizeof peak_stack);
    bench::send(&static_ram, sizeof static_ram);
    Serial.flush();
}

}  // namespace

void setup() {
    bench::paint_stack();
    Serial.begin(DELTA6_BENCH_BAUD);
    send_info();
    uint8_t sreg = SREG;
    cli();
    mark(kMarkCalibrateStart);
    mark(kMarkCalibrateStop);
    SREG = sreg;
#ifdef DELTA6_BENCH_CALIBRATED
    delta6::calibration_reset(calibration_state);
    delta6::calibration_set_period(delta6::calibration::kCalibrationConstants, kBenchPeriodS,
                                   calibration_state);
#endif
    int16_t delta[6];
    for (uint16_t i = 0; i < DELTA6_BENCH_SOLVES; ++i) {
        float wrench[6];
        make_case(i, delta);
        sreg = SREG;
        cli();
        mark(kMarkStart);
        const uint8_t status = solve(delta, wrench);
        mark(kMarkStop);
        SREG = sreg;
        send_solve(delta, status, wrench);
    }
    send_end(bench::peak_stack_bytes());
    mark(kMarkEnd);
}

void loop() {}
