#include "delta6_device.h"

#include <string.h>

#include "delta6_cobs.h"
#include "delta6_crc16.h"
#include "delta6_fastmath.h"
#include "delta6_solver.h"

namespace delta6 {

using namespace proto;

namespace {

using fastmath::is_finite;

// Whether the low-pass cutoff (0: off) can be designed at rate_hz.
bool filterFits(float cutoff_hz, uint16_t rate_hz) {
  return cutoff_hz == 0.0f || lowPassFits(cutoff_hz, static_cast<float>(rate_hz));
}

// |v| <= bound for a finite positive bound, NaN and infinities excluded: the magnitude's bits
// order like the values (an integer compare, no float library calls).
bool withinMagnitude(float v, float bound) {
  return (fastmath::bits_of(v) & 0x7FFFFFFFul) <= fastmath::bits_of(bound);
}

// The index (0..5) of the first translation or angle the device does not accept, or 6.
uint8_t badToolValue(const float translation[3], const float rpy[3]) {
  for (uint8_t i = 0; i < 3; ++i) {
    if (!withinMagnitude(translation[i], kMaxToolTranslation)) return i;
  }
  for (uint8_t i = 0; i < 3; ++i) {
    if (!withinMagnitude(rpy[i], kMaxToolAngle)) return static_cast<uint8_t>(3 + i);
  }
  return 6;
}

}  // namespace

Device::Device(Hardware& hardware, const Identity& identity, const Config& defaults)
    : hw_(hardware),
      id_(identity),
      defaults_(defaults),
      filter_on_(false),
      queue_head_(0),
      queue_count_(0),
      streaming_(false),
      config_problem_(0),
      tx_overflow_(false),
      stream_changed_(false),
      boot_id_(0),
      seq_(0),
      last_status_(0),
      temperature_centi_(kTemperatureUnknown),
      last_telemetry_us_(0),
      averaging_(0),
      averaging_request_(0),
      averaging_target_(0),
      averaging_count_(0) {
  serial_number_ = ident(id_.serial_number);
  memset(&counters_, 0, sizeof(counters_));
  memset(&last_answer_, 0, sizeof(last_answer_));
  memset(&sums_, 0, sizeof(sums_));
  memset(averaging_first_, 0, sizeof(averaging_first_));
  loadDefaults(&config_);
  for (uint8_t i = 0; i < 6; ++i) {
    scale_[i] = scaleForFullScale(ident(id_.full_scale[i]));
    inverse_lsb_[i] = 1.0f / scaleValue(scale_[i]);
  }
  configurePipeline();
}

// --- configuration ------------------------------------------------------------------------

void Device::encodeConfig(const Config& c, uint32_t design_hash, uint8_t* blob) {
  memset(blob, 0, kConfigBlobSize);
  putU16(blob + kConfigOffMagic, kConfigMagic);
  blob[kConfigOffLayout] = kConfigLayoutVersion;
  blob[kConfigOffSize] = kConfigBlobSize;
  putU32(blob + kConfigOffDesignHash, design_hash);
  putU16(blob + kConfigOffRateHz, c.rate_hz);
  blob[kConfigOffMode] = c.mode;
  blob[kConfigOffTareActive] = c.tare_active ? 1 : 0;
  for (uint8_t i = 0; i < 6; ++i) {
    putF32(blob + kConfigOffTare + 4 * i, c.tare[i]);
    putU16(blob + kConfigOffZeroCounts + 2 * i, c.zero_counts[i]);
    putU16(blob + kConfigOffLimits + 2 * i, c.limits[i]);
  }
  putF32(blob + kConfigOffFilterHz, c.filter_hz);
  for (uint8_t i = 0; i < 3; ++i) {
    putF32(blob + kConfigOffToolTranslation + 4 * i, c.tool_translation[i]);
    putF32(blob + kConfigOffToolRpy + 4 * i, c.tool_rpy[i]);
  }
  const uint16_t crc = crc16(blob, kConfigBlobSize - 2);
  blob[kConfigBlobSize - 2] = static_cast<uint8_t>(crc >> 8);
  blob[kConfigBlobSize - 1] = static_cast<uint8_t>(crc);
}

uint8_t Device::decodeConfig(const uint8_t* blob, Config* out) const {
  if (getU16(blob + kConfigOffMagic) != kConfigMagic) return kConfigErased;
  // The previous layout is a prefix of this one (same offsets), without the pipeline fields.
  const bool v1 = blob[kConfigOffLayout] == kConfigLayoutV1 && blob[kConfigOffSize] == kConfigBlobSizeV1;
  if (!v1 && (blob[kConfigOffLayout] != kConfigLayoutVersion ||
              blob[kConfigOffSize] != kConfigBlobSize)) {
    return kConfigBadVersion;
  }
  if (crc16(blob, blob[kConfigOffSize]) != 0) return kConfigBadCrc;
  Config c;
  memset(&c, 0, sizeof(c));  // a layout-1 blob: no filter, identity tool, no limits
  if (!v1) {
    c.filter_hz = getF32(blob + kConfigOffFilterHz);
    for (uint8_t i = 0; i < 3; ++i) {
      c.tool_translation[i] = getF32(blob + kConfigOffToolTranslation + 4 * i);
      c.tool_rpy[i] = getF32(blob + kConfigOffToolRpy + 4 * i);
    }
    for (uint8_t i = 0; i < 6; ++i) {
      c.limits[i] = getU16(blob + kConfigOffLimits + 2 * i);
      if (c.limits[i] > static_cast<uint16_t>(kMaxValue)) return kConfigOutOfRange;
    }
    if (badToolValue(c.tool_translation, c.tool_rpy) < 6) return kConfigOutOfRange;
  }
  const uint16_t saved_rate = getU16(blob + kConfigOffRateHz);
  c.rate_hz = saved_rate;
  c.mode = blob[kConfigOffMode];
  c.tare_active = blob[kConfigOffTareActive] == 1;
  if (saved_rate == 0 || !filterFits(c.filter_hz, saved_rate)) return kConfigOutOfRange;
  if (c.mode != kModeWrench && c.mode != kModeWrenchRaw) return kConfigOutOfRange;
  if (blob[kConfigOffTareActive] > 1) return kConfigOutOfRange;
  // Saved by a faster image (no model, another clock): this one's highest rate, the rest kept.
  // The filter stays on at the lower rate unless its cutoff no longer fits it.
  uint8_t adjusted = 0;
  const bool tool = !toolIsIdentity(c.tool_translation, c.tool_rpy);
  if (saved_rate > maxRate(c.filter_hz != 0.0f || tool)) {
    adjusted = kConfigRateLowered;
    c.rate_hz = maxRate(c.filter_hz != 0.0f || tool);
    if (!filterFits(c.filter_hz, c.rate_hz)) {
      c.filter_hz = 0.0f;
      const uint16_t limit = maxRate(tool);
      c.rate_hz = saved_rate < limit ? saved_rate : limit;
    }
  }
  for (uint8_t i = 0; i < 6; ++i) {
    c.tare[i] = getF32(blob + kConfigOffTare + 4 * i);
    // Any finite offset: the loader accepts every configuration the device can hold.
    if (!is_finite(c.tare[i])) return kConfigOutOfRange;
    c.zero_counts[i] = getU16(blob + kConfigOffZeroCounts + 2 * i);
    if (c.zero_counts[i] >= kCountsPerTurn) return kConfigOutOfRange;
  }
  // Offsets belong to the model they were measured with, limits to its wire scaling; zero
  // counts, the filter and the tool frame are mechanical.
  if (getU32(blob + kConfigOffDesignHash) != ident(id_.design_hash)) {
    c.tare_active = false;
    for (uint8_t i = 0; i < 6; ++i) c.tare[i] = 0.0f;
    for (uint8_t i = 0; i < 6; ++i) c.limits[i] = 0;
  }
  *out = c;
  return adjusted;
}

void Device::setRate(uint16_t rate_hz) {
  if (rate_hz == config_.rate_hz) return;
  config_.rate_hz = rate_hz;
  configurePipeline();  // the filter's coefficients depend on the rate
  hw_.sampleRateChanged(rate_hz);
}

void Device::applyConfig(const Config& c) {
  const uint16_t old_rate = config_.rate_hz;
  config_ = c;
  configurePipeline();
  if (c.rate_hz != old_rate) hw_.sampleRateChanged(c.rate_hz);
}

void Device::configurePipeline() {
  LowPassCoefficients k;
  filter_on_ = config_.filter_hz != 0.0f &&
               designLowPass(config_.filter_hz, static_cast<float>(config_.rate_hz), &k);
  if (filter_on_) filter_.configure(k);
  filter_.reset();
  // Checked where it is set or loaded: a frame that does not make is the identity.
  const float zero[3] = {0.0f, 0.0f, 0.0f};
  if (!makeToolFrame(config_.tool_translation, config_.tool_rpy, &tool_)) {
    makeToolFrame(zero, zero, &tool_);
  }
}

void Device::begin(uint8_t reset_cause, uint16_t boot_id) {
  boot_id_ = boot_id;
  uint8_t blob[kConfigBlobSize];
  hw_.eepromRead(ident(id_.eeprom_address), blob, kConfigBlobSize);
  Config loaded;
  const uint8_t problem = decodeConfig(blob, &loaded);
  config_problem_ = problem;
  if (usingDefaults()) {
    loadDefaults(&config_);
  } else {
    config_ = loaded;  // a lowered rate is said by INFO's config_problem
  }
  configurePipeline();
  hw_.sampleRateChanged(config_.rate_hz);
  answer(kEvent, 0, kEventBoot, 0, reset_cause);
  if (usingDefaults()) answer(kEvent, 0, kEventConfigDefaults, 0, problem);
  answer(kInfo, 0, 0, 0, 0);
  service();
}

void Device::saveConfig(const Command& c) {
  uint8_t blob[kConfigBlobSize];
  encodeConfig(config_, ident(id_.design_hash), blob);
  const uint16_t address = ident(id_.eeprom_address);
  hw_.eepromWrite(address, blob, kConfigBlobSize);
  // Read back byte by byte: a worn or write-protected EEPROM must not be reported as saved.
  for (uint16_t i = 0; i < kConfigBlobSize; ++i) {
    uint8_t b;
    hw_.eepromRead(static_cast<uint16_t>(address + i), &b, 1);
    if (b != blob[i]) {
      nack(c, kNackEepromFailed, i);
      return;
    }
  }
  config_problem_ = 0;
  ack(c, kConfigBlobSize);
}

uint16_t Device::persistentStatus() const {
  uint16_t s = 0;
  if (config_.tare_active) s |= kStatusTareActive;
  if (averaging_) s |= kStatusTareBusy;
  if (usingDefaults()) s |= kStatusConfigDefaults;
  return s;
}

// --- commands -------------------------------------------------------------------------

void Device::onByte(uint8_t byte) {
  Command command;
  switch (parser_.feed(byte, &command)) {
    case kParseCommand:
      execute(command);
      service();
      break;
    case kParseBadFrame:
      ++counters_.rx_bad_frames;
      break;
    case kParseBadCrc:
      ++counters_.rx_crc_errors;
      break;
    case kParseTooLong:
      ++counters_.rx_overflows;
      break;
    default:
      break;
  }
}

uint16_t Device::linkRateLimit(uint8_t mode) const {
  const uint32_t baud = ident(id_.baud);
  if (baud == 0) return 0xFFFF;
  const uint32_t frame = recordSize(mode == kModeWrenchRaw ? kWrenchRaw : kWrench) + kFrameOverhead;
  // 10 bits per byte (start, 8 data, stop); data records may fill 90 % of the link.
  const uint32_t limit = baud / kLinkBudgetDivisor * kLinkBudgetNumerator / frame;
  return limit > 0xFFFF ? 0xFFFF : static_cast<uint16_t>(limit);
}

uint16_t Device::maxRate(bool pipeline) const {
  const uint16_t slower = ident(id_.max_rate_pipeline_hz);
  const uint16_t board = ident(id_.max_rate_hz);
  return pipeline && slower != 0 && slower < board ? slower : board;
}

uint16_t Device::checkRate(uint16_t rate_hz, uint8_t mode, bool pipeline, uint8_t* reason) const {
  const uint16_t board = maxRate(pipeline);
  if (rate_hz > board) {
    *reason = kNackRateTooHigh;
    return board;
  }
  const uint16_t link = linkRateLimit(mode);
  if (rate_hz > link) {
    *reason = kNackLinkTooSlow;
    return link;
  }
  *reason = 0;
  return 0;
}

void Device::execute(const Command& c) {
  if (c.type < kFirstCommand) {
    // A record, not a command: our own output looped back. Never answer it, or a loopback
    // would answer its answers forever.
    ++counters_.rx_bad_frames;
    return;
  }
  ++counters_.rx_frames;
  // A retried request (same id and command) gets the same answer without running twice.
  if (c.request_id != 0 && c.request_id == last_answer_.request_id &&
      c.type == last_answer_.command) {
    answer(last_answer_.kind, last_answer_.request_id, last_answer_.command, last_answer_.code,
           last_answer_.value);
    return;
  }
  if (averaging_ && c.request_id != 0 && c.request_id == averaging_request_ &&
      c.type == averaging_) {
    return;  // still averaging: the answer comes when it is done
  }
  const uint8_t expected = commandSize(c.type);
  if (expected == 0) {
    ++counters_.rx_bad_frames;
    nack(c, kNackUnknownCommand);
    return;
  }
  if (c.size != expected) {
    ++counters_.rx_bad_frames;
    nack(c, kNackBadLength, expected);
    return;
  }
  const bool busy = averaging_ != 0;
  switch (c.type) {
    case kCmdGetInfo:
      answer(kInfo, c.request_id, c.type, 0, 0);
      break;
    case kCmdGetTelemetry:
      answer(kTelemetry, c.request_id, c.type, 0, 0);
      break;
    case kCmdPing:
      ack(c, hw_.micros());
      break;
    case kCmdStart: {
      uint16_t rate = getU16(c.args);
      if (rate == 0) rate = config_.rate_hz;
      uint8_t reason;
      const uint16_t limit = checkRate(rate, config_.mode, pipelineOn(), &reason);
      if (reason) {
        nack(c, reason, limit);
        break;
      }
      if (!filterFits(config_.filter_hz, rate)) {
        nack(c, kNackFilterRange, rate);
        break;
      }
      setRate(rate);
      if (!streaming_) {   // the first periodic record covers the stream, not the idle time
        last_telemetry_us_ = hw_.micros();
        counters_.loop_time_max_us = 0;
        counters_.loop_time_sum_us = 0;
        counters_.loop_time_samples = 0;
      }
      streaming_ = true;
      stream_changed_ = true;
      ack(c, rate);
      break;
    }
    case kCmdStop:
      streaming_ = false;
      ack(c, 0);
      break;
    case kCmdSetMode: {
      const uint8_t mode = c.args[0];
      if (mode != kModeWrench && mode != kModeWrenchRaw) {
        nack(c, kNackBadArgument, mode);
        break;
      }
      uint8_t reason;
      const uint16_t limit = checkRate(config_.rate_hz, mode, pipelineOn(), &reason);
      if (streaming_ && reason) {
        nack(c, reason, limit);
        break;
      }
      config_.mode = mode;
      stream_changed_ = true;
      ack(c, mode);
      break;
    }
    case kCmdTare:
    case kCmdZeroHere: {
      const uint16_t n = getU16(c.args);
      if (busy) {
        nack(c, kNackBusy);
      } else if (n == 0) {
        nack(c, kNackBadArgument, 0);
      } else {
        startAveraging(c, n);
      }
      break;
    }
    case kCmdClearTare:
      if (busy) {
        nack(c, kNackBusy);
        break;
      }
      config_.tare_active = false;
      for (uint8_t i = 0; i < 6; ++i) config_.tare[i] = 0.0f;
      stream_changed_ = true;
      ack(c, 0);
      break;
    case kCmdSetZero: {
      if (busy) {
        nack(c, kNackBusy);
        break;
      }
      uint16_t counts[6];
      uint8_t bad = 6;   // the first count beyond the turn, if any: the NACK's detail
      for (uint8_t i = 0; i < 6; ++i) {
        counts[i] = getU16(c.args + 2 * i);
        if (counts[i] >= kCountsPerTurn && bad == 6) bad = i;
      }
      if (bad != 6) {
        nack(c, kNackBadArgument, counts[bad]);
        break;
      }
      // Offsets measured against other zero counts mean nothing now.
      config_.tare_active = false;
      for (uint8_t i = 0; i < 6; ++i) {
        config_.zero_counts[i] = counts[i];
        config_.tare[i] = 0.0f;
      }
      filter_.reset();  // the wrench jumps: start from the new level, no step response
      stream_changed_ = true;
      ack(c, 0);
      break;
    }
    case kCmdSaveConfig:
      if (busy) {
        nack(c, kNackBusy);
      } else {
        saveConfig(c);
      }
      break;
    case kCmdLoadDefaults:
      if (busy) {
        nack(c, kNackBusy);
        break;
      }
      {
        Config defaults;
        loadDefaults(&defaults);
        applyConfig(defaults);
      }
      stream_changed_ = true;
      ack(c, 0);
      break;
    case kCmdSetFilter:
    case kCmdSetTool:
      if (busy) {
        nack(c, kNackBusy);  // a tare averages the pipeline's output: keep it fixed meanwhile
      } else if (c.type == kCmdSetFilter) {
        setFilter(c);
      } else {
        setTool(c);
      }
      break;
    case kCmdSetLimits:
      setLimits(c);
      break;
    case kCmdAbort:
      // Ends a tare or zero capture that would keep the device busy (65535 samples take
      // minutes): it is answered NACK ABORTED, nothing changed; ACK 1 if one ran, 0 if not.
      if (averaging_) {
        const uint8_t command = averaging_;
        averaging_ = 0;
        answer(kNack, averaging_request_, command, kNackAborted, 0);
        ack(c, 1);
      } else {
        ack(c, 0);
      }
      break;
    default:
      nack(c, kNackUnknownCommand);
      break;
  }
}

void Device::setFilter(const Command& c) {
  const float cutoff = getF32(c.args);
  if (!filterFits(cutoff, config_.rate_hz)) {
    nack(c, kNackFilterRange, config_.rate_hz);
    return;
  }
  if (cutoff != 0.0f && config_.rate_hz > maxRate(true)) {
    nack(c, kNackRateTooHigh, maxRate(true));  // the board cannot filter at this rate
    return;
  }
  config_.filter_hz = cutoff;
  configurePipeline();
  stream_changed_ = true;
  ack(c, 0);
}

void Device::setTool(const Command& c) {
  float translation[3], rpy[3];
  for (uint8_t i = 0; i < 3; ++i) {
    translation[i] = getF32(c.args + 4 * i);
    rpy[i] = getF32(c.args + 12 + 4 * i);
  }
  const uint8_t bad = badToolValue(translation, rpy);
  if (bad < 6) {
    nack(c, kNackBadArgument, bad);
    return;
  }
  if (!toolIsIdentity(translation, rpy) && config_.rate_hz > maxRate(true)) {
    nack(c, kNackRateTooHigh, maxRate(true));  // the board cannot transform at this rate
    return;
  }
  // The tare is a wrench in the reporting frame: the same physical offset, re-expressed
  // (back to {E} with the old frame, into the new one). No second ToolFrame on the stack.
  if (config_.tare_active) unapplyToolFrame(tool_, config_.tare);
  makeToolFrame(translation, rpy, &tool_);
  if (config_.tare_active) applyToolFrame(tool_, config_.tare);
  for (uint8_t i = 0; i < 3; ++i) {
    config_.tool_translation[i] = translation[i];
    config_.tool_rpy[i] = rpy[i];
  }
  stream_changed_ = true;
  ack(c, 0);
}

void Device::setLimits(const Command& c) {
  uint16_t limits[6];
  for (uint8_t i = 0; i < 6; ++i) {
    limits[i] = getU16(c.args + 2 * i);
    if (limits[i] > static_cast<uint16_t>(kMaxValue)) {
      nack(c, kNackBadArgument, limits[i]);
      return;
    }
  }
  for (uint8_t i = 0; i < 6; ++i) config_.limits[i] = limits[i];
  ack(c, 0);
}

void Device::startAveraging(const Command& c, uint16_t samples) {
  averaging_ = c.type;
  averaging_request_ = c.request_id;
  averaging_target_ = samples;
  averaging_count_ = 0;
  memset(&sums_, 0, sizeof(sums_));
}

void Device::accumulate(const float* wrench, const Sample& s, uint16_t status) {
  const uint16_t bad = averaging_ == kCmdTare ? kStatusWrenchInvalid : kStatusEncoderMask;
  if (status & bad) {
    // An average over flagged samples would be a made-up offset: give up and say why.
    const uint8_t command = averaging_;
    averaging_ = 0;
    answer(kNack, averaging_request_, command, kNackFaultDuringAveraging, status);
    return;
  }
  for (uint8_t i = 0; i < 6; ++i) {
    if (averaging_ == kCmdTare) {
      sums_.wrench[i] += wrench[i];
    } else {
      if (averaging_count_ == 0) averaging_first_[i] = s.counts[i];
      sums_.counts[i] += wrap_count_delta(s.counts[i], averaging_first_[i]);
    }
  }
  if (++averaging_count_ >= averaging_target_) finishAveraging();
}

void Device::finishAveraging() {
  const float n = static_cast<float>(averaging_count_);
  const uint8_t command = averaging_;
  averaging_ = 0;
  if (command == kCmdTare) {
    for (uint8_t i = 0; i < 6; ++i) {
      if (!is_finite(sums_.wrench[i] / n)) {  // the sum overflowed: no such offset
        answer(kNack, averaging_request_, command, kNackFaultDuringAveraging, kStatusOverrange);
        return;
      }
    }
  }
  for (uint8_t i = 0; i < 6; ++i) {
    if (command == kCmdTare) {
      config_.tare[i] = sums_.wrench[i] / n;
    } else {
      // Mean offset from the first sample, rounded half away from zero.
      const int32_t sum = sums_.counts[i];
      const int32_t half = static_cast<int32_t>(averaging_count_ / 2);
      const int32_t mean = sum >= 0 ? (sum + half) / static_cast<int32_t>(averaging_count_)
                                    : -((-sum + half) / static_cast<int32_t>(averaging_count_));
      config_.zero_counts[i] =
          static_cast<uint16_t>((averaging_first_[i] + mean) & (kCountsPerTurn - 1));
      config_.tare[i] = 0.0f;
    }
  }
  // New zero counts: the wrench jumps, start from the new level as SET_ZERO does.
  if (command != kCmdTare) filter_.reset();
  config_.tare_active = command == kCmdTare;
  stream_changed_ = true;
  answer(kAck, averaging_request_, command, 0, averaging_count_);
}

// --- answers ----------------------------------------------------------------------------

void Device::answer(uint8_t kind, uint8_t request_id, uint8_t command, uint8_t code,
                    uint32_t value) {
  Response r = {kind, request_id, command, code, value};
  if (request_id != 0 && (kind == kAck || kind == kNack || kind == kInfo || kind == kTelemetry)) {
    last_answer_ = r;
  }
  if (queue_count_ >= kQueueLength) {
    ++counters_.responses_dropped;  // the host times out and retries
    return;
  }
  queue_[(queue_head_ + queue_count_) % kQueueLength] = r;
  ++queue_count_;
}

void Device::service() {
  while (queue_count_ > 0) {
    const Response& r = queue_[queue_head_];
    const uint16_t size = recordSize(r.kind) + kFrameOverhead;
    if (hw_.txSpace() < size) return;
    if (r.kind == kInfo) {
      sendInfo(r.request_id);
    } else {
      hw_.txWrite(tx_, buildResponse(r));
    }
    queue_head_ = static_cast<uint8_t>((queue_head_ + 1) % kQueueLength);
    --queue_count_;
  }
}

uint16_t Device::buildResponse(const Response& r) {
  uint8_t* p = tx_ + 1;
  switch (r.kind) {
    case kTelemetry:
      return buildTelemetry(r.request_id);
    case kEvent:
      p[kEventOffType] = kEvent;
      p[kEventOffCode] = r.command;
      putU32(p + kEventOffArg, r.value);
      return finishFrame(tx_, kEventSize);
    case kNack:
      p[kNackOffType] = kNack;
      p[kNackOffRequestId] = r.request_id;
      p[kNackOffCommand] = r.command;
      p[kNackOffReason] = r.code;
      putU32(p + kNackOffDetail, r.value);
      return finishFrame(tx_, kNackSize);
    default:
      p[kAckOffType] = kAck;
      p[kAckOffRequestId] = r.request_id;
      p[kAckOffCommand] = r.command;
      putU32(p + kAckOffValue, r.value);
      return finishFrame(tx_, kAckSize);
  }
}

// INFO goes out in pieces that end just before the last byte of a name field, which is always
// a NUL (a name has at most k...NameBytes - 1 characters). COBS never carries a block across
// a zero byte, so each piece COBS-encodes alone to exactly its part of the whole frame, the
// NUL between two pieces being the boundary of their encodings. The largest piece, not the
// record, is on the stack while INFO is sent.
namespace {
const uint8_t kInfoEnd0 = kInfoOffDesignName + kInfoDesignNameBytes - 1;
const uint8_t kInfoEnd1 = kInfoOffCalibrationName + kInfoCalibrationNameBytes - 1;
const uint8_t kInfoEnd2 = kInfoOffModelName + kInfoModelNameBytes - 1;
const uint8_t kInfoPieces = 4;
uint8_t infoPieceEnd(uint8_t piece) {
  return piece == 0 ? kInfoEnd0 : piece == 1 ? kInfoEnd1 : piece == 2 ? kInfoEnd2 : kInfoSize;
}
// The fields each piece writes lie within it (buildInfoPiece): the layout's order.
static_assert(kInfoOffDesignName + kInfoDesignNameBytes == kInfoOffFullScale &&
                  kInfoOffCalibrationName + kInfoCalibrationNameBytes == kInfoOffBootId &&
                  kInfoOffModelName + kInfoModelNameBytes == kInfoOffFilterHz,
              "INFO's pieces end at its name fields");
static_assert(kInfoOffType < kInfoOffDesignName && kInfoOffMode < kInfoOffDesignName &&
                  kInfoOffDesignHash < kInfoOffDesignName && kInfoOffFirmware < kInfoOffDesignName &&
                  kInfoOffJointLimitRad < kInfoOffCalibrationName &&
                  kInfoOffCalibrationHash < kInfoOffCalibrationName &&
                  kInfoOffTare < kInfoOffCalibrationName && kInfoOffModelHash < kInfoOffModelName &&
                  kInfoOffMaxRatePipelineHz > kInfoOffLimits,
              "each INFO field lies in the piece that writes it");
const uint8_t kInfoLargestPiece = kInfoEnd1 - kInfoEnd0 - 1;
static_assert(kInfoEnd0 <= kInfoLargestPiece && kInfoEnd2 - kInfoEnd1 - 1 <= kInfoLargestPiece &&
                  kInfoSize - kInfoEnd2 - 1 + 2 <= kInfoLargestPiece,
              "the buffer holds every piece (the last with the CRC)");

// At most field_bytes - 1 characters of s (null: none), from p on.
void putName(uint8_t* p, const char* s, uint8_t field_bytes) {
  for (uint8_t i = 0; s && i + 1 < field_bytes && s[i]; ++i) p[i] = static_cast<uint8_t>(s[i]);
}
}  // namespace

void Device::sendInfo(uint8_t request_id) {
  uint8_t buf[1 + kInfoLargestPiece];  // a COBS code byte, then the piece
  uint16_t crc = kCrc16Init;
  uint8_t start = 0;
  for (uint8_t piece = 0; piece < kInfoPieces; ++piece) {
    const uint8_t end = infoPieceEnd(piece);
    uint8_t* p = buf + 1;
    uint8_t n = static_cast<uint8_t>(end - start);
    memset(p, 0, n);
    buildInfoPiece(request_id, piece, p);
    crc = crc16(p, n, crc);
    if (piece + 1 < kInfoPieces) {
      crc = crc16Update(crc, 0);  // the name's NUL between this piece and the next
    } else {
      p[n++] = static_cast<uint8_t>(crc >> 8);
      p[n++] = static_cast<uint8_t>(crc);
    }
    hw_.txWrite(buf, cobsEncodeInPlace(buf, n));
    start = static_cast<uint8_t>(end + 1);
  }
  const uint8_t delimiter = 0;
  hw_.txWrite(&delimiter, 1);
}

void Device::buildInfoPiece(uint8_t request_id, uint8_t piece, uint8_t* p) const {
  // p holds the piece from its first byte on: the field at offset o is at b(o) = p + (o - base),
  // an index into the piece (p - base would point before the buffer).
  // Identity fields one by one from flash (a copy of the whole would deepen the stack).
  switch (piece) {
    case 0:
      p[kInfoOffType] = kInfo;
      p[kInfoOffRequestId] = request_id;
      p[kInfoOffProtocol] = kVersionMajor;
      p[kInfoOffProtocol + 1] = kVersionMinor;
      for (uint8_t i = 0; i < 3; ++i) p[kInfoOffFirmware + i] = ident(id_.firmware_version[i]);
      p[kInfoOffMode] = config_.mode;
      putU32(p + kInfoOffDesignHash, ident(id_.design_hash));
      putName(p + kInfoOffDesignName, ident(id_.design_name), kInfoDesignNameBytes);
      break;
    case 1: {
      const auto b = [p](uint8_t offset) { return p + (offset - kInfoOffFullScale); };
      for (uint8_t i = 0; i < 6; ++i) {
        putF32(b(kInfoOffFullScale + 4 * i), ident(id_.full_scale[i]));
        *b(kInfoOffLsbMantissa + i) = scale_[i].mantissa;
        *b(kInfoOffLsbExponent + i) = static_cast<uint8_t>(scale_[i].exponent);
        putU16(b(kInfoOffZeroCounts + 2 * i), config_.zero_counts[i]);
        putF32(b(kInfoOffTare + 4 * i), config_.tare[i]);
      }
      putU16(b(kInfoOffRateHz), config_.rate_hz);
      putU16(b(kInfoOffMaxRateHz), ident(id_.max_rate_hz));
      putU16(b(kInfoOffStatus), persistentStatus());
      *b(kInfoOffStreaming) = streaming_ ? 1 : 0;
      *b(kInfoOffConfigProblem) = config_problem_;
      putU32(b(kInfoOffBaud), ident(id_.baud));
      putU32(b(kInfoOffSerialNumber), serial_number_);
      putF32(b(kInfoOffJointLimitRad), ident(id_.joint_limit_rad));
      putU32(b(kInfoOffCalibrationHash), ident(id_.calibration_hash));
      putName(b(kInfoOffCalibrationName), ident(id_.calibration_name), kInfoCalibrationNameBytes);
      break;
    }
    case 2: {
      const auto b = [p](uint8_t offset) { return p + (offset - kInfoOffBootId); };
      putU16(b(kInfoOffBootId), boot_id_);
      putU32(b(kInfoOffModelHash), ident(id_.model_hash));
      putName(b(kInfoOffModelName), ident(id_.model_name), kInfoModelNameBytes);
      break;
    }
    default: {
      const auto b = [p](uint8_t offset) { return p + (offset - kInfoOffFilterHz); };
      putF32(b(kInfoOffFilterHz), filter_on_ ? config_.filter_hz : 0.0f);
      for (uint8_t i = 0; i < 3; ++i) {
        putF32(b(kInfoOffToolTranslation + 4 * i), config_.tool_translation[i]);
        putF32(b(kInfoOffToolRpy + 4 * i), config_.tool_rpy[i]);
      }
      for (uint8_t i = 0; i < 6; ++i) putU16(b(kInfoOffLimits + 2 * i), config_.limits[i]);
      putU16(b(kInfoOffMaxRatePipelineHz), maxRate(true));
      break;
    }
  }
}

uint16_t Device::buildTelemetry(uint8_t request_id) {
  uint8_t* p = tx_ + 1;
  const Counters& k = counters_;
  p[kTelemetryOffType] = kTelemetry;
  p[kTelemetryOffRequestId] = request_id;
  putU32(p + kTelemetryOffTimeUs, hw_.micros());
  putU16(p + kTelemetryOffStatus, static_cast<uint16_t>(last_status_ | persistentStatus()));
  putU32(p + kTelemetryOffSamples, k.samples);
  putU16(p + kTelemetryOffOverruns, k.overruns);
  for (uint8_t i = 0; i < 6; ++i) putU16(p + kTelemetryOffEncoderErrors + 2 * i, k.encoder_errors[i]);
  putU16(p + kTelemetryOffSolverErrors, k.solver_errors);
  putU16(p + kTelemetryOffRxFrames, k.rx_frames);
  putU16(p + kTelemetryOffRxCrcErrors, k.rx_crc_errors);
  putU16(p + kTelemetryOffRxBadFrames, k.rx_bad_frames);
  putU16(p + kTelemetryOffRxOverflows, k.rx_overflows);
  putU16(p + kTelemetryOffTxDropped, k.tx_dropped);
  putU16(p + kTelemetryOffResponsesDropped, k.responses_dropped);
  putU16(p + kTelemetryOffLoopTimeMaxUs, k.loop_time_max_us);
  const uint32_t mean = k.loop_time_samples ? k.loop_time_sum_us / k.loop_time_samples : 0;
  putU16(p + kTelemetryOffLoopTimeMeanUs, static_cast<uint16_t>(mean > 0xFFFF ? 0xFFFF : mean));
  putU16(p + kTelemetryOffTemperatureCenti, static_cast<uint16_t>(temperature_centi_));
  putU16(p + kTelemetryOffNextSeq, seq_);
  putU16(p + kTelemetryOffBootId, boot_id_);
  if (request_id == 0) {  // the periodic record closes the loop-time window
    counters_.loop_time_max_us = 0;
    counters_.loop_time_sum_us = 0;
    counters_.loop_time_samples = 0;
  }
  return finishFrame(tx_, kTelemetrySize);
}

// --- samples ----------------------------------------------------------------------------

void Device::onSample(const Sample& s) {
  Counters& k = counters_;
  ++k.samples;
  temperature_centi_ = s.temperature_centi;
  if (s.loop_time_us > k.loop_time_max_us) k.loop_time_max_us = s.loop_time_us;
  if (k.loop_time_samples == 0xFFFFu) {
    // A window left open this long (stopped: no periodic record closes it) keeps its mean by
    // halving its weight; 65,535 loop times of at most 65,535 us fit the 32-bit sum.
    k.loop_time_sum_us >>= 1;
    k.loop_time_samples >>= 1;
  }
  k.loop_time_sum_us += s.loop_time_us;
  ++k.loop_time_samples;

  uint16_t status = s.encoder_errors & kStatusEncoderMask;
  const int16_t joint_limit = ident(id_.joint_limit_counts);
  for (uint8_t j = 0; j < 6; ++j) {
    if (status & (1u << j)) {
      ++k.encoder_errors[j];
    } else if (joint_limit > 0) {
      const int16_t d = wrap_count_delta(s.counts[j], config_.zero_counts[j]);
      if (d > joint_limit || d < -joint_limit) status |= kStatusJointLimit;
    }
  }
  if (s.overrun) {
    status |= kStatusLoopOverrun;
    ++k.overruns;
  }
  // The pipeline: low-pass, tool frame (tare and quantisation below). Every valid sample
  // goes through the filter, streaming or not, so its state is current when a stream or a
  // tare starts; a sample without a wrench leaves the filter as it was.
  float w[6];
  for (uint8_t i = 0; i < 6; ++i) w[i] = s.wrench[i];
  bool valid = (status & kStatusEncoderMask) == 0;
  if (valid) {
    bool finite = s.solver_ok;
    for (uint8_t i = 0; i < 6 && finite; ++i) finite = is_finite(w[i]);
    if (finite) {
      if (filter_on_) filter_.apply(w);
      applyToolFrame(tool_, w);
      // A huge but finite wrench can overflow on the way: no value, and a filter that
      // would carry the infinity forever starts again.
      for (uint8_t i = 0; i < 6 && finite; ++i) finite = is_finite(w[i]);
      if (!finite) filter_.reset();
    }
    if (!finite) {
      status |= kStatusSolverError;
      ++k.solver_errors;
      valid = false;
    }
  }
  if (!valid) status |= kStatusWrenchInvalid;
  if (averaging_) accumulate(w, s, status);
  last_status_ = status;

  service();
  if (streaming_) {
    // Quantised only when sent: about 400 AVR cycles per axis saved while stopped.
    int16_t wrench[6];
    // OVERRANGE: an axis clipped at the wire's range or outside its overload limit.
    bool over = false;
    for (uint8_t i = 0; i < 6; ++i) {
      if (!valid) {
        wrench[i] = kInvalidValue;
        continue;
      }
      const float v = config_.tare_active ? w[i] - config_.tare[i] : w[i];
      const int16_t q = quantize(v, inverse_lsb_[i], &over);
      wrench[i] = q;
      // Over the threshold: |q| > limit, in counts, so exact at the threshold.
      const uint16_t limit = config_.limits[i];
      if (limit != 0 && (q > static_cast<int16_t>(limit) || q < -static_cast<int16_t>(limit))) {
        over = true;
      }
    }
    if (over) status |= kStatusOverrange;
    last_status_ = status;
    sendData(s, static_cast<uint16_t>(status | persistentStatus()), wrench);
    if (s.time_us - last_telemetry_us_ >= kTelemetryPeriodUs) {
      last_telemetry_us_ = s.time_us;
      answer(kTelemetry, 0, 0, 0, 0);
      service();
    }
  }
}

void Device::sendData(const Sample& s, uint16_t status, const int16_t* wrench) {
  const bool raw = config_.mode == kModeWrenchRaw;
  const uint16_t size = recordSize(raw ? kWrenchRaw : kWrench) + kFrameOverhead;
  const uint16_t seq = seq_++;
  // Answers go first: while one waits for space, data records give way (counted, and seen
  // by the host as a sequence gap), so commands are answered even on a saturated link.
  if (queue_count_ > 0 || hw_.txSpace() < size) {
    ++counters_.tx_dropped;
    tx_overflow_ = true;
    return;
  }
  if (tx_overflow_) status |= kStatusTxOverflow;
  tx_overflow_ = false;
  // The first record sent since a command changed what records mean (dropped ones pass the
  // mark on): every record before it predates the change.
  if (stream_changed_) status |= kStatusStreamChanged;
  stream_changed_ = false;
  const uint16_t n = encodeDataRecord(tx_, seq, s.time_us, status, wrench,
                                      raw ? s.counts : static_cast<const uint16_t*>(0));
  hw_.txWrite(tx_, n);
}

}  // namespace delta6
