// C ABI over the firmware solver for the ctypes tests (tests/firmware/test_solver_native.py).
// Compiled by host g++ together with delta6_solver.cpp and one design's generated header.
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "delta6_fastmath.h"
#include "delta6_solver.h"
#include "generated/delta6_design.h"

using delta6::SolverConstants;

namespace {
const SolverConstants& pick(const SolverConstants* c) {
    return c ? *c : delta6::design::kSolverConstants;
}
}  // namespace

extern "C" {

size_t d6_constants_size() { return sizeof(SolverConstants); }

// n solves; constants NULL means the generated design's.
void d6_solve_counts(const SolverConstants* c, size_t n, const int16_t* delta, float* wrench,
                     uint8_t* status) {
    for (size_t i = 0; i < n; ++i) {
        status[i] = delta6::solve_counts(pick(c), delta + 6 * i, wrench + 6 * i);
    }
}

void d6_solve_radians(const SolverConstants* c, size_t n, const float* theta, float* wrench,
                      uint8_t* status) {
    for (size_t i = 0; i < n; ++i) {
        status[i] = delta6::solve_radians(pick(c), theta + 6 * i, wrench + 6 * i);
    }
}

// The table trigonometry alone (branch = 1: la cos/sin(theta_offset + q), else cos/sin q),
// for the exhaustive check over every count of the joint box.
void d6_table_trig(int branch, size_t n, const int16_t* delta, float* c, float* s) {
    const SolverConstants& k = delta6::design::kSolverConstants;
    for (size_t i = 0; i < n; ++i) {
        const uint16_t biased = static_cast<uint16_t>(delta[i] + k.table_origin);
        delta6::fastmath::table_cos_sin(branch ? k.branch_table : k.joint_table, k.fine_table,
                                        biased, c + i, s + i);
    }
}

int16_t d6_wrap_count_delta(uint16_t raw, uint16_t zero) {
    return delta6::wrap_count_delta(raw, zero);
}

// The generated header's own values, to check them against the Python side.
uint32_t d6_design_hash() { return delta6::design::kHash; }
void d6_design_name(char* out, size_t size) {
    strncpy(out, delta6::design::kName, size);
    out[size - 1] = '\0';
}
void d6_design_full_scale(float* out) {
    for (int i = 0; i < 6; ++i) out[i] = delta6::design::kFullScale[i];
}
int16_t d6_design_limit_counts() { return delta6::design::kJointLimitCounts; }
float d6_design_limit_rad() { return delta6::design::kJointLimitRad; }
}
