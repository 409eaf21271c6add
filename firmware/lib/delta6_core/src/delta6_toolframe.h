// The reporting frame of the wrench: a tool transform as on ATI's sensors. The solver gives
// the wrench at the origin of frame {E} in {E}'s axes; the device reports it at a point p (the
// tool point, in {E}, metres) in axes rotated by R (roll, pitch, yaw in radians about x, y, z
// of {E}: R = Rz(yaw) Ry(pitch) Rx(roll), the tool's axes expressed in {E}):
//
//   F_tool = R^T F,   M_tool = R^T (M - p x F)
//
// delta6.core.toolframe is the Python reference.
#ifndef DELTA6_TOOLFRAME_H
#define DELTA6_TOOLFRAME_H

#include <stdint.h>

namespace delta6 {

struct ToolFrame {
  float rt[9];       // R^T, row-major
  float p[3];
  bool identity;     // no translation and no rotation: nothing to do per sample
};

// From the translation (m) and roll, pitch, yaw (rad); false for non-finite values.
bool makeToolFrame(const float translation[3], const float rpy[3], ToolFrame* out);
// The wrench w (Fx Fy Fz Mx My Mz) moved into the tool frame, in place.
void applyToolFrame(const ToolFrame& t, float w[6]);

}  // namespace delta6

#endif
