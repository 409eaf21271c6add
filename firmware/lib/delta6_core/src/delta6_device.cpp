#include "delta6_device.h"

#include <string.h>

#include "delta6_crc16.h"
#include "delta6_fastmath.h"
#include "delta6_solver.h"

namespace delta6 {

using namespace proto;

namespace {

using fastmath::is_finite;

}  // namespace

Device::Device(Hardware& hardware, const Identity& identity, const Config& defaults)
    : hw_(hardware),
      id_(identity),
      defaults_(defaults),
      queue_head_(0),
      queue_count_(0),
      streaming_(false),
      config_defaults_(false),
      tx_overflow_(false),
      seq_(0),
      last_status_(0),
      temperature_centi_(kTemperatureUnknown),
      last_telemetry_us_(0),
      averaging_(0),
      averaging_request_(0),
      averaging_target_(0),
      averaging_count_(0) {
  memset(&counters_, 0, sizeof(counters_));
  memset(&last_answer_, 0, sizeof(last_answer_));
  memset(&sums_, 0, sizeof(sums_));
  config_ = defaults;
  for (uint8_t i = 0; i < 6; ++i) {
    scale_[i] = scaleForFullScale(id_.full_scale[i]);
    inverse_lsb_[i] = 1.0f / scaleValue(scale_[i]);
  }
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
  }
  const uint16_t crc = crc16(blob, kConfigBlobSize - 2);
  blob[kConfigBlobSize - 2] = static_cast<uint8_t>(crc >> 8);
  blob[kConfigBlobSize - 1] = static_cast<uint8_t>(crc);
}

uint8_t Device::decodeConfig(const uint8_t* blob, Config* out) const {
  if (getU16(blob + kConfigOffMagic) != kConfigMagic) return kConfigErased;
  if (blob[kConfigOffLayout] != kConfigLayoutVersion || blob[kConfigOffSize] != kConfigBlobSize) {
    return kConfigBadVersion;
  }
  if (crc16(blob, kConfigBlobSize) != 0) return kConfigBadCrc;
  Config c;
  c.rate_hz = getU16(blob + kConfigOffRateHz);
  c.mode = blob[kConfigOffMode];
  c.tare_active = blob[kConfigOffTareActive] == 1;
  if (c.rate_hz == 0 || c.rate_hz > id_.max_rate_hz) return kConfigOutOfRange;
  if (c.mode != kModeWrench && c.mode != kModeWrenchRaw) return kConfigOutOfRange;
  if (blob[kConfigOffTareActive] > 1) return kConfigOutOfRange;
  for (uint8_t i = 0; i < 6; ++i) {
    const uint32_t bits = getU32(blob + kConfigOffTare + 4 * i);
    memcpy(&c.tare[i], &bits, 4);
    // Any finite offset: the loader accepts every configuration the device can hold.
    if (!is_finite(c.tare[i])) return kConfigOutOfRange;
    c.zero_counts[i] = getU16(blob + kConfigOffZeroCounts + 2 * i);
    if (c.zero_counts[i] >= kCountsPerTurn) return kConfigOutOfRange;
  }
  // Offsets belong to the model they were measured with; zero counts are mechanical.
  if (getU32(blob + kConfigOffDesignHash) != id_.design_hash) {
    c.tare_active = false;
    for (uint8_t i = 0; i < 6; ++i) c.tare[i] = 0.0f;
  }
  *out = c;
  return 0;
}

void Device::setRate(uint16_t rate_hz) {
  if (rate_hz == config_.rate_hz) return;
  config_.rate_hz = rate_hz;
  hw_.sampleRateChanged(rate_hz);
}

void Device::applyConfig(const Config& c) {
  const uint16_t old_rate = config_.rate_hz;
  config_ = c;
  if (c.rate_hz != old_rate) hw_.sampleRateChanged(c.rate_hz);
}

void Device::begin(uint8_t reset_cause) {
  uint8_t blob[kConfigBlobSize];
  hw_.eepromRead(id_.eeprom_address, blob, kConfigBlobSize);
  Config loaded;
  const uint8_t problem = decodeConfig(blob, &loaded);
  config_defaults_ = problem != 0;
  config_ = problem ? defaults_ : loaded;
  hw_.sampleRateChanged(config_.rate_hz);
  answer(kEvent, 0, kEventBoot, 0, reset_cause);
  if (problem) answer(kEvent, 0, kEventConfigDefaults, 0, problem);
  answer(kInfo, 0, 0, 0, 0);
  service();
}

void Device::saveConfig(const Command& c) {
  uint8_t blob[kConfigBlobSize];
  encodeConfig(config_, id_.design_hash, blob);
  hw_.eepromWrite(id_.eeprom_address, blob, kConfigBlobSize);
  // Read back byte by byte: a worn or write-protected EEPROM must not be reported as saved.
  for (uint16_t i = 0; i < kConfigBlobSize; ++i) {
    uint8_t b;
    hw_.eepromRead(static_cast<uint16_t>(id_.eeprom_address + i), &b, 1);
    if (b != blob[i]) {
      nack(c, kNackEepromFailed, i);
      return;
    }
  }
  config_defaults_ = false;
  ack(c, kConfigBlobSize);
}

uint16_t Device::persistentStatus() const {
  uint16_t s = 0;
  if (config_.tare_active) s |= kStatusTareActive;
  if (averaging_) s |= kStatusTareBusy;
  if (config_defaults_) s |= kStatusConfigDefaults;
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
  if (id_.baud == 0) return 0xFFFF;
  const uint32_t frame = recordSize(mode == kModeWrenchRaw ? kWrenchRaw : kWrench) + kFrameOverhead;
  // 10 bits per byte (start, 8 data, stop); data records may fill 90 % of the link.
  const uint32_t limit = id_.baud / kLinkBudgetDivisor * kLinkBudgetNumerator / frame;
  return limit > 0xFFFF ? 0xFFFF : static_cast<uint16_t>(limit);
}

uint16_t Device::checkRate(uint16_t rate_hz, uint8_t mode, uint8_t* reason) const {
  if (rate_hz > id_.max_rate_hz) {
    *reason = kNackRateTooHigh;
    return id_.max_rate_hz;
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
      const uint16_t limit = checkRate(rate, config_.mode, &reason);
      if (reason) {
        nack(c, reason, limit);
        break;
      }
      setRate(rate);
      if (!streaming_) last_telemetry_us_ = hw_.micros();
      streaming_ = true;
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
      const uint16_t limit = checkRate(config_.rate_hz, mode, &reason);
      if (streaming_ && reason) {
        nack(c, reason, limit);
        break;
      }
      config_.mode = mode;
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
      ack(c, 0);
      break;
    case kCmdSetZero: {
      if (busy) {
        nack(c, kNackBusy);
        break;
      }
      uint16_t counts[6];
      bool ok = true;
      for (uint8_t i = 0; i < 6; ++i) {
        counts[i] = getU16(c.args + 2 * i);
        if (counts[i] >= kCountsPerTurn) ok = false;
      }
      if (!ok) {
        nack(c, kNackBadArgument);
        break;
      }
      // Offsets measured against other zero counts mean nothing now.
      config_.tare_active = false;
      for (uint8_t i = 0; i < 6; ++i) {
        config_.zero_counts[i] = counts[i];
        config_.tare[i] = 0.0f;
      }
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
      applyConfig(defaults_);
      ack(c, 0);
      break;
    default:
      nack(c, kNackUnknownCommand);
      break;
  }
}

void Device::startAveraging(const Command& c, uint16_t samples) {
  averaging_ = c.type;
  averaging_request_ = c.request_id;
  averaging_target_ = samples;
  averaging_count_ = 0;
  memset(&sums_, 0, sizeof(sums_));
}

void Device::accumulate(const Sample& s, uint16_t status) {
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
      sums_.wrench[i] += s.wrench[i];
    } else {
      sums_.counts[i] += wrap_count_delta(s.counts[i], config_.zero_counts[i]);
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
      // Mean offset from the old zero, rounded half away from zero.
      const int32_t sum = sums_.counts[i];
      const int32_t half = static_cast<int32_t>(averaging_count_ / 2);
      const int32_t mean = sum >= 0 ? (sum + half) / static_cast<int32_t>(averaging_count_)
                                    : -((-sum + half) / static_cast<int32_t>(averaging_count_));
      config_.zero_counts[i] =
          static_cast<uint16_t>((config_.zero_counts[i] + mean) & (kCountsPerTurn - 1));
      config_.tare[i] = 0.0f;
    }
  }
  config_.tare_active = command == kCmdTare;
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
    const uint16_t n = buildResponse(r);
    hw_.txWrite(tx_, n);
    queue_head_ = static_cast<uint8_t>((queue_head_ + 1) % kQueueLength);
    --queue_count_;
  }
}

uint16_t Device::buildResponse(const Response& r) {
  uint8_t* p = tx_ + 1;
  switch (r.kind) {
    case kInfo:
      return buildInfo(r.request_id);
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

uint16_t Device::buildInfo(uint8_t request_id) {
  uint8_t* p = tx_ + 1;
  memset(p, 0, kInfoSize);
  p[kInfoOffType] = kInfo;
  p[kInfoOffRequestId] = request_id;
  p[kInfoOffProtocol] = kVersionMajor;
  p[kInfoOffProtocol + 1] = kVersionMinor;
  p[kInfoOffFirmware] = id_.firmware_version[0];
  p[kInfoOffFirmware + 1] = id_.firmware_version[1];
  p[kInfoOffFirmware + 2] = id_.firmware_version[2];
  p[kInfoOffMode] = config_.mode;
  putU32(p + kInfoOffDesignHash, id_.design_hash);
  // At most kInfoDesignNameBytes - 1 characters: the field always ends in a NUL.
  for (uint8_t i = 0; i < kInfoDesignNameBytes - 1 && id_.design_name && id_.design_name[i]; ++i) {
    p[kInfoOffDesignName + i] = static_cast<uint8_t>(id_.design_name[i]);
  }
  for (uint8_t i = 0; i < 6; ++i) {
    putF32(p + kInfoOffFullScale + 4 * i, id_.full_scale[i]);
    p[kInfoOffLsbMantissa + i] = scale_[i].mantissa;
    p[kInfoOffLsbExponent + i] = static_cast<uint8_t>(scale_[i].exponent);
    putU16(p + kInfoOffZeroCounts + 2 * i, config_.zero_counts[i]);
    putF32(p + kInfoOffTare + 4 * i, config_.tare[i]);
  }
  putU16(p + kInfoOffRateHz, config_.rate_hz);
  putU16(p + kInfoOffMaxRateHz, id_.max_rate_hz);
  putU16(p + kInfoOffStatus, persistentStatus());
  p[kInfoOffStreaming] = streaming_ ? 1 : 0;
  putU32(p + kInfoOffBaud, id_.baud);
  putU32(p + kInfoOffSerialNumber, id_.serial_number);
  putF32(p + kInfoOffJointLimitRad, id_.joint_limit_rad);
  putU32(p + kInfoOffCalibrationHash, id_.calibration_hash);
  for (uint8_t i = 0; i < kInfoCalibrationNameBytes - 1 && id_.calibration_name &&
                      id_.calibration_name[i]; ++i) {
    p[kInfoOffCalibrationName + i] = static_cast<uint8_t>(id_.calibration_name[i]);
  }
  return finishFrame(tx_, kInfoSize);
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
  k.loop_time_sum_us += s.loop_time_us;
  ++k.loop_time_samples;

  uint16_t status = s.encoder_errors & kStatusEncoderMask;
  for (uint8_t j = 0; j < 6; ++j) {
    if (status & (1u << j)) {
      ++k.encoder_errors[j];
    } else if (id_.joint_limit_counts > 0) {
      const int16_t d = wrap_count_delta(s.counts[j], config_.zero_counts[j]);
      if (d > id_.joint_limit_counts || d < -id_.joint_limit_counts) status |= kStatusJointLimit;
    }
  }
  if (s.overrun) {
    status |= kStatusLoopOverrun;
    ++k.overruns;
  }
  bool valid = (status & kStatusEncoderMask) == 0;
  if (valid) {
    bool finite = s.solver_ok;
    for (uint8_t i = 0; i < 6 && finite; ++i) finite = is_finite(s.wrench[i]);
    if (!finite) {
      status |= kStatusSolverError;
      ++k.solver_errors;
      valid = false;
    }
  }
  if (!valid) status |= kStatusWrenchInvalid;

  if (averaging_) accumulate(s, status);
  last_status_ = status;

  service();
  if (streaming_) {
    // Quantised only when sent: about 400 AVR cycles per axis saved while stopped.
    int16_t wrench[6];
    bool clipped = false;
    for (uint8_t i = 0; i < 6; ++i) {
      const float w = config_.tare_active ? s.wrench[i] - config_.tare[i] : s.wrench[i];
      wrench[i] = valid ? quantize(w, inverse_lsb_[i], &clipped) : kInvalidValue;
    }
    if (clipped) status |= kStatusOverrange;
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
  const uint16_t n = encodeDataRecord(tx_, seq, s.time_us, status, wrench,
                                      raw ? s.counts : static_cast<const uint16_t*>(0));
  hw_.txWrite(tx_, n);
}

}  // namespace delta6
