// C interface to the portable device core for the host: the simulated device
// (delta6.sim.simdevice, the delta6sim:// serial URL) and the cross-language tests call these
// through ctypes. Built natively by delta6.build.nativebuild; never part of the firmware image.
#include <stdint.h>
#include <string.h>

#include "delta6_cobs.h"
#include "delta6_crc16.h"
#include "delta6_device.h"
#include "delta6_protocol.h"
#include "delta6_version.h"
#include "sim_hardware.h"

using delta6::Config;
using delta6::Device;
using delta6::Identity;
using delta6::Sample;
using delta6::sim::SimHardware;

namespace {

// Identity and defaults first (a base is built before the members that refer to it).
struct Setup {
  char name[24];
  Identity identity;
  Config defaults;

  Setup(const char* design_name, uint32_t hash, const float* full_scale, float joint_limit,
        int16_t joint_limit_counts, uint32_t baud, uint16_t max_rate, uint16_t default_rate, const uint16_t* zero,
        uint32_t serial) {
    memset(name, 0, sizeof(name));
    strncpy(name, design_name, sizeof(name) - 1);
    identity.design_name = name;
    identity.design_hash = hash;
    for (int i = 0; i < 6; ++i) identity.full_scale[i] = full_scale[i];
    identity.joint_limit_rad = joint_limit;
    identity.joint_limit_counts = joint_limit_counts;
    identity.firmware_version[0] = delta6::kFirmwareVersionMajor;
    identity.firmware_version[1] = delta6::kFirmwareVersionMinor;
    identity.firmware_version[2] = delta6::kFirmwareVersionPatch;
    identity.baud = baud;
    identity.max_rate_hz = max_rate;
    identity.serial_number = serial;
    identity.eeprom_address = 0;
    identity.calibration_name = nullptr;
    identity.calibration_hash = 0;
    identity.model_name = nullptr;
    identity.model_hash = 0;
    identity.max_rate_pipeline_hz = 0;
    memset(&defaults, 0, sizeof(defaults));
    defaults.rate_hz = default_rate;
    defaults.mode = delta6::proto::kModeWrench;
    for (int i = 0; i < 6; ++i) defaults.zero_counts[i] = zero[i];
  }
};

struct Sim : Setup {
  SimHardware hardware;
  Device device;
  bool sampled = false;
  uint32_t last_sample_us = 0;

  Sim(const char* design_name, uint32_t hash, const float* full_scale, float joint_limit,
      int16_t joint_limit_counts, uint32_t baud, uint16_t max_rate, uint16_t default_rate,
      const uint16_t* zero, uint32_t serial, uint16_t tx_capacity)
      : Setup(design_name, hash, full_scale, joint_limit, joint_limit_counts, baud, max_rate,
              default_rate, zero, serial),
        hardware(baud, tx_capacity),
        device(hardware, identity, defaults) {}
};

}  // namespace

extern "C" {

void* d6sim_create(const char* name, uint32_t hash, const float* full_scale, float joint_limit,
                   int16_t joint_limit_counts, uint32_t baud, uint16_t max_rate,
                   uint16_t default_rate, const uint16_t* zero, uint32_t serial,
                   uint16_t tx_capacity) {
  return new Sim(name, hash, full_scale, joint_limit, joint_limit_counts, baud, max_rate,
                 default_rate, zero, serial, tx_capacity);
}

void d6sim_destroy(void* sim) { delete static_cast<Sim*>(sim); }

void d6sim_begin(void* p, uint8_t reset_cause, uint16_t boot_id) {
  static_cast<Sim*>(p)->device.begin(reset_cause, boot_id);
}

void d6sim_set_time(void* p, uint32_t us) { static_cast<Sim*>(p)->hardware.setTime(us); }

void d6sim_feed(void* p, const uint8_t* data, uint32_t n) {
  Sim* s = static_cast<Sim*>(p);
  for (uint32_t i = 0; i < n; ++i) s->device.onByte(data[i]);
}

// n samples; arrays are n long, counts and wrench n x 6 (row-major). Each sample first moves
// the clock to its time, as the board's timer would.
void d6sim_samples(void* p, uint32_t n, const uint32_t* time_us, const uint16_t* counts,
                   const uint8_t* encoder_errors, const uint8_t* solver_ok, const float* wrench,
                   const uint8_t* overrun, const uint16_t* loop_us, int16_t temperature) {
  Sim* s = static_cast<Sim*>(p);
  for (uint32_t k = 0; k < n; ++k) {
    Sample x;
    x.time_us = time_us[k];
    for (int i = 0; i < 6; ++i) {
      x.counts[i] = counts[6 * k + i];
      x.wrench[i] = wrench[6 * k + i];
    }
    x.encoder_errors = encoder_errors[k];
    x.solver_ok = solver_ok[k] != 0;
    x.overrun = overrun[k] != 0;
    x.loop_time_us = loop_us[k];
    x.temperature_centi = temperature;
    if (s->sampled) {
      // The board's main loop serves waiting answers while it idles between samples (the
      // queue drains meanwhile): once here, half way.
      s->hardware.setTime(s->last_sample_us + (x.time_us - s->last_sample_us) / 2);
      s->device.service();
    }
    s->sampled = true;
    s->last_sample_us = x.time_us;
    s->hardware.setTime(x.time_us);
    s->device.onSample(x);
  }
}

uint32_t d6sim_pending(void* p) { return static_cast<Sim*>(p)->hardware.pending(); }
uint32_t d6sim_read(void* p, uint8_t* out, uint32_t cap) {
  return static_cast<Sim*>(p)->hardware.read(out, cap);
}

uint16_t d6sim_rate(void* p) { return static_cast<Sim*>(p)->device.sampleRateHz(); }
uint32_t d6sim_rate_changes(void* p) { return static_cast<Sim*>(p)->hardware.rateChanges(); }
int d6sim_streaming(void* p) { return static_cast<Sim*>(p)->device.streaming() ? 1 : 0; }
uint8_t d6sim_mode(void* p) { return static_cast<Sim*>(p)->device.mode(); }
uint16_t d6sim_status(void* p) { return static_cast<Sim*>(p)->device.persistentStatus(); }
void d6sim_zero_counts(void* p, uint16_t* out) {
  memcpy(out, static_cast<Sim*>(p)->device.zeroCounts(), 12);
}
void d6sim_tare(void* p, float* out) {
  const Config& c = static_cast<Sim*>(p)->device.config();
  for (int i = 0; i < 6; ++i) out[i] = c.tare_active ? c.tare[i] : 0.0f;
}
uint8_t* d6sim_eeprom(void* p) { return static_cast<Sim*>(p)->hardware.eeprom(); }
uint32_t d6sim_eeprom_size() { return delta6::sim::kEepromSize; }
uint32_t d6sim_eeprom_writes(void* p) { return static_cast<Sim*>(p)->hardware.eepromWrites(); }
void d6sim_break_eeprom(void* p, int broken) {
  static_cast<Sim*>(p)->hardware.breakEeprom(broken != 0);
}
uint16_t d6sim_link_limit(void* p, uint8_t mode) {
  return static_cast<Sim*>(p)->device.linkRateLimit(mode);
}
void d6sim_set_max_rate_pipeline(void* p, uint16_t hz) {
  static_cast<Sim*>(p)->identity.max_rate_pipeline_hz = hz;
}
uint32_t d6sim_sizeof_device() { return sizeof(Device); }

// --- the codec pieces, for the cross-language tests -----------------------------------------

uint16_t d6_crc16(const uint8_t* data, uint32_t n) {
  return delta6::crc16(data, static_cast<uint16_t>(n));
}

uint32_t d6_cobs_encode_in_place(uint8_t* buf, uint32_t n) {
  return delta6::cobsEncodeInPlace(buf, static_cast<uint16_t>(n));
}

int32_t d6_cobs_decode_in_place(uint8_t* buf, uint32_t n) {
  return delta6::cobsDecodeInPlace(buf, static_cast<uint16_t>(n));
}

uint32_t d6_record_size(uint8_t type) { return delta6::proto::recordSize(type); }
uint32_t d6_command_size(uint8_t type) { return delta6::proto::commandSize(type); }

uint32_t d6_encode_data(uint8_t* out, uint16_t seq, uint32_t time_us, uint16_t status,
                        const int16_t* wrench, const uint16_t* counts) {
  return delta6::proto::encodeDataRecord(out, seq, time_us, status, wrench, counts);
}

void d6_scale(float full_scale, uint8_t* mantissa, int8_t* exponent) {
  const delta6::proto::Scale s = delta6::proto::scaleForFullScale(full_scale);
  *mantissa = s.mantissa;
  *exponent = s.exponent;
}

int16_t d6_quantize(float value, float inverse_lsb, int* clipped) {
  bool c = false;
  const int16_t q = delta6::proto::quantize(value, inverse_lsb, &c);
  *clipped = c ? 1 : 0;
  return q;
}

// Feed bytes to a fresh command parser. Each completed frame appends one row of 32 bytes to
// out: result, type, request id, size, then size - 2 argument bytes. Returns the row count.
uint32_t d6_parse_commands(const uint8_t* data, uint32_t n, uint8_t* out, uint32_t max_rows) {
  delta6::proto::CommandParser parser;
  uint32_t rows = 0;
  for (uint32_t i = 0; i < n && rows < max_rows; ++i) {
    delta6::proto::Command c;
    const delta6::proto::ParseResult r = parser.feed(data[i], &c);
    if (r == delta6::proto::kParseNone) continue;
    uint8_t* row = out + 32 * rows++;
    memset(row, 0, 32);
    row[0] = static_cast<uint8_t>(r);
    if (r == delta6::proto::kParseCommand) {
      row[1] = c.type;
      row[2] = c.request_id;
      row[3] = c.size;
      memcpy(row + 4, c.args, c.size - 2u);
    }
  }
  return rows;
}

// pipeline: cutoff Hz, tool translation (3), tool rpy (3); null for none (and no limits).
void d6_encode_config(const uint16_t* rate_mode_active, const float* tare, const uint16_t* zero,
                      const float* pipeline, const uint16_t* limits, uint32_t design_hash,
                      uint8_t* blob) {
  Config c;
  memset(&c, 0, sizeof(c));
  if (pipeline) {
    c.filter_hz = pipeline[0];
    for (int i = 0; i < 3; ++i) {
      c.tool_translation[i] = pipeline[1 + i];
      c.tool_rpy[i] = pipeline[4 + i];
    }
  }
  if (limits) memcpy(c.limits, limits, sizeof(c.limits));
  c.rate_hz = rate_mode_active[0];
  c.mode = static_cast<uint8_t>(rate_mode_active[1]);
  c.tare_active = rate_mode_active[2] != 0;
  for (int i = 0; i < 6; ++i) {
    c.tare[i] = tare[i];
    c.zero_counts[i] = zero[i];
  }
  Device::encodeConfig(c, design_hash, blob);
}

}  // extern "C"
