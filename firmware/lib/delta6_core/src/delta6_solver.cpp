// The wrench solver; see delta6_solver.h for the interface and docs/firmware.md for the
// derivation and the cycle budget. Notation follows docs/model.md: r_i = a - b + la cos
// theta_i and h_i = la sin theta_i place the sphere centre of branch i at r_i u_i + h_i z.
#include "delta6_solver.h"

#include "delta6_fastmath.h"

namespace delta6 {
namespace {

using fastmath::absf;
using fastmath::scale2;

constexpr float kSqrt3 = 1.73205081f;
constexpr float kHalfSqrt3 = 0.866025404f;
constexpr float kInvSqrt3 = 0.577350269f;
constexpr uint8_t kTableShift = 6;  // log2(kTableStep)
static_assert((1 << kTableShift) == kTableStep, "table step must be a power of two");

// What the trigonometry of the six joints contributes; the rest is the same for both entry
// points. Branch i (joints 1..3): rho_i = la cos theta_i, h_i = la sin theta_i, tau_i the
// spring torque. Gimbal j (joints 4..6): cos and sin of theta_ej, moment_j = k theta_ej.
struct JointTerms {
    float rho[3];
    float h[3];
    float tau[3];
    float cos_g[3];
    float sin_g[3];
    float moment[3];
};

uint8_t fail(uint8_t status, float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) wrench[i] = 0.0f;
    return status;
}

// v <- R^T v with R = Rz(theta6) Rx(theta4) Ry(theta5): R^T = Ry^T Rx^T Rz^T, applied as
// three plane rotations (12 multiplies instead of 9 + the 14 that building R would take).
void rotate_to_e(const JointTerms& t, float v[3]) {
    const float c4 = t.cos_g[0], s4 = t.sin_g[0];
    const float c5 = t.cos_g[1], s5 = t.sin_g[1];
    const float c6 = t.cos_g[2], s6 = t.sin_g[2];
    const float x1 = c6 * v[0] + s6 * v[1];
    const float y1 = c6 * v[1] - s6 * v[0];
    const float y2 = c4 * y1 + s4 * v[2];
    const float z2 = c4 * v[2] - s4 * y1;
    v[0] = c5 * x1 - s5 * z2;
    v[1] = y2;
    v[2] = s5 * x1 + c5 * z2;
}

// Forward kinematics, statics and rotation (eqs. 1-13) from the joint terms.
uint8_t solve_core(const SolverConstants& k, const JointTerms& t, float wrench[6]) {
    const float r1 = k.d + t.rho[0], r2 = k.d + t.rho[1], r3 = k.d + t.rho[2];
    const float h1 = t.h[0], h2 = t.h[1], h3 = t.h[2];

    // Forward kinematics. Subtracting sphere 1 from spheres 2 and 3 leaves two linear
    // equations in x, y; with the azimuths at 0/120/240 deg and |c_i|^2 - lb^2 = const +
    // 2 (a - b) la cos theta_i, their solution is x = ax z + bx, y = ay z + by with the common
    // denominator S = r1 r2 + r2 r3 + r3 r1 (the projected triangle of the centres).
    const float p12 = r1 * r2, p13 = r1 * r3, p23 = r2 * r3;
    const float area = p12 + p13 + p23;
    if (!(area > k.min_area)) return fail(kSolveSingular, wrench);
    const float inv_area = 1.0f / area;
    const float dh2 = h2 - h1, dh3 = h3 - h1;
    const float d_inv_area = k.d * inv_area;
    const float ax = (r3 * dh2 + r2 * dh3) * inv_area;
    const float bx = ((p12 + p13) - scale2(p23, 1)) * d_inv_area;
    const float ay = (scale2(r1, 1) * (dh3 - dh2) + r2 * dh3 - r3 * dh2) * (inv_area * kInvSqrt3);
    const float by = r1 * (r2 - r3) * (d_inv_area * kSqrt3);
    // Sphere 1: (x - r1)^2 + y^2 + (z - h1)^2 = lb^2, a quadratic qa z^2 + 2 qb z + qc = 0.
    const float ex = bx - r1;
    const float qa = ax * ax + ay * ay + 1.0f;
    const float qb = ax * ex + ay * by - h1;
    const float qc = ex * ex + by * by + h1 * h1 - k.lb_sq;
    const float disc = qb * qb - qa * qc;
    // disc / qa is the squared height of the solutions over the plane of the centres.
    if (!(disc >= k.min_height_sq * qa)) return fail(kSolveNoSolution, wrench);
    const float z = (fastmath::sqrt32(disc) - qb) / qa;  // the root below the base (z down)
    const float x = ax * z + bx, y = ay * z + by;

    // Statics, eqs. (2)-(10): link i carries tau_i v_i / G_i with v_i = P - c_i and
    // G_i = (u_i . v_i) h_i - v_iz rho_i = la lb * lever_i (eq. 7); lb cancels.
    const float half_x = scale2(x, -1), sy = kHalfSqrt3 * y;
    const float uv1 = x - r1, uv2 = (sy - half_x) - r2, uv3 = -(half_x + sy) - r3;
    const float vz1 = z - h1, vz2 = z - h2, vz3 = z - h3;
    const float g1 = uv1 * h1 - vz1 * t.rho[0];
    const float g2 = uv2 * h2 - vz2 * t.rho[1];
    const float g3 = uv3 * h3 - vz3 * t.rho[2];
    if (!(absf(g1) >= k.min_lever && absf(g2) >= k.min_lever && absf(g3) >= k.min_lever)) {
        return fail(kSolveSingular, wrench);
    }
    const float s1 = t.tau[0] / g1, s2 = t.tau[1] / g2, s3 = t.tau[2] / g3;
    // E0_F = -sum s_i (P - r_i u_i - h_i z).
    const float sigma = s1 + s2 + s3;
    const float q1 = s1 * r1, q2 = s2 * r2, q3 = s3 * r3;
    float force[3] = {
        (q1 - scale2(q2 + q3, -1)) - sigma * x,
        kHalfSqrt3 * (q2 - q3) - sigma * y,
        -(s1 * vz1 + s2 * vz2 + s3 * vz3),
    };
    float moment[3] = {t.moment[0], t.moment[1], t.moment[2]};

    // Eq. (12): both vectors into {E} with R^T.
    rotate_to_e(t, force);
    rotate_to_e(t, moment);
    for (uint8_t i = 0; i < 3; ++i) {
        if (!fastmath::is_finite(force[i]) || !fastmath::is_finite(moment[i])) {
            return fail(kSolveNonFinite, wrench);
        }
    }
    for (uint8_t i = 0; i < 3; ++i) {
        wrench[i] = force[i];
        wrench[3 + i] = moment[i];
    }
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
    for (uint8_t i = 0; i < 3; ++i) {
        const uint16_t biased = static_cast<uint16_t>(delta[i] + k.table_origin);
        const fastmath::CosSin branch =
            fastmath::table_cos_sin(k.branch_table, k.fine_table, biased, kTableShift);
        t.rho[i] = branch.c;
        t.h[i] = branch.s;
        t.tau[i] = k.torque_per_count[i] * static_cast<float>(delta[i]);
        const uint16_t biased_g = static_cast<uint16_t>(delta[3 + i] + k.table_origin);
        const fastmath::CosSin gimbal =
            fastmath::table_cos_sin(k.joint_table, k.fine_table, biased_g, kTableShift);
        t.cos_g[i] = gimbal.c;
        t.sin_g[i] = gimbal.s;
        t.moment[i] = k.torque_per_count[3 + i] * static_cast<float>(delta[3 + i]);
    }
    return solve_core(k, t, wrench);
}

uint8_t solve_radians(const SolverConstants& k, const float theta_e[6], float wrench[6]) {
    for (uint8_t i = 0; i < 6; ++i) {
        if (!(absf(theta_e[i]) <= k.limit_rad)) return fail(kSolveOutOfBox, wrench);
    }
    JointTerms t;
    for (uint8_t i = 0; i < 3; ++i) {
        const float theta = theta_e[i] + k.theta_offset;
        t.rho[i] = k.la * fastmath::cos32(theta);
        t.h[i] = k.la * fastmath::sin32(theta);
        t.tau[i] = k.spring_rate[i] * theta_e[i];
        t.cos_g[i] = fastmath::cos32(theta_e[3 + i]);
        t.sin_g[i] = fastmath::sin32(theta_e[3 + i]);
        t.moment[i] = k.spring_rate[3 + i] * theta_e[3 + i];
    }
    return solve_core(k, t, wrench);
}

}  // namespace delta6
