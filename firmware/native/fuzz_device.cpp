// Sanitizer fuzz driver for the device core: random commands (valid, mutated, unknown), random
// garbage and random samples (NaN, infinities, huge values, encoder faults, clock jumps and
// wrap-around), EEPROM corruption and reboots, fed to delta6::Device. Build with
// -fsanitize=address,undefined (the tests do). Every byte the device sends goes to stdout for
// the host decoder to check as well; the driver itself checks every frame as it goes:
// valid COBS and CRC, a known type with its exact size, and a data record either carries a
// wrench or marks all six values invalid, never a mix. Exit status 1 on any violation.
//
// usage: fuzz_device SEED STEPS > stream.bin
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "delta6_cobs.h"
#include "delta6_crc16.h"
#include "delta6_device.h"
#include "delta6_protocol.h"
#include "sim_hardware.h"

using namespace delta6;

namespace {

uint64_t state;
uint32_t next() {  // xorshift64*
  state ^= state >> 12;
  state ^= state << 25;
  state ^= state >> 27;
  return static_cast<uint32_t>((state * 2685821657736338717ULL) >> 32);
}
uint32_t below(uint32_t n) { return n ? next() % n : 0; }

float randomFloat() {
  switch (below(8)) {
    case 0: return __builtin_nanf("");
    case 1: return below(2) ? __builtin_inff() : -__builtin_inff();
    case 2: return (below(2) ? 1.0f : -1.0f) * 1e30f;
    case 3: return 1e-40f;  // subnormal
    default: return (static_cast<float>(below(200001)) - 100000.0f) * 1e-3f;
  }
}

// Checks the device's output frame by frame.
struct OutputChecker {
  uint8_t frame[300];
  uint16_t len = 0;
  uint32_t frames = 0;
  uint32_t violations = 0;

  void byte(uint8_t b) {
    if (b != 0) {
      if (len < sizeof(frame)) frame[len] = b;
      ++len;
      return;
    }
    check();
    len = 0;
  }

  void fail(const char* what) {
    if (violations++ < 10) fprintf(stderr, "violation in frame %u: %s\n", frames, what);
  }

  void check() {
    ++frames;
    if (len == 0 || len > sizeof(frame)) return fail("empty or oversized frame");
    const int16_t n = cobsDecodeInPlace(frame, len);
    if (n < 3) return fail("invalid COBS");
    if (crc16(frame, static_cast<uint16_t>(n)) != 0) return fail("bad CRC");
    const uint16_t size = proto::recordSize(frame[0]);
    if (size == 0 || n != size + 2) return fail("unknown type or wrong size");
    if (frame[0] == proto::kWrench || frame[0] == proto::kWrenchRaw) {
      const bool invalid = proto::getU16(frame + proto::kWrenchOffStatus) & proto::kStatusWrenchInvalid;
      int sentinels = 0;
      for (int i = 0; i < 6; ++i) {
        const int16_t v = static_cast<int16_t>(proto::getU16(frame + proto::kWrenchOffWrench + 2 * i));
        sentinels += v == proto::kInvalidValue;
      }
      if (invalid ? sentinels != 6 : sentinels != 0) fail("wrench values disagree with status");
    }
  }
};

const uint8_t kTypes[] = {proto::kCmdGetInfo, proto::kCmdPing, proto::kCmdStart,
                          proto::kCmdStop, proto::kCmdSetMode, proto::kCmdTare,
                          proto::kCmdClearTare, proto::kCmdSaveConfig,
                          proto::kCmdLoadDefaults, proto::kCmdSetZero, proto::kCmdZeroHere,
                          proto::kCmdGetTelemetry, proto::kCmdSetFilter, proto::kCmdSetTool,
                          proto::kCmdSetLimits, proto::kLastCommand + 1, 0xFF, 0x01, 0x03};

// A command frame (delimiter included) into out; returns its length.
uint16_t makeCommand(uint8_t* out) {
  const uint8_t type = kTypes[below(sizeof(kTypes))];
  uint8_t size = proto::commandSize(type);
  if (size == 0 || below(8) == 0) size = static_cast<uint8_t>(2 + below(20));
  out[1] = type;
  out[2] = static_cast<uint8_t>(below(256));
  for (uint8_t i = 2; i < size; ++i) out[1 + i] = static_cast<uint8_t>(next());
  if (type == proto::kCmdStart && below(2)) proto::putU16(out + 3, static_cast<uint16_t>(below(3000)));
  if ((type == proto::kCmdTare || type == proto::kCmdZeroHere) && below(2)) {
    proto::putU16(out + 3, static_cast<uint16_t>(below(20)));
  }
  if (type == proto::kCmdSetMode && below(2)) out[3] = static_cast<uint8_t>(1 + below(2));
  // Pipeline settings the device accepts, half of the time (random bits mostly are not).
  if (type == proto::kCmdSetFilter && below(2)) {
    proto::putF32(out + 3, below(4) ? static_cast<float>(below(300)) : 0.0f);
  }
  if (type == proto::kCmdSetTool && below(2)) {
    for (uint8_t i = 0; i < 6; ++i) {
      proto::putF32(out + 3 + 4 * i, (static_cast<float>(below(2001)) - 1000.0f) * 1e-3f);
    }
  }
  if (type == proto::kCmdSetLimits && below(2)) {
    for (uint8_t i = 0; i < 6; ++i) proto::putU16(out + 3 + 2 * i, static_cast<uint16_t>(below(3000)));
  }
  return proto::finishFrame(out, size);
}

void mutate(uint8_t* buf, uint16_t* len) {
  switch (below(5)) {
    case 0: buf[below(*len)] ^= static_cast<uint8_t>(1u << below(8)); break;
    case 1: if (*len > 1) *len = static_cast<uint16_t>(below(*len)); break;
    case 2: {  // duplicate a byte
      const uint16_t at = static_cast<uint16_t>(below(*len));
      memmove(buf + at + 1, buf + at, *len - at);
      ++*len;
      break;
    }
    case 3: {  // drop a byte
      const uint16_t at = static_cast<uint16_t>(below(*len));
      memmove(buf + at, buf + at + 1, *len - at - 1u);
      --*len;
      break;
    }
    default: break;
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: fuzz_device SEED STEPS > stream.bin\n");
    return 2;
  }
  state = strtoull(argv[1], 0, 10) * 0x9E3779B97F4A7C15ULL + 1;
  const long steps = strtol(argv[2], 0, 10);

  sim::SimHardware hw(500000, static_cast<uint16_t>(delta6::proto::kMaxFrameBytes + below(200)));
  Identity id;
  memset(&id, 0, sizeof(id));
  id.design_name = "fuzz-design-with-a-name-longer-than-23";
  id.design_hash = 0x12345678;
  const float fs[6] = {15.0f, 15.0f, 25.0f, 0.38f, 0.33f, 0.43f};
  memcpy(id.full_scale, fs, sizeof(fs));
  id.joint_limit_rad = 0.5236f;
  id.joint_limit_counts = 1365;
  id.baud = 500000;
  id.max_rate_hz = 2000;
  Config defaults;
  memset(&defaults, 0, sizeof(defaults));
  defaults.rate_hz = 500;
  defaults.mode = proto::kModeWrench;

  Device device(hw, id, defaults);
  OutputChecker checker;
  uint32_t now = 0xFFFFFFFFu - below(2000000);  // wraps early in the run
  hw.setTime(now);
  device.begin(0);

  uint8_t buf[96];
  uint8_t out[512];
  for (long step = 0; step < steps; ++step) {
    const uint32_t action = below(100);
    if (action < 30) {
      uint16_t len = makeCommand(buf);
      if (below(3) == 0) mutate(buf, &len);
      for (uint16_t i = 0; i < len; ++i) device.onByte(buf[i]);
    } else if (action < 40) {
      const uint16_t len = static_cast<uint16_t>(below(80));
      for (uint16_t i = 0; i < len; ++i) device.onByte(static_cast<uint8_t>(below(4) ? next() : 0));
    } else if (action < 41) {
      hw.eeprom()[below(sim::kEepromSize)] ^= static_cast<uint8_t>(1u << below(8));
      device.begin(static_cast<uint8_t>(below(256)));  // a reboot with possibly corrupt EEPROM
    } else {
      Sample s;
      now += below(10) == 0 ? next() : below(3000);
      s.time_us = now;
      for (int i = 0; i < 6; ++i) {
        s.counts[i] = static_cast<uint16_t>(below(10) ? below(16384) : next());
        s.wrench[i] = randomFloat();
      }
      s.encoder_errors = static_cast<uint8_t>(below(4) == 0 ? next() : 0);
      s.solver_ok = below(8) != 0;
      s.overrun = below(16) == 0;
      s.loop_time_us = static_cast<uint16_t>(next());
      s.temperature_centi = static_cast<int16_t>(next());
      hw.setTime(now);
      device.onSample(s);
    }
    uint32_t n;
    while ((n = hw.read(out, sizeof(out))) > 0) {
      for (uint32_t i = 0; i < n; ++i) checker.byte(out[i]);
      fwrite(out, 1, n, stdout);
    }
  }
  fprintf(stderr, "fuzz_device: %ld steps, %u frames, %u violations, %u samples\n", steps,
          checker.frames, checker.violations, device.counters().samples);
  return checker.violations ? 1 : 0;
}
