#include "delta6_toolframe.h"

#include "delta6_fastmath.h"

namespace delta6 {

namespace {

// The axis after a (x -> y -> z -> x), without a division.
inline uint8_t next(uint8_t a) { return a == 2 ? 0 : static_cast<uint8_t>(a + 1); }

// m = Rk(angle)^T m for the elementary rotation about axis k: it mixes rows i and j, the
// two axes after k. Written as one loop (not the nine products of R spelled out): on the AVR
// every float operation is a call, and the loops keep the tool frame in a few hundred bytes.
void rotateRows(float m[9], uint8_t k, float angle) {
  const float c = fastmath::cos32(angle), s = fastmath::sin32(angle);
  float* ri = m + 3 * next(k);
  float* rj = m + 3 * next(next(k));
  for (uint8_t col = 0; col < 3; ++col) {
    const float a = ri[col], b = rj[col];
    ri[col] = c * a + s * b;
    rj[col] = c * b - s * a;
  }
}

// out = m v (transpose: m^T v) for a row-major 3x3 m.
void multiply(const float m[9], bool transpose, const float v[3], float out[3]) {
  for (uint8_t i = 0; i < 3; ++i) {
    float sum = 0.0f;
    for (uint8_t j = 0; j < 3; ++j) sum += (transpose ? m[3 * j + i] : m[3 * i + j]) * v[j];
    out[i] = sum;
  }
}

// m += sign * (p x f).
void addCross(const float p[3], const float f[3], float sign, float m[3]) {
  for (uint8_t i = 0; i < 3; ++i) {
    const uint8_t j = next(i), k = next(j);
    m[i] += sign * (p[j] * f[k] - p[k] * f[j]);
  }
}

}  // namespace

bool toolIsIdentity(const float translation[3], const float rpy[3]) {
  for (uint8_t i = 0; i < 3; ++i) {  // +-0 only, by the bits: no float compare calls
    if ((fastmath::bits_of(translation[i]) << 1) || (fastmath::bits_of(rpy[i]) << 1)) return false;
  }
  return true;
}

bool makeToolFrame(const float translation[3], const float rpy[3], ToolFrame* out) {
  for (uint8_t i = 0; i < 3; ++i) {
    if (!fastmath::is_finite(translation[i]) || !fastmath::is_finite(rpy[i])) return false;
  }
  out->identity = toolIsIdentity(translation, rpy);
  // The identity needs no trig: the device builds it at start-up, before its clock runs.
  for (uint8_t i = 0; i < 9; ++i) out->rt[i] = i % 4 == 0 ? 1.0f : 0.0f;
  for (uint8_t i = 0; i < 3; ++i) out->p[i] = translation[i];
  if (!out->identity) {
    // R^T = Rx(roll)^T Ry(pitch)^T Rz(yaw)^T, built from the identity right to left.
    for (uint8_t k = 3; k-- > 0;) rotateRows(out->rt, k, rpy[k]);
  }
  return true;
}

void applyToolFrame(const ToolFrame& t, float w[6]) {
  if (t.identity) return;
  // F_tool = R^T F, M_tool = R^T (M - p x F). Spelled out, unlike the rest of this file: it
  // runs every sample, and the loops' index arithmetic costs about 900 cycles more.
  const float* p = t.p;
  const float m[3] = {w[3] - (p[1] * w[2] - p[2] * w[1]),
                      w[4] - (p[2] * w[0] - p[0] * w[2]),
                      w[5] - (p[0] * w[1] - p[1] * w[0])};
  const float f[3] = {w[0], w[1], w[2]};
  for (uint8_t i = 0; i < 3; ++i) {
    const float* row = t.rt + 3 * i;
    w[i] = row[0] * f[0] + row[1] * f[1] + row[2] * f[2];
    w[3 + i] = row[0] * m[0] + row[1] * m[1] + row[2] * m[2];
  }
}

void unapplyToolFrame(const ToolFrame& t, float w[6]) {
  if (t.identity) return;
  // F = R F_tool, M = R M_tool + p x F.
  const float f[3] = {w[0], w[1], w[2]};
  const float m[3] = {w[3], w[4], w[5]};
  multiply(t.rt, true, f, w);
  multiply(t.rt, true, m, w + 3);
  addCross(t.p, w, 1.0f, w + 3);
}

}  // namespace delta6
