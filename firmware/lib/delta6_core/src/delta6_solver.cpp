// The wrench solver; see delta6_solver.h for the interface and docs/firmware.md for the
// derivation and the cycle budget. Notation follows docs/model.md: r_i = a - b + la cos
// theta_i and h_i = la sin theta_i place the sphere centre of branch i at r_i u_i + h_i z.
#include "delta6_solver.h"

#include "delta6_fastmath.h"

// Stage markers for the cycle profile of tools/bench_solver_avr.py --stages: the benchmark
// build defines DELTA6_SOLVER_PROFILE and provides the hook header; elsewhere they vanish.
#ifdef DELTA6_SOLVER_PROFILE
#include "delta6_solver_profile_hooks.h"
#else
#define DELTA6_PROFILE_MARK(stage) ((void)0)
#endif

namespace delta6 {
namespace {

using fastmath::absf;
using fastmath::scale2;
using fastmath::rotate_back;

constexpr float kSqrt3 = 1.73205081f;
constexpr float kHalfSqrt3 = 0.866025404f;
constexpr float kInvSqrt3 = 0.577350269f;
static_assert(kTableStep == 64, "fastmath::table_cos_sin splits counts into 64-count steps");

// What the trigonometry of the six joints contributes; the rest is the same for both entry
// points. Index i = joint i+1. Branches (i < 3): c = rho_i = la cos theta_i, s = h_i =
// la sin theta_i. Gimbal (i >= 3): c, s = cos, sin theta_ei. torque = k_i theta_ei.
struct JointTerms {
    float c[6];
    float s[6];
    float torque[6];
};

uint8_t fail(uint8_t status, float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) wrench[i] = 0.0f;
    return status;
}

// Eq. (12): force and moment (w[0..2], w[3..5]) into {E} with R^T, where R = Rz(theta6)
// Rx(theta4) Ry(theta5), so R^T = Ry^T Rx^T Rz^T: three plane rotations per vector, 24
// multiplies for both, against 14 to build R and 18 to apply it.
void rotate_to_e(const JointTerms& t, float w[6]) {
    for (uint8_t v = 0; v < 6; v += 3) {
        rotate_back(t.c[5], t.s[5], w[v], w[v + 1]);      // Rz(theta6)^T: x, y
        rotate_back(t.c[3], t.s[3], w[v + 1], w[v + 2]);  // Rx(theta4)^T: y, z
        rotate_back(t.c[4], t.s[4], w[v + 2], w[v]);      // Ry(theta5)^T: z, x
    }
}

// Forward kinematics, statics and rotation (eqs. 1-13) from the joint terms.
uint8_t solve_core(const SolverConstants& k, const JointTerms& t, float wrench[6]) {
    DELTA6_PROFILE_MARK(kProfileForwardKinematics);
    const float r1 = k.d + t.c[0], r2 = k.d + t.c[1], r3 = k.d + t.c[2];
    const float h1 = t.s[0], h2 = t.s[1], h3 = t.s[2];

    // Forward kinematics. Subtracting sphere 1 from spheres 2 and 3 leaves two linear
    // equations in x, y; with the azimuths at 0/120/240 deg and |c_i|^2 - lb^2 = const +
    // 2 (a - b) la cos theta_i, their solution is x = ax z + bx, y = ay z + by with the common
    // denominator S = r1 r2 + r2 r3 + r3 r1 (the projected triangle of the centres).
    const float p12 = r1 * r2, p13 = r1 * r3, p23 = r2 * r3;
    const float area = p12 + p13 + p23;
    if (!fastmath::at_least(area, k.min_area)) return fail(kSolveSingular, wrench);
    const float inv_area = 1.0f / area;
    const float dh2 = h2 - h1, dh3 = h3 - h1;
    const float d_inv_area = k.d * inv_area;
    const float ax = (r3 * dh2 + r2 * dh3) * inv_area;
    const float bx = ((p12 + p13) - scale2(p23, 1)) * d_inv_area;
    const float ay = (scale2(r1, 1) * (dh3 - dh2) + r2 * dh3 - r3 * dh2) * (inv_area * kInvSqrt3);
    const float by = r1 * (r2 - r3) * (d_inv_area * kSqrt3);
    DELTA6_PROFILE_MARK(kProfileQuadratic);
    // Sphere 1: (x - r1)^2 + y^2 + (z - h1)^2 = lb^2, a quadratic qa z^2 + 2 qb z + qc = 0.
    const float ex = bx - r1;
    const float qa = ax * ax + ay * ay + 1.0f;
    const float qb = ax * ex + ay * by - h1;
    const float qc = ex * ex + by * by + h1 * h1 - k.lb_sq;
    const float disc = qb * qb - qa * qc;
    // disc / qa is the squared height of the solutions over the plane of the centres.
    if (!fastmath::at_least(disc, k.min_height_sq * qa)) return fail(kSolveNoSolution, wrench);
    const float z = (fastmath::sqrt32(disc) - qb) / qa;  // the root below the base (z down)
    const float x = ax * z + bx, y = ay * z + by;

    DELTA6_PROFILE_MARK(kProfileStatics);
    // Statics, eqs. (2)-(10): link i carries tau_i v_i / G_i with v_i = P - c_i and
    // G_i = (u_i . v_i) h_i - v_iz rho_i = lb * eq. 7's lever la (v_x sin - v_z cos); the
    // link length lb cancels between the lever and the unit vector.
    const float half_x = scale2(x, -1), sy = kHalfSqrt3 * y;
    const float uv1 = x - r1, uv2 = (sy - half_x) - r2, uv3 = -(half_x + sy) - r3;
    const float vz1 = z - h1, vz2 = z - h2, vz3 = z - h3;
    const float g1 = uv1 * h1 - vz1 * t.c[0];
    const float g2 = uv2 * h2 - vz2 * t.c[1];
    const float g3 = uv3 * h3 - vz3 * t.c[2];
    const float min_lever = k.min_lever;
    if (!(fastmath::at_least(absf(g1), min_lever) && fastmath::at_least(absf(g2), min_lever) &&
          fastmath::at_least(absf(g3), min_lever))) {
        return fail(kSolveSingular, wrench);
    }
    const float s1 = t.torque[0] / g1, s2 = t.torque[1] / g2, s3 = t.torque[2] / g3;
    DELTA6_PROFILE_MARK(kProfileForceSum);
    // E0_F = -sum s_i (P - r_i u_i - h_i z).
    const float sigma = s1 + s2 + s3;
    const float q1 = s1 * r1, q2 = s2 * r2, q3 = s3 * r3;
    float w[6] = {
        (q1 - scale2(q2 + q3, -1)) - sigma * x,
        kHalfSqrt3 * (q2 - q3) - sigma * y,
        -(s1 * vz1 + s2 * vz2 + s3 * vz3),
        t.torque[3],
        t.torque[4],
        t.torque[5],
    };
    DELTA6_PROFILE_MARK(kProfileRotation);
    rotate_to_e(t, w);
    DELTA6_PROFILE_MARK(kProfileOutput);
    for (uint8_t i = 0; i < 6; ++i) {
        if (!fastmath::is_finite(w[i])) return fail(kSolveNonFinite, wrench);
    }
    for (uint8_t i = 0; i < 6; ++i) wrench[i] = w[i];
    return kSolveOk;
}

}  // namespace

uint8_t solve_counts(const SolverConstants& k, const int16_t delta[6], float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) {
        if (delta[i] > k.limit_counts || delta[i] < -k.limit_counts) {
            return fail(kSolveOutOfBox, wrench);
        }
    }
    JointTerms t;
    for (uint8_t i = 0; i < 6; ++i) {
        const uint16_t biased = static_cast<uint16_t>(delta[i] + k.table_origin);
        fastmath::table_cos_sin(i < 3 ? k.branch_table : k.joint_table, k.fine_table, biased,
                                &t.c[i], &t.s[i]);
        t.torque[i] = k.torque_per_count[i] * static_cast<float>(delta[i]);
    }
    return solve_core(k, t, wrench);
}

uint8_t solve_radians(const SolverConstants& k, const float theta_e[6], float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) {
        if (!(absf(theta_e[i]) <= k.limit_rad)) return fail(kSolveOutOfBox, wrench);
    }
    JointTerms t;
    for (uint8_t i = 0; i < 6; ++i) {
        const bool branch = i < 3;
        const float theta = branch ? theta_e[i] + k.theta_offset : theta_e[i];
        const float scale = branch ? k.la : 1.0f;
        t.c[i] = scale * fastmath::cos32(theta);
        t.s[i] = scale * fastmath::sin32(theta);
        t.torque[i] = k.spring_rate[i] * theta_e[i];
    }
    return solve_core(k, t, wrench);
}

}  // namespace delta6
