// The calibrated model on the chip: the analytical model with a unit's calibration applied,
// causally, in one pass per sample (docs/calibration.md). It computes what the Python
// reference delta6.core.calibrated computes, in float32:
//
//   1. history of each joint's count x: the direction of motion d (a play of +-H/2 counts),
//      hysteresis plays of whole-count radii, the filtered joint speed v;
//   2. angle side: theta = x * count - offset - e(x) + half_play * d;
//   3. torque: tau = rate * theta + s(x) + sum_r w_r (x - play_r)
//      + sum_s c_s clamp(v / V_s, -1, 1) + viscous * v + presliding * d;
//      (e, s: the encoder's periodic error and the spring's curve, tables over x, only in a
//      calibration that has them: CurvedCalibrationConstants);
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
// The torque's count terms are summed in int32, in units of 2^-kTorqueShift N*m.
constexpr uint8_t kTorqueShift = 28;
// Bumped whenever CalibrationConstants changes shape; the generated header checks it.
constexpr uint16_t kCalibrationConstantsVersion = 6;

struct CalibrationConstants {
    // Torque of joint j, with x its count, y_r its plays and y2 its direction play (half
    // counts): tau = (kx x + sum_r kw_r (x - y_r) + kd (2x - y2) + k0) 2^-kTorqueShift
    // + friction(v).
    int32_t kx[6];                     // k * ratio * count
    int32_t kw[6][kMaxPlayRadii];      // hysteresis weight / radius
    int32_t kd[6];                     // (k * ratio * half_play + presliding) / H
    int32_t k0[6];                     // -k * ratio * offset
    int16_t direction_half;            // H, half counts: the direction play's radius
    uint8_t radii;                     // hysteresis plays in use (<= kMaxPlayRadii)
    int16_t radius[kMaxPlayRadii];     // counts
    float speed_tau;                   // s: the speed filter's time constant
    // Friction, a piecewise-linear odd function of the speed v (the sum of the saturated signs
    // and the viscous term): on the segment k of |v| (k breakpoints at or below it),
    // slope[k] v + offset[k] 2^-kTorqueShift sign(v).
    uint8_t speeds;                    // breakpoints in use (<= kMaxSignSpeeds)
    float breakpoint[kMaxSignSpeeds];  // the sign speeds V_s, ascending, rad/s
    float slope[6][kMaxSignSpeeds + 1];   // N*m*s/rad
    int32_t offset[6][kMaxSignSpeeds + 1];
    // The friction is known up to the speeds its calibration run reached: |v| is held
    // within speed_limit (rad/s; 1e30 where the calibration sets none).
    float speed_limit[6];
    // ... at the speed led by speed_lead s of its filtered acceleration (0: no lead, and no
    // cycles spent on it): the filtered speed lags the true one where the friction switches.
    float speed_lead;
    // The angles: the coarse tables (flash, as the solver's) hold each joint's constant
    // correction (branches: la_i and the rest angle; all: minus the encoder offset); the part
    // that varies is ed (2x - y2) (backlash), plus elbow * tau on the branches (compliance).
    const float* table[6];
    float ed[6];                       // half_play / H, rad per half count
    float eh[6];                       // half_play, rad: ed H
    float elbow[3];                    // rad per N*m of the joint's torque
    // Geometry, branches 1..3.
    float ux[3], uy[3];                // cos, sin of each branch's azimuth
    float d[3];                        // a_i - b_i, m
    float lb_sq[3];                    // lb_i^2, m^2
    float half_dlb_sq[3];              // (lb_i^2 - lb_1^2) / 2, m^2
    float gimbal[3];                   // rad: rotation vector of {E0} in {B}
    float tilt;                        // rad per N*m about the platform centre
    float c;                           // m: {E} below the platform centre
    float min_det;                     // lower bound on the trilateration determinant, m^2
};

// Steps of the count (either sign) whose speed-filter term g * step is kept in the state.
constexpr uint8_t kSpeedSteps = 8;

// The history kept between samples (what the Python model calls ModelState).
struct CalibrationState {
    uint8_t started;                   // 0: the next sample starts settled
    uint8_t after_gap;                 // periods were lost since the last sample solved
    int16_t last[6];                   // the previous count
    int16_t direction2[6];             // direction play, half counts
    int16_t play[6][kMaxPlayRadii];    // hysteresis plays, counts
    // The torque's count terms, kx x + kd (2x - y2) + sum_r kw_r (x - y_r) + k0, kept up to
    // date by their changes (wrapping int32: the same value as the sum itself).
    int32_t count_sum[6];
    float speed[6];                    // rad/s
    float speed_a, speed_g;            // v = a v + g (x - last): from the sample period
    float lead[6];                     // rad/s: speed_lead x the filtered acceleration
    float lead_a, lead_k;              // lead = a lead + k (v - v_before); k = 0: no lead
    float speed_step[kSpeedSteps];     // g * k for k = 1..kSpeedSteps (the same products)
};

// A calibration with per-joint curves (delta6.core.curves): int16 tables at the knots
// x_i = i * kTableStep - table_origin (the rows of the coarse trig tables, and one beyond),
// interpolated linearly over the count x, held at the end knots outside. The encoder error at
// each knot is already in the coarse trig table of its row; the board adds the part between
// knots, summed with the backlash angle in fixed point (2^-kCurveTurnShift rad). A separate
// struct, so that a calibration without curves compiles to the code it has without them.
constexpr uint8_t kCurveAngleShift = 19;    // angle tables: 2^-19 rad
constexpr uint8_t kCurveTorqueShift = 16;   // torque tables: 2^-16 N*m
constexpr uint8_t kCurveTurnShift = 31;     // the angle's varying part: 2^-31 rad
constexpr uint16_t kCalibrationCurvesVersion = 2;

struct CurvedCalibrationConstants {
    CalibrationConstants base;
    uint8_t knots;                     // table entries per joint
    const int16_t* torque[6];          // s(x) - k ratio e(x), 2^-kCurveTorqueShift N*m
    const int16_t* angle[6];           // e(x), 2^-kCurveAngleShift rad; null: no encoder curve
    int32_t ed[6];                     // base.ed in 2^-kCurveTurnShift rad per half count
    int32_t eh[6];                     // base.eh in 2^-kCurveTurnShift rad
};

// Forget the history: the next sample starts settled (after a zero change).
void calibration_reset(CalibrationState& s);
// A period passed without a sample solved (a failed read, a missed period): the next sample's
// count step spans more than one period, so it is no speed (read as one period's step it was a
// spike): the speed decays for that sample as if the joint stood still; the plays and the
// count terms take the whole step, as they depend on the position only.
inline void calibration_gap(CalibrationState& s) { s.after_gap = 1; }
// The speed filter's coefficients for a sample period (call when the rate changes).
void calibration_set_period(const CalibrationConstants& c, float period_s,
                            CalibrationState& s);
// One sample: signed count deltas in, the calibrated wrench out (statuses as solve_counts;
// any non-zero status leaves all six outputs 0.0f). The history advances with every call.
uint8_t solve_calibrated(const SolverConstants& k, const CalibrationConstants& c,
                         CalibrationState& s, const int16_t delta[6], float wrench[6]);

// The same with the curves (the overload the generated header's constants select).
inline void calibration_set_period(const CurvedCalibrationConstants& c, float period_s,
                                   CalibrationState& s) {
    calibration_set_period(c.base, period_s, s);
}
uint8_t solve_calibrated(const SolverConstants& k, const CurvedCalibrationConstants& c,
                         CalibrationState& s, const int16_t delta[6], float wrench[6]);

}  // namespace delta6

#endif  // DELTA6_CALIBRATED_H
