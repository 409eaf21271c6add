// C ABI over the calibrated model for the ctypes tests (delta6.build.nativecalibrated).
// Compiled by host g++ with delta6_calibrated.cpp, the solver and one design's header.
#include <stddef.h>
#include <stdint.h>

#include "delta6_calibrated.h"
#include "delta6_solver.h"
#include "generated/delta6_design.h"
#if __has_include("generated/delta6_calibration.h")
#include "generated/delta6_calibration.h"
#define D6C_HAS_GENERATED 1
#endif

using delta6::CalibrationConstants;
using delta6::CalibrationState;
using delta6::CurvedCalibrationConstants;

namespace {
// n samples, continuing from *s; periods[i] (NULL: all 1) sample periods since the sample
// before (more than 1: the board lost the periods between, as after a failed read).
template <typename Constants>
void run(const Constants* c, CalibrationState* s, size_t n, const int16_t* delta,
         const uint16_t* periods, float* wrench, uint8_t* status) {
    for (size_t i = 0; i < n; ++i) {
        if (periods != nullptr && periods[i] > 1) delta6::calibration_gap(*s);
        status[i] = delta6::solve_calibrated(delta6::design::kSolverConstants, *c, *s,
                                             delta + 6 * i, wrench + 6 * i);
    }
}
}  // namespace

extern "C" {

// The generated header's constants (NULL when the build has none; the base of a calibration
// with curves), its curves (NULL without), its hash and name.
const CalibrationConstants* d6c_generated() {
#if defined(DELTA6_CALIBRATION_CURVES)
    return &delta6::calibration::kCalibrationConstants.base;
#elif defined(D6C_HAS_GENERATED)
    return &delta6::calibration::kCalibrationConstants;
#else
    return nullptr;
#endif
}
const CurvedCalibrationConstants* d6c_generated_curved() {
#if defined(DELTA6_CALIBRATION_CURVES)
    return &delta6::calibration::kCalibrationConstants;
#else
    return nullptr;
#endif
}
uint32_t d6c_generated_hash() {
#ifdef D6C_HAS_GENERATED
    return delta6::calibration::kHash;
#else
    return 0;
#endif
}

size_t d6c_constants_size() { return sizeof(CalibrationConstants); }
size_t d6c_curved_size() { return sizeof(CurvedCalibrationConstants); }
size_t d6c_state_size() { return sizeof(CalibrationState); }

void d6c_reset(CalibrationState* s) { delta6::calibration_reset(*s); }

void d6c_set_period(const CalibrationConstants* c, float period_s, CalibrationState* s) {
    delta6::calibration_set_period(*c, period_s, *s);
}

// n samples, continuing from *s (periods: see run above).
void d6c_run(const CalibrationConstants* c, CalibrationState* s, size_t n, const int16_t* delta,
             const uint16_t* periods, float* wrench, uint8_t* status) {
    run(c, s, n, delta, periods, wrench, status);
}

// The same with curves.
void d6c_run_curved(const CurvedCalibrationConstants* c, CalibrationState* s, size_t n,
                    const int16_t* delta, const uint16_t* periods, float* wrench,
                    uint8_t* status) {
    run(c, s, n, delta, periods, wrench, status);
}
}
