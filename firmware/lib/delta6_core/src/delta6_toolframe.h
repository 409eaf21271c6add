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

// No translation and no rotation (every value +-0).
bool toolIsIdentity(const float translation[3], const float rpy[3]);
// From the translation (m) and roll, pitch, yaw (rad); false for non-finite values.
bool makeToolFrame(const float translation[3], const float rpy[3], ToolFrame* out);
// The wrench w (Fx Fy Fz Mx My Mz) moved into the tool frame, in place.
void applyToolFrame(const ToolFrame& t, float w[6]);
// The inverse: a wrench given in the tool frame back at {E}'s origin in {E}'s axes
// (F = R F_tool, M = R M_tool + p x F). The device re-expresses its tare with it when the
// tool frame changes.
void unapplyToolFrame(const ToolFrame& t, float w[6]);

}  // namespace delta6

#endif
