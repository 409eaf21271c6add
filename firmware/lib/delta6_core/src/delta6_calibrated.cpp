// The calibrated model; see delta6_calibrated.h. Constants live in flash on the AVR, so every
// read goes through the fastmath flash helpers.
#include "delta6_calibrated.h"

#include "delta6_fastmath.h"
#include "delta6_flash.h"

#if defined(__AVR__)
#include <avr/pgmspace.h>
#endif

// Stage markers for a cycle profile (as in delta6_solver.cpp): only a profile build defines
// DELTA6_SOLVER_PROFILE and provides the hook header; elsewhere they vanish.
#ifdef DELTA6_SOLVER_PROFILE
#include "delta6_solver_profile_hooks.h"
#else
#define DELTA6_PROFILE_MARK(stage) ((void)0)
#endif

// The stages are separate functions (see below); the attribute keeps LTO from merging them.
#if defined(__GNUC__)
#define DELTA6_NOINLINE __attribute__((noinline))
#define DELTA6_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define DELTA6_NOINLINE
#define DELTA6_ALWAYS_INLINE inline
#endif
#if defined(__AVR__)
#define DELTA6_FOR_SIZE __attribute__((optimize("Os")))
#else
#define DELTA6_FOR_SIZE
#endif
// -O2 for this file on the AVR (the image is built -Os): about 1,000 cycles less per sample
// for about 800 bytes of flash. Not in an image with an on-chip residual too (its generated
// header next to the design's, as the application includes it): that image fills the
// ATmega328P's 32 KB and runs at 200 Hz, where the cycles are not needed.
#if defined(__AVR__)
#if defined(__has_include)
#if !__has_include("generated/delta6_model.h")
#pragma GCC optimize("O2")
#endif
#else
#pragma GCC optimize("O2")
#endif
#endif

namespace delta6 {
namespace {

using fastmath::absf;
using fastmath::flash_float;
using fastmath::rotate_back;

// One encoder count, rad: 2 pi (float) over the counts of a turn (a power of two: exact).
constexpr float kCountRad = 6.28318531f / static_cast<float>(kCountsPerTurn);
static_assert(kCountRad == 3.83495197e-4f, "one count is 2 pi / 2^14 rad");

inline int16_t clamp_play(int16_t y, int16_t x, int16_t r) {
    const int16_t lo = static_cast<int16_t>(x - r), hi = static_cast<int16_t>(x + r);
    return y < lo ? lo : (y > hi ? hi : y);
}

// x * 2^-k for a float converted from a non-zero int32 (normal, exponent >= 127): subtracts k
// from the exponent field instead of calling the float multiply.
inline float scale_down(float x, uint8_t k) {
    if (fastmath::bits_of(x) == 0) return x;
    return fastmath::float_of(fastmath::bits_of(x) - (static_cast<uint32_t>(k) << 23));
}

// a + b and a * b modulo 2^32: the count terms' sum is kept by its changes, whose
// intermediate products may leave the int32 range although the sum itself never does.
inline int32_t wrapping_add(int32_t a, int32_t b) {
    return static_cast<int32_t>(static_cast<uint32_t>(a) + static_cast<uint32_t>(b));
}
inline int32_t wrapping_mul(int32_t a, int16_t b) {
    return static_cast<int32_t>(static_cast<uint32_t>(a) *
                                static_cast<uint32_t>(static_cast<int32_t>(b)));
}

inline bool negative(float x) { return (fastmath::bits_of(x) & 0x80000000ul) != 0; }

uint8_t fail(uint8_t status, float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) wrench[i] = 0.0f;
    return status;
}

// A pointer stored in flash to an int16 table (16 bits on the AVR).
inline const int16_t* flash_i16_table(const int16_t* const* p) {
#if defined(__AVR__)
    return reinterpret_cast<const int16_t*>(pgm_read_word(p));
#else
    return *p;
#endif
}

// The knot interval of the count biased = x + origin, clamped to the tables: knot i and the
// weight L of knot i + 1 in 2^-12 (0..4096; the count's 64ths, times 64).
struct KnotSpan {
    uint8_t i;
    int16_t weight;
};

inline KnotSpan knot_span(const CurvedCalibrationConstants* cv, int16_t b) {
    const uint8_t last = static_cast<uint8_t>(flash::byte(&cv->knots) - 1);
    KnotSpan k = {0, 0};
    if (b > 0) {
        if (static_cast<uint16_t>(b) >= static_cast<uint16_t>(last) << 6) {
            k.i = static_cast<uint8_t>(last - 1);
            k.weight = 4096;
        } else {
            k.i = static_cast<uint8_t>(static_cast<uint16_t>(b << 2) >> 8);
            k.weight = static_cast<int16_t>(static_cast<uint16_t>(b & 63) << 6);
        }
    }
    return k;
}

// The curve tables' joint torque at count x, 2^-kTorqueShift N*m: linear between the knots
// i and i + 1 around x + origin (kTableStep apart), held at the end knots outside:
// t_i (4096 - L) + t_(i+1) L in 2^-(kCurveTorqueShift + 12) N*m, the sum's unit (two 16-bit
// by 16-bit products, no shifts of 32-bit values).
static_assert(kTorqueShift == kCurveTorqueShift + 12, "the curve's products are in 2^-28 N*m");
inline int32_t curve_torque(const CurvedCalibrationConstants* cv, uint8_t j, int16_t x,
                            int16_t origin) {
    const int16_t* t = flash_i16_table(&cv->torque[j]);
    const KnotSpan k = knot_span(cv, static_cast<int16_t>(x + origin));
    return static_cast<int32_t>(flash::i16(t + k.i)) * static_cast<int16_t>(4096 - k.weight)
           + static_cast<int32_t>(flash::i16(t + k.i + 1)) * k.weight;
}

// The encoder error beyond knot i of the count biased = x + origin (inside the box), in
// 2^-kCurveTurnShift rad: (e_(i+1) - e_i) L, L the weight of knot i + 1 in 2^-12.
// Codegen keeps neighbouring knots within an int16 of each other.
static_assert(kCurveTurnShift == kCurveAngleShift + 12, "the curve's turn is in 2^-31 rad");
inline int32_t curve_angle_between_knots(const CurvedCalibrationConstants* cv, uint8_t j,
                                         uint16_t biased) {
    const int16_t* a = flash_i16_table(&cv->angle[j]);
    if (a == nullptr) return 0;
    const uint8_t i = static_cast<uint8_t>(static_cast<uint16_t>(biased << 2) >> 8);
    const int16_t weight = static_cast<int16_t>(static_cast<uint16_t>(biased & 63u) << 6);
    return static_cast<int32_t>(static_cast<int16_t>(flash::i16(a + i + 1) - flash::i16(a + i)))
           * weight;
}

// The stages below are separate functions on purpose: inlined into one, the AVR build runs
// out of registers and reaches most of its values through a frame larger than the 64 bytes
// a single load or store can address (two extra instructions around each access).

// 1-3: the history, the joint torques (the count terms, the constant and the friction
// offset summed in int32) and the varying part of each angle's correction (dir2 = 2x - y2,
// the direction of motion in half counts).
// With kCurves, the spring's and the encoder error's torque from the curve tables joins the
// int32 sum (computed before the box check: the index is clamped to the tables).
template <bool kCurves>
DELTA6_NOINLINE void joint_torques(const CalibrationConstants& cc, CalibrationState& st,
                                   const int16_t delta[6], float tau[6], int16_t dir2[6],
                                   const CurvedCalibrationConstants* cv, int16_t origin) {
    const uint8_t radii = flash::byte(&cc.radii);
    const uint8_t speeds = flash::byte(&cc.speeds);
    const int16_t half = flash::i16(&cc.direction_half);
    const float speed_a = st.speed_a, speed_g = st.speed_g;
    const float lead_a = st.lead_a, lead_k = st.lead_k;
    const bool led = (fastmath::bits_of(lead_k) & 0x7FFFFFFFul) != 0;
    const bool after_gap = st.after_gap != 0;   // this sample's step is no speed
    for (uint8_t j = 0; j < 6; ++j) {
        const int16_t x = delta[j];
        const int16_t x2 = static_cast<int16_t>(2 * x);
        const int16_t step = static_cast<int16_t>(x - st.last[j]);
        int16_t y2 = st.direction2[j];
        // The count terms change by their coefficients times the changes of x - y_r and of
        // 2x - y2: every play that stood still changes with x, so their coefficients are
        // summed and take one multiply; a play that moved with x changes nothing; only a play
        // that moved part of the step (a reversal inside it) takes a multiply of its own. A
        // joint standing still moves no play: its sum stands.
        if (step != 0) {
            const int16_t last = st.last[j];
            int32_t sum = st.count_sum[j];
            int32_t k = flash::i32(&cc.kx[j]);
            const int32_t kd = flash::i32(&cc.kd[j]);
            const int16_t y2_new = clamp_play(y2, x2, half);
            if (y2_new == y2) {
                k = wrapping_add(k, wrapping_add(kd, kd));
            } else {
                // 2x - y2 before and after, both within the play's radius.
                const int16_t change = static_cast<int16_t>(
                    static_cast<int16_t>(x2 - y2_new)
                    - static_cast<int16_t>(static_cast<int16_t>(2 * last) - y2));
                if (change != 0) sum = wrapping_add(sum, wrapping_mul(kd, change));
                y2 = y2_new;
                st.direction2[j] = y2;
            }
            int16_t* play = st.play[j];
            const int32_t* kw = cc.kw[j];
            for (uint8_t r = 0; r < radii; ++r) {
                const int16_t y = play[r];
                const int16_t y_new = clamp_play(y, x, flash::i16(&cc.radius[r]));
                if (y_new == y) {
                    k = wrapping_add(k, flash::i32(&kw[r]));
                } else {
                    const int16_t change = static_cast<int16_t>(
                        static_cast<int16_t>(x - y_new) - static_cast<int16_t>(last - y));
                    if (change != 0) {
                        sum = wrapping_add(sum, wrapping_mul(flash::i32(&kw[r]), change));
                    }
                    play[r] = y_new;
                }
            }
            st.count_sum[j] = wrapping_add(sum, wrapping_mul(k, step));
        }
        const int16_t d2 = static_cast<int16_t>(x2 - y2);
        dir2[j] = d2;
        int32_t sum = st.count_sum[j];
        // Wrapping, like the count sum: a count outside the joint box may overflow int32 before
        // the box check refuses the sample (signed overflow would be undefined).
        if (kCurves) sum = wrapping_add(sum, curve_torque(cv, j, x, origin));
        // A joint standing still (often, at the board's rates) costs one multiply, not three;
        // a step of a few counts, one multiply and one addition: g times the step comes from
        // the state's table (the same float product, computed when the period was set).
        const float before = st.speed[j];
        float v = speed_a * before;
        if (step != 0 && !after_gap) {
            const uint16_t size = static_cast<uint16_t>(step < 0 ? -step : step);
            const float g = size <= kSpeedSteps ? st.speed_step[size - 1]
                                                : speed_g * static_cast<float>(size);
            v = step < 0 ? v - g : v + g;
        }
        st.speed[j] = v;
        st.last[j] = x;
        if (led) {
            // The friction's speed: v led by its filtered acceleration (two multiplies).
            const float w = lead_a * st.lead[j] + lead_k * (v - before);
            st.lead[j] = w;
            v += w;
        }
        // Friction: at the speed held within the calibration's limit, the segment of |v|
        // among the breakpoints; its offset joins the int32 sum, its slope takes one multiply.
        float av = absf(v);
        const float limit = flash_float(&cc.speed_limit[j]);
        if (fastmath::at_least(av, limit)) av = limit;
        const float vf = negative(v) ? -av : av;
        uint8_t seg = 0;
        while (seg < speeds && fastmath::at_least(av, flash_float(&cc.breakpoint[seg]))) ++seg;
        const int32_t off = flash::i32(&cc.offset[j][seg]);
        sum = wrapping_add(sum, negative(v) ? -off : off);
        tau[j] = scale_down(static_cast<float>(sum), kTorqueShift)
                 + flash_float(&cc.slope[j][seg]) * vf;
    }
}

// 4: trig from each joint's table (constant corrections included), turned by the varying
// part e: on the branches (backlash and the elbow's turn, |e| < 0.05 rad) to second order,
// cos e = 1 - e^2/2, sin e = e; on the gimbal (backlash alone, |e| < 0.01 rad) to first
// order; within 2e-6 of the amplitude either way.
// (The solver's constants come in as scalars: a pointer to them would keep a copy in RAM.)
// With kCurves and an encoder curve, the encoder error between the knots joins e (the part at
// the knot is in the coarse table): at most the error's change over one knot step, a few
// 1e-3 rad, so the rotation's approximations keep their accuracy.
template <bool kCurves>
DELTA6_NOINLINE void joint_trig(const CalibrationConstants& cc, int16_t origin,
                                const float* fine, const int16_t delta[6],
                                const int16_t dir2[6], const float tau[6], float cs[6],
                                float sn[6], const CurvedCalibrationConstants* cv) {
    const int16_t half = flash::i16(&cc.direction_half);
    for (uint8_t j = 0; j < 6; ++j) {
        const uint16_t biased = static_cast<uint16_t>(delta[j] + origin);
        float c0, s0;
        fastmath::table_cos_sin(flash::table(&cc.table[j]), fine, biased, &c0, &s0);
        // The direction is +-H (the play saturated) but during a reversal: no multiply then.
        const int16_t d2 = dir2[j];
        float e;
        if (kCurves) {
            // The backlash and the encoder error between the knots summed in fixed point:
            // one conversion to float instead of a conversion and a float addition.
            const int32_t eh = flash::i32(&cv->eh[j]);
            int32_t turn = d2 == half ? eh : d2 == -half ? -eh
                           : flash::i32(&cv->ed[j]) * d2;
            turn -= curve_angle_between_knots(cv, j, biased);
            e = turn == 0 ? 0.0f : scale_down(static_cast<float>(turn), kCurveTurnShift);
        } else {
            e = d2 == half ? flash_float(&cc.eh[j])
                : d2 == -half ? -flash_float(&cc.eh[j])
                : flash_float(&cc.ed[j]) * static_cast<float>(d2);
        }
        if (j < 3) e += flash_float(&cc.elbow[j]) * tau[j];
        if ((fastmath::bits_of(e) & 0x7FFFFFFFul) != 0) {
            // c' = c m - s e, s' = s m + c e with m = cos e: 1 - e^2/2 on the branches (as
            // c - e (s + c e/2) and s + e (c - s e/2): four multiplies), 1 on the gimbal.
            if (j < 3) {
                const float h = fastmath::scale2(e, -1);
                const float c1 = c0 - e * (s0 + c0 * h);
                s0 -= e * (s0 * h - c0);
                c0 = c1;
            } else {
                const float c1 = c0 - s0 * e;
                s0 += c0 * e;
                c0 = c1;
            }
        }
        cs[j] = c0;
        sn[j] = s0;
    }
}

// 5: sphere centres c_i = r_i u_i + h_i z and the general trilateration, relative to the
// first centre: P' = P - c_1 from P' . A_j = e_j (j = 2, 3) and |P'| = lb_1, with
// A_j = c_j - c_1 and e_j = (|A_j|^2 - lb_j^2 + lb_1^2) / 2. Fills a with A_2 and A_3
// (x, y, z), p with P'. Returns a SolveStatus.
DELTA6_NOINLINE uint8_t trilaterate(const CalibrationConstants& cc, float min_height_sq,
                                    const float cs[6], const float sn[6], float a[2][3],
                                    float p[3]) {
    float cx[3], cy[3];
    for (uint8_t i = 0; i < 3; ++i) {
        const float r = flash_float(&cc.d[i]) + cs[i];
        cx[i] = r * flash_float(&cc.ux[i]);
        cy[i] = r * flash_float(&cc.uy[i]);
    }
    const float a2x = cx[1] - cx[0], a2y = cy[1] - cy[0], a2z = sn[1] - sn[0];
    const float a3x = cx[2] - cx[0], a3y = cy[2] - cy[0], a3z = sn[2] - sn[0];
    a[0][0] = a2x;
    a[0][1] = a2y;
    a[0][2] = a2z;
    a[1][0] = a3x;
    a[1][1] = a3y;
    a[1][2] = a3z;
    const float e2 = fastmath::scale2(a2x * a2x + a2y * a2y + a2z * a2z, -1)
                     - flash_float(&cc.half_dlb_sq[1]);
    const float e3 = fastmath::scale2(a3x * a3x + a3y * a3y + a3z * a3z, -1)
                     - flash_float(&cc.half_dlb_sq[2]);
    const float det = a2x * a3y - a2y * a3x;
    if (!fastmath::at_least(det, flash_float(&cc.min_det))) return kSolveSingular;
    const float inv = 1.0f / det;
    const float ax = (a2y * a3z - a3y * a2z) * inv, bx = (a3y * e2 - a2y * e3) * inv;
    const float ay = (a3x * a2z - a2x * a3z) * inv, by = (a2x * e3 - a3x * e2) * inv;
    const float qa = ax * ax + ay * ay + 1.0f;
    const float qb = ax * bx + ay * by;
    const float qc = bx * bx + by * by - flash_float(&cc.lb_sq[0]);
    const float disc = qb * qb - qa * qc;
    if (!fastmath::at_least(disc, min_height_sq * qa)) return kSolveNoSolution;
    const float z = (fastmath::sqrt32(disc) - qb) / qa;
    p[0] = ax * z + bx;
    p[1] = ay * z + by;
    p[2] = z;
    return kSolveOk;
}

// Statics: link i carries tau_i v_i / G_i, G_i = (u_i . v_i) h_i - v_iz rho_i, with
// v_i = P - c_i (P' for the first branch, P' - A_i for the others); the force on the
// platform is F = -sum tau_i v_i / G_i. Returns a SolveStatus.
DELTA6_NOINLINE uint8_t statics(const CalibrationConstants& cc, float min_lever,
                                const float cs[6], const float sn[6], const float tau[6],
                                const float a[2][3], const float p[3], float f[3]) {
    float v[3][3];
    for (uint8_t k = 0; k < 3; ++k) {
        v[0][k] = p[k];
        v[1][k] = p[k] - a[0][k];
        v[2][k] = p[k] - a[1][k];
    }
    float s[3];
    for (uint8_t i = 0; i < 3; ++i) {
        const float uv = flash_float(&cc.ux[i]) * v[i][0] + flash_float(&cc.uy[i]) * v[i][1];
        const float g = uv * sn[i] - v[i][2] * cs[i];
        if (!fastmath::at_least(absf(g), min_lever)) return kSolveSingular;
        s[i] = tau[i] / g;
    }
    for (uint8_t k = 0; k < 3; ++k) {
        f[k] = -(s[0] * v[0][k] + s[1] * v[1][k] + s[2] * v[2][k]);
    }
    return kSolveOk;
}

// 6: the gimbal, F_E0 = F - w x F with w = gimbal + tilt * (M + c z x F), then eq. (12) with
// the corrected gimbal angles, R^T = Ry^T Rx^T Rz^T, into wrench (left as it was unless
// every value is finite). Returns a SolveStatus. (Its own function: in the caller's frame,
// beyond the 64 bytes a load or store addresses, every value costs two more instructions.)
DELTA6_NOINLINE uint8_t to_e(const CalibrationConstants& cc, const float tau[6],
                             const float f[3], const float cs[6], const float sn[6],
                             float wrench[6]) {
    const float c = flash_float(&cc.c), tilt = flash_float(&cc.tilt);
    const float wx = flash_float(&cc.gimbal[0]) + tilt * (tau[3] - c * f[1]);
    const float wy = flash_float(&cc.gimbal[1]) + tilt * (tau[4] + c * f[0]);
    const float wz = flash_float(&cc.gimbal[2]) + tilt * tau[5];
    float w[6] = {
        f[0] - (wy * f[2] - wz * f[1]),
        f[1] - (wz * f[0] - wx * f[2]),
        f[2] - (wx * f[1] - wy * f[0]),
        tau[3], tau[4], tau[5],
    };
    DELTA6_PROFILE_MARK(25);
    for (uint8_t v = 0; v < 6; v += 3) {
        rotate_back(cs[5], sn[5], w[v], w[v + 1]);
        rotate_back(cs[3], sn[3], w[v + 1], w[v + 2]);
        rotate_back(cs[4], sn[4], w[v + 2], w[v]);
    }
    for (uint8_t i = 0; i < 6; ++i) {
        if (!fastmath::is_finite(w[i])) return kSolveNonFinite;
    }
    for (uint8_t i = 0; i < 6; ++i) wrench[i] = w[i];
    return kSolveOk;
}

}  // namespace

void calibration_reset(CalibrationState& s) {
    s.started = 0;
    s.after_gap = 0;
}

void calibration_set_period(const CalibrationConstants& c, float period_s,
                            CalibrationState& s) {
    const float tau = flash_float(&c.speed_tau);
    if (!(period_s > 0.0f)) {
        s.speed_a = 1.0f;
        s.speed_g = 0.0f;
        s.lead_a = 1.0f;
        s.lead_k = 0.0f;
        for (uint8_t k = 0; k < kSpeedSteps; ++k) s.speed_step[k] = 0.0f;
        return;
    }
    s.speed_a = tau / (tau + period_s);
    s.speed_g = (1.0f - s.speed_a) * kCountRad / period_s;
    // The acceleration's filter: twice the speed's time constant (delta6.core.calibrated).
    const float slow = 2.0f * tau;
    s.lead_a = slow / (slow + period_s);
    s.lead_k = (1.0f - s.lead_a) * flash_float(&c.speed_lead) / period_s;
    for (uint8_t k = 0; k < kSpeedSteps; ++k) {
        s.speed_step[k] = s.speed_g * static_cast<float>(k + 1);
    }
}

namespace {

// The history settled at the first sample's counts: every play at x, the direction play at 2x,
// no speed. Once per start: compiled for size.
DELTA6_NOINLINE DELTA6_FOR_SIZE void start_settled(const CalibrationConstants& cc,
                                                   CalibrationState& st, const int16_t delta[6]) {
    for (uint8_t j = 0; j < 6; ++j) {
        st.last[j] = delta[j];
        st.direction2[j] = static_cast<int16_t>(2 * delta[j]);
        for (uint8_t r = 0; r < kMaxPlayRadii; ++r) st.play[j][r] = delta[j];
        st.speed[j] = 0.0f;
        st.lead[j] = 0.0f;
        st.count_sum[j] = wrapping_add(wrapping_mul(flash::i32(&cc.kx[j]), delta[j]),
                                       flash::i32(&cc.k0[j]));
    }
    st.started = 1;
    st.after_gap = 0;
}

// Inlined into each overload, so that the one without curves is the code it was before.
template <bool kCurves>
DELTA6_ALWAYS_INLINE uint8_t solve(const SolverConstants& k, const CalibrationConstants& cc,
              const CurvedCalibrationConstants* cv, CalibrationState& st,
              const int16_t delta[6], float wrench[6]) {
    if (!st.started) start_settled(cc, st, delta);
    float tau[6];
    int16_t dir2[6];
    joint_torques<kCurves>(cc, st, delta, tau, dir2, cv, k.table_origin);
    st.after_gap = 0;
    DELTA6_PROFILE_MARK(21);
    // The joint box, on the counts as the analytical solver has it.
    for (uint8_t i = 0; i < 6; ++i) {
        if (delta[i] > k.limit_counts || delta[i] < -k.limit_counts) {
            return fail(kSolveOutOfBox, wrench);
        }
    }
    float cs[6], sn[6];
    joint_trig<kCurves>(cc, k.table_origin, k.fine_table, delta, dir2, tau, cs, sn, cv);
    DELTA6_PROFILE_MARK(22);
    float a[2][3], p[3];
    uint8_t status = trilaterate(cc, k.min_height_sq, cs, sn, a, p);
    if (status != kSolveOk) return fail(status, wrench);
    DELTA6_PROFILE_MARK(23);
    float f[3];
    status = statics(cc, k.min_lever, cs, sn, tau, a, p, f);
    if (status != kSolveOk) return fail(status, wrench);
    DELTA6_PROFILE_MARK(24);
    status = to_e(cc, tau, f, cs, sn, wrench);
    if (status != kSolveOk) return fail(status, wrench);
    return kSolveOk;
}

}  // namespace

uint8_t solve_calibrated(const SolverConstants& k, const CalibrationConstants& cc,
                         CalibrationState& st, const int16_t delta[6], float wrench[6]) {
    return solve<false>(k, cc, nullptr, st, delta, wrench);
}

uint8_t solve_calibrated(const SolverConstants& k, const CurvedCalibrationConstants& cv,
                         CalibrationState& st, const int16_t delta[6], float wrench[6]) {
    return solve<true>(k, cv.base, &cv, st, delta, wrench);
}

}  // namespace delta6
