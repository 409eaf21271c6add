// Native unit tests of the portable solver core, built with -fsanitize=address,undefined by
// tests/firmware/test_solver_unit.py (C++11, like the oldest toolchain the firmware meets). Checks the
// bit-level helpers against the operations they replace, sweeps every count of every joint,
// and breaks the constants to reach each fault path. Prints one line per failure and exits
// non-zero if any.
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "delta6_fastmath.h"
#include "delta6_solver.h"
#include "generated/delta6_design.h"

namespace {

int failures = 0;

#define CHECK(cond)                                                        \
    do {                                                                   \
        if (!(cond)) {                                                     \
            ++failures;                                                    \
            if (failures < 20) printf("%s:%d: CHECK(%s)\n", __FILE__, __LINE__, #cond); \
        }                                                                  \
    } while (0)

uint32_t rng_state = 0x12345678u;
uint32_t next_random() {
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 17;
    rng_state ^= rng_state << 5;
    return rng_state;
}

float from_bits(uint32_t u) { return delta6::fastmath::float_of(u); }
uint32_t to_bits(float x) { return delta6::fastmath::bits_of(x); }

const uint32_t kSpecialBits[] = {
    0x00000000u, 0x80000000u, 0x00000001u, 0x807FFFFFu, 0x00800000u, 0x80800000u,
    0x3F800000u, 0xBF800000u, 0x7F7FFFFFu, 0xFF7FFFFFu, 0x7F800000u, 0xFF800000u,
    0x7FC00000u, 0xFFC00001u, 0x7F000000u, 0x01000000u, 0x00FFFFFFu,
};

bool all_zero(const float w[6]) {
    for (int i = 0; i < 6; ++i) {
        if (to_bits(w[i]) != 0u) return false;  // +0.0f exactly
    }
    return true;
}

bool all_finite(const float w[6]) {
    for (int i = 0; i < 6; ++i) {
        if (!isfinite(w[i])) return false;
    }
    return true;
}

void test_wrap_count_delta() {
    const uint16_t zeros[] = {0, 1, 4096, 8191, 8192, 8193, 16383};
    for (uint16_t zero : zeros) {
        for (int32_t raw = 0; raw < 16384; ++raw) {
            const int32_t expected = ((raw - zero + 8192) % 16384 + 16384) % 16384 - 8192;
            CHECK(delta6::wrap_count_delta(static_cast<uint16_t>(raw), zero) == expected);
        }
    }
}

void check_scale2(float x) {
    for (int8_t k = -2; k <= 2; ++k) {
        if (k == 0) continue;
        const float factor = k > 0 ? static_cast<float>(1 << k) : 1.0f / static_cast<float>(1 << -k);
        const float expected = x * factor;
        const float got = delta6::fastmath::scale2(x, k);
        CHECK((isnan(expected) && isnan(got)) || to_bits(expected) == to_bits(got));
    }
}

void check_predicates(float x) {
    using namespace delta6::fastmath;
    CHECK(is_finite(x) == static_cast<bool>(isfinite(x)));
    CHECK(to_bits(absf(x)) == (to_bits(x) & 0x7FFFFFFFu));
    const float bounds[] = {1e-30f, 1.4e-6f, 4.8e-5f, 3e-3f, 1.0f, 3e38f};
    for (float b : bounds) CHECK(at_least(x, b) == (x >= b && isfinite(x)));
}

void test_bit_helpers() {
    for (uint32_t u : kSpecialBits) {
        check_scale2(from_bits(u));
        check_predicates(from_bits(u));
    }
    for (int i = 0; i < 2000000; ++i) {
        const float x = from_bits(next_random());
        check_scale2(x);
        check_predicates(x);
    }
}

int16_t random_count(int16_t limit) {
    return static_cast<int16_t>(static_cast<int32_t>(next_random() % (2u * limit + 1u)) - limit);
}

void test_every_count_of_every_joint() {
    const delta6::SolverConstants& k = delta6::design::kSolverConstants;
    const int16_t lim = k.limit_counts;
    for (int joint = 0; joint < 6; ++joint) {
        for (int32_t n = -lim; n <= lim; ++n) {
            int16_t delta[6];
            for (int j = 0; j < 6; ++j) delta[j] = random_count(lim);
            delta[joint] = static_cast<int16_t>(n);
            float w[6];
            CHECK(delta6::solve_counts(k, delta, w) == delta6::kSolveOk);
            CHECK(all_finite(w));
        }
        const int16_t outside[] = {static_cast<int16_t>(lim + 1), static_cast<int16_t>(-lim - 1),
                                   32767, -32768, 8191, -8192};
        for (int16_t n : outside) {
            int16_t delta[6] = {0, 0, 0, 0, 0, 0};
            delta[joint] = n;
            float w[6] = {1, 1, 1, 1, 1, 1};
            CHECK(delta6::solve_counts(k, delta, w) == delta6::kSolveOutOfBox);
            CHECK(all_zero(w));
        }
    }
    int16_t rest[6] = {0, 0, 0, 0, 0, 0};
    float w[6];
    CHECK(delta6::solve_counts(k, rest, w) == delta6::kSolveOk);
    CHECK(all_zero(w));
}

void test_radians_special_values() {
    const delta6::SolverConstants& k = delta6::design::kSolverConstants;
    for (uint32_t u : kSpecialBits) {
        for (int joint = 0; joint < 6; ++joint) {
            float theta[6] = {0.1f, -0.2f, 0.05f, 0.3f, -0.1f, 0.2f};
            theta[joint] = from_bits(u);
            float w[6];
            const uint8_t status = delta6::solve_radians(k, theta, w);
            CHECK(all_finite(w));
            const bool inside = fabsf(theta[joint]) <= k.limit_rad;
            CHECK(status == (inside ? delta6::kSolveOk : delta6::kSolveOutOfBox));
            if (!inside) CHECK(all_zero(w));
        }
    }
}

void expect_fault(const delta6::SolverConstants& broken, uint8_t flag) {
    int16_t delta[6] = {100, -200, 300, 10, 20, -30};
    float w[6] = {1, 1, 1, 1, 1, 1};
    CHECK(delta6::solve_counts(broken, delta, w) == flag);
    CHECK(all_zero(w));
    const float theta[6] = {0.1f, -0.2f, 0.05f, 0.3f, -0.1f, 0.2f};
    float v[6] = {1, 1, 1, 1, 1, 1};
    CHECK(delta6::solve_radians(broken, theta, v) == flag);
    CHECK(all_zero(v));
}

void test_fault_paths() {
    delta6::SolverConstants broken = delta6::design::kSolverConstants;
    broken.lb_sq = 1e-6f;  // 1 mm links: cannot close
    expect_fault(broken, delta6::kSolveNoSolution);
    broken = delta6::design::kSolverConstants;
    broken.min_height_sq = 1.0f;  // demand a 1 m height
    expect_fault(broken, delta6::kSolveNoSolution);
    broken = delta6::design::kSolverConstants;
    broken.min_lever = 1.0f;
    expect_fault(broken, delta6::kSolveSingular);
    broken = delta6::design::kSolverConstants;
    broken.min_area = 1.0f;
    expect_fault(broken, delta6::kSolveSingular);
    broken = delta6::design::kSolverConstants;
    broken.d = -broken.la;  // elbow centres through the axis: S can vanish
    for (int i = 0; i < 2000; ++i) {
        int16_t delta[6];
        for (int j = 0; j < 6; ++j) delta[j] = random_count(broken.limit_counts);
        float w[6];
        const uint8_t status = delta6::solve_counts(broken, delta, w);
        CHECK(all_finite(w));
        if (status != delta6::kSolveOk) CHECK(all_zero(w));
    }
}

}  // namespace

int main() {
    test_wrap_count_delta();
    test_bit_helpers();
    test_every_count_of_every_joint();
    test_radians_special_values();
    test_fault_paths();
    if (failures) {
        printf("%d check(s) failed\n", failures);
        return 1;
    }
    printf("all passed\n");
    return 0;
}
