#include "delta6_toolframe.h"

#include "delta6_fastmath.h"

namespace delta6 {

bool makeToolFrame(const float translation[3], const float rpy[3], ToolFrame* out) {
  for (uint8_t i = 0; i < 3; ++i) {
    if (!fastmath::is_finite(translation[i]) || !fastmath::is_finite(rpy[i])) return false;
  }
  using fastmath::cos32;
  using fastmath::sin32;
  const float cr = cos32(rpy[0]), sr = sin32(rpy[0]);
  const float cp = cos32(rpy[1]), sp = sin32(rpy[1]);
  const float cy = cos32(rpy[2]), sy = sin32(rpy[2]);
  // R = Rz(yaw) Ry(pitch) Rx(roll); rt holds its transpose.
  const float r[9] = {cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
                      sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
                      -sp,     cp * sr,                cp * cr};
  for (uint8_t i = 0; i < 3; ++i) {
    for (uint8_t j = 0; j < 3; ++j) out->rt[3 * i + j] = r[3 * j + i];
    out->p[i] = translation[i];
  }
  out->identity = translation[0] == 0.0f && translation[1] == 0.0f && translation[2] == 0.0f &&
                  rpy[0] == 0.0f && rpy[1] == 0.0f && rpy[2] == 0.0f;
  return true;
}

void applyToolFrame(const ToolFrame& t, float w[6]) {
  if (t.identity) return;
  const float* p = t.p;
  // Moment about the tool point: M - p x F.
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

}  // namespace delta6
