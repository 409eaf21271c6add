// The calibrated model on the chip: the analytical model with a unit's calibration applied,
// causally, in one pass per sample (docs/calibration.md). It computes what the Python
// reference delta6.core.calibrated computes, in float32:
//
//   1. history of each joint's count x: the direction of motion d (a play of +-H/2 counts),
//      hysteresis plays of whole-count radii, the filtered joint speed v;
//   2. angle side: theta = x * count - offset + half_play * d;
//   3. torque: tau = rate * theta + sum_r w_r (x - play_r) + sum_s c_s clamp(v / V_s, -1, 1)
//      + viscous * v + presliding * d;
//   4. per-branch geometry (a - b, la, lb, azimuth, rest angle) and the elbow's turn
//      elbow * tau: the trig tables give the nominal angle, a small rotation adds the rest;
//   5. general trilateration and statics, then the gimbal: F_E0 = F - w x F with
//      w = gimbal + tilt * (moment about the platform centre); eq. (12).
//
// The constants come from `delta6 codegen --calibration` (generated/delta6_calibration.h,
// kCalibrationConstants, stored in flash on the AVR); the state is a few bytes per joint.
// Portable C++14: no Arduino headers, no heap, no STL.
#ifndef DELTA6_CALIBRATED_H
#define DELTA6_CALIBRATED_H

#include <stdint.h>

#include "delta6_solver.h"

namespace delta6 {

constexpr uint8_t kMaxPlayRadii = 4;
constexpr uint8_t kMaxSignSpeeds = 4;
// Bumped whenever CalibrationConstants changes shape; the generated header checks it.
constexpr uint16_t kCalibrationConstantsVersion = 1;

struct CalibrationConstants {
    // Angle side, joints 1..6.
    float offset[6];                   // rad: encoder reading minus true angle
    float half_play[6];                // rad: half the backlash
    int16_t direction_half;            // H, half counts: the direction play's radius
    float direction_scale;             // 1 / H
    // Torque, joints 1..6.
    float rate[6];                     // k * rate ratio, N*m/rad
    uint8_t radii;                     // hysteresis plays in use (<= kMaxPlayRadii)
    int16_t radius[kMaxPlayRadii];     // counts
    float hysteresis[6][kMaxPlayRadii];  // weight / radius: N*m per count of (x - play)
    float speed_tau;                   // s: the speed filter's time constant
    uint8_t speeds;                    // saturated signs in use (<= kMaxSignSpeeds)
    float inv_speed[kMaxSignSpeeds];   // 1 / V_s, s/rad
    float sign[6][kMaxSignSpeeds];     // N*m
    float viscous[6];                  // N*m*s/rad
    float presliding[6];               // N*m
    // Geometry, branches 1..3.
    float ux[3], uy[3];                // cos, sin of each branch's azimuth
    float d[3];                        // a_i - b_i, m
    float la_scale[3];                 // la_i / la: the branch table holds la cos, la sin
    float rest[3];                     // rad added to the branch angle (rest-angle error)
    float lb_sq[3];                    // lb_i^2, m^2
    float half_dlb_sq[3];              // (lb_i^2 - lb_1^2) / 2, m^2
    float elbow[3];                    // rad per N*m of the joint's torque
    float gimbal[3];                   // rad: rotation vector of {E0} in {B}
    float tilt;                        // rad per N*m about the platform centre
    float c;                           // m: {E} below the platform centre
    float min_det;                     // lower bound on the trilateration determinant, m^2
};

// The history kept between samples (what the Python model calls ModelState).
struct CalibrationState {
    uint8_t started;                   // 0: the next sample starts settled
    int16_t last[6];                   // the previous count
    int16_t direction2[6];             // direction play, half counts
    int16_t play[6][kMaxPlayRadii];    // hysteresis plays, counts
    float speed[6];                    // rad/s
    float speed_a, speed_g;            // v = a v + g (x - last): from the sample period
};

// Forget the history: the next sample starts settled (after a zero change or a gap).
void calibration_reset(CalibrationState& s);
// The speed filter's coefficients for a sample period (call when the rate changes).
void calibration_set_period(const CalibrationConstants& c, float period_s,
                            CalibrationState& s);
// One sample: signed count deltas in, the calibrated wrench out (statuses as solve_counts;
// any non-zero status leaves all six outputs 0.0f). The history advances with every call.
uint8_t solve_calibrated(const SolverConstants& k, const CalibrationConstants& c,
                         CalibrationState& s, const int16_t delta[6], float wrench[6]);

}  // namespace delta6

#endif  // DELTA6_CALIBRATED_H
