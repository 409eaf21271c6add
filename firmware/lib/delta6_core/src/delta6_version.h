// The firmware's version, reported in the info record. One definition for every build of the
// core: the board's firmware and the simulated device (firmware/native/) report the same.
#ifndef DELTA6_VERSION_H
#define DELTA6_VERSION_H

#include <stdint.h>

namespace delta6 {

const uint8_t kFirmwareVersionMajor = 1;
const uint8_t kFirmwareVersionMinor = 0;
const uint8_t kFirmwareVersionPatch = 0;

}  // namespace delta6

#endif
