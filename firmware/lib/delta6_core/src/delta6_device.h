// The device side of the Delta6 protocol as a portable state machine: command dispatch,
// configuration (RAM and EEPROM), tare, zero counts, record encoding, telemetry counters and
// the status word. It touches hardware only through delta6::Hardware, so the very same code
// runs on the board (the board layer implements Hardware) and natively in tests and in the
// host's simulated device (firmware/native/). docs/protocol.md describes the behaviour.
//
// Use from the application:
//   Device device(hardware, identity, defaults);
//   device.begin(reset_cause);           // loads the configuration, announces itself
//   every sample period: device.onSample(sample);
//   for every received byte: device.onByte(byte);
//   the encoder zero counts to use: device.zeroCounts(); the sample rate: sampleRateHz()
#ifndef DELTA6_DEVICE_H
#define DELTA6_DEVICE_H

#include <stdint.h>

#include "delta6_filter.h"
#include "delta6_flash.h"
#include "delta6_protocol.h"
#include "delta6_toolframe.h"

namespace delta6 {

// What the board layer provides. Calls come from the context that calls Device's methods.
class Hardware {
 public:
  // Bytes the transmit queue accepts right now. The queue must be able to hold
  // Device::kMinTxBuffer bytes when empty, or the largest records never go out.
  virtual uint16_t txSpace() = 0;
  // Queue n <= txSpace() bytes for transmission; must not block for long. Records come whole
  // (ending in the 0x00 delimiter), except INFO, which comes in several writes in a row.
  virtual void txWrite(const uint8_t* data, uint16_t n) = 0;
  // Read / write n bytes of non-volatile memory (Device::kConfigBlobSize at most).
  virtual void eepromRead(uint16_t address, uint8_t* data, uint16_t n) = 0;
  virtual void eepromWrite(uint16_t address, const uint8_t* data, uint16_t n) = 0;
  // Free-running microsecond clock (answers to ping, telemetry time stamps).
  virtual uint32_t micros() = 0;
  // The sample rate changed (start with a new rate, defaults or configuration loaded): the
  // application retimes its sampling loop. Also called once from begin().
  virtual void sampleRateChanged(uint16_t rate_hz) = 0;

 protected:
  ~Hardware() {}  // not virtual: no heap, no delete, nothing for avr-gcc to link
};

// What the firmware build knows about itself; constant for the device's lifetime.
struct Identity {
  const char* design_name;   // ASCII, at most 23 characters (longer is cut)
  uint32_t design_hash;      // Design.hash32() of the design the solver was generated for
  float full_scale[6];       // Fx Fy Fz (N), Mx My Mz (N*m): sets the wire scaling
  float joint_limit_rad;     // the joint box, reported in the info record
  int16_t joint_limit_counts;  // |count delta| beyond this sets kStatusJointLimit; 0: no
                               // check. The solver's own limit: design::kJointLimitCounts
  uint8_t firmware_version[3];  // major, minor, patch
  uint32_t baud;             // the UART's rate, for the link-capacity check; 0: no check
  uint16_t max_rate_hz;      // the fastest loop the board sustains
  uint32_t serial_number;    // board-specific identifier, 0 if none
  uint16_t eeprom_address;   // where the configuration blob lives
  const char* calibration_name;  // the calibration compiled in (ASCII, <= 23 characters), or
  uint32_t calibration_hash;     // nullptr and 0: the analytical model (INFO, protocol 1.1)
  const char* model_name;  // the on-chip residual model compiled in (ASCII, <= 23
  uint32_t model_hash;     // characters), or nullptr and 0: none (INFO, protocol 1.2)
  uint16_t max_rate_pipeline_hz;  // the fastest loop with the filter or the tool frame on
                                  // (they cost cycles per sample); 0: max_rate_hz
};

// The persistent configuration (saved to EEPROM only by the save command). The wrench
// pipeline per sample: low-pass (filter_hz) -> tool frame -> tare -> quantise -> limits.
struct Config {
  uint16_t rate_hz;
  uint8_t mode;              // proto::kModeWrench or proto::kModeWrenchRaw
  bool tare_active;
  float tare[6];             // subtracted from the tool-frame wrench when tare_active
  uint16_t zero_counts[6];   // encoder count at zero deflection, joints 1..6 (0..16383)
  float filter_hz;           // low-pass cutoff, 0: off (kMinCutoffRatio..kMaxCutoffRatio x rate)
  float tool_translation[3]; // the tool point in {E}, m (|value| <= proto::kMaxToolTranslation)
  float tool_rpy[3];         // the tool's axes: roll, pitch, yaw about {E}, rad (<= proto::kMaxToolAngle)
  uint16_t limits[6];        // overload thresholds, counts of each axis's LSB; 0: none
};

// The tool frames the device accepts: proto::kMaxToolTranslation and kMaxToolAngle (the
// generated wire header, from delta6.link.protocol).

// One sample from the application.
struct Sample {
  uint32_t time_us;          // device time when the encoders were latched
  uint16_t counts[6];        // raw 14-bit encoder counts (0..16383)
  uint8_t encoder_errors;    // bit j: encoder j+1 failed this sample, counts[j] is meaningless
  bool solver_ok;            // the solver produced a wrench
  float wrench[6];           // untared solver output, N and N*m in frame {E}
  bool overrun;              // the loop missed at least one period since the previous sample
  uint16_t loop_time_us;     // time spent reading and solving this sample
  int16_t temperature_centi; // board temperature in 0.01 degC, proto::kTemperatureUnknown
};

// Health counters, reported by the telemetry record. 16-bit counters wrap; hosts take
// differences modulo 2^16 between telemetry records.
struct Counters {
  uint32_t samples;
  uint16_t overruns;
  uint16_t encoder_errors[6];
  uint16_t solver_errors;
  uint16_t rx_frames;          // command frames with a valid CRC
  uint16_t rx_crc_errors;
  uint16_t rx_bad_frames;      // invalid COBS, too short, unknown type or wrong length
  uint16_t rx_overflows;       // frames longer than the receive buffer
  uint16_t tx_dropped;         // data records dropped for lack of transmit space
  uint16_t responses_dropped;  // answers dropped because the answer queue was full
  uint16_t loop_time_max_us;   // over the current telemetry window
  uint32_t loop_time_sum_us;
  uint16_t loop_time_samples;
};

class Device {
 public:
  static const uint16_t kConfigBlobSize = proto::kConfigBlobSize;
  static const uint16_t kMinTxBuffer = proto::kMaxFrameBytes;
  // The frame buffer holds every record but INFO, which goes out in pieces (sendInfo).
  static const uint8_t kTxBuffer = proto::kTelemetrySize + proto::kFrameOverhead;
  static const uint32_t kTelemetryPeriodUs = 1000000;
  static const uint8_t kQueueLength = 4;

  // identity and defaults: declared DELTA6_FLASH (program memory on the AVR; delta6_flash.h),
  // read only through flash::copy. The names identity points to are in RAM.
  Device(Hardware& hardware, const Identity& identity, const Config& defaults);

  // Load the configuration from EEPROM (defaults if it is invalid, flagged), announce the boot
  // and the device info, and report the sample rate. reset_cause is board-specific; boot_id
  // tells this boot session from the one before (info and telemetry carry it): a value the
  // previous boot did not have (the board layer keeps a counter across resets).
  void begin(uint8_t reset_cause, uint16_t boot_id = 0);
  // One sample: status word, tare, quantisation, the data record if streaming, telemetry.
  void onSample(const Sample& sample);
  // One received byte; a complete command is executed at once.
  void onByte(uint8_t byte);
  // Send queued answers that fit into the transmit queue now (onSample and onByte do too).
  void service();

  const uint16_t* zeroCounts() const { return config_.zero_counts; }
  bool filterOn() const { return filter_on_; }
  uint16_t sampleRateHz() const { return config_.rate_hz; }
  bool streaming() const { return streaming_; }
  uint8_t mode() const { return config_.mode; }
  uint16_t persistentStatus() const;
  const Counters& counters() const { return counters_; }
  const Config& config() const { return config_; }
  proto::Scale scale(uint8_t axis) const { return scale_[axis]; }
  // The board's serial number when only the running board knows it (Identity's is then 0).
  void setSerialNumber(uint32_t serial_number) { serial_number_ = serial_number; }
  // Highest rate the link carries in a mode (90 % of the baud rate), or 0xFFFF without a baud.
  uint16_t linkRateLimit(uint8_t mode) const;

  // The EEPROM blob: serialise, and parse with validation (returns 0, a proto::kConfig*
  // reason it was rejected, or kConfigRateLowered: loaded with a rate above this image's
  // highest lowered to it). A blob written for another design hash keeps everything but the
  // tare and the limits.
  static void encodeConfig(const Config& config, uint32_t design_hash, uint8_t* blob);
  uint8_t decodeConfig(const uint8_t* blob, Config* config) const;

 private:
  struct Response {
    uint8_t kind;        // proto::kAck, kNack, kInfo, kTelemetry or kEvent
    uint8_t request_id;
    uint8_t command;     // the command answered; event code for kEvent
    uint8_t code;        // NACK reason
    uint32_t value;      // ACK value, NACK detail, event argument
  };

  void execute(const proto::Command& command);
  void answer(uint8_t kind, uint8_t request_id, uint8_t command, uint8_t code,
              uint32_t value);
  void ack(const proto::Command& c, uint32_t value) { answer(proto::kAck, c.request_id, c.type, 0, value); }
  void nack(const proto::Command& c, uint8_t reason, uint32_t detail = 0) {
    answer(proto::kNack, c.request_id, c.type, reason, detail);
  }
  uint16_t buildResponse(const Response& r);
  void sendInfo(uint8_t request_id);
  void buildInfoPiece(uint8_t request_id, uint8_t piece, uint8_t* p) const;
  void loadDefaults(Config* out) const { flash::copy(out, &defaults_, sizeof(Config)); }
  // A field of the identity, from flash.
  template <typename T>
  static T ident(const T& field) {
    T value;
    flash::copy(&value, &field, sizeof(T));
    return value;
  }
  uint16_t buildTelemetry(uint8_t request_id);
  void startAveraging(const proto::Command& c, uint16_t samples);
  void accumulate(const float* wrench, const Sample& sample, uint16_t status);
  void finishAveraging();
  void saveConfig(const proto::Command& c);
  void applyConfig(const Config& config);
  void setRate(uint16_t rate_hz);
  uint16_t checkRate(uint16_t rate_hz, uint8_t mode, bool pipeline, uint8_t* reason) const;
  // The highest rate the board sustains with or without the filter / tool frame on.
  uint16_t maxRate(bool pipeline) const;
  bool pipelineOn() const { return filter_on_ || !tool_.identity; }
  // The EEPROM configuration was rejected at boot (a lowered rate is not a rejection).
  bool usingDefaults() const {
    return config_problem_ != 0 && config_problem_ != proto::kConfigRateLowered;
  }
  // The filter's coefficients and the tool transform from config_ (the filter restarts).
  void configurePipeline();
  void setFilter(const proto::Command& c);
  void setTool(const proto::Command& c);
  void setLimits(const proto::Command& c);
  void sendData(const Sample& sample, uint16_t status, const int16_t* wrench);

  Hardware& hw_;
  const Identity& id_;
  const Config& defaults_;
  Config config_;
  proto::Scale scale_[6];
  float inverse_lsb_[6];
  LowPass6 filter_;
  bool filter_on_;
  ToolFrame tool_;

  proto::CommandParser parser_;
  Response queue_[kQueueLength];
  uint8_t queue_head_;
  uint8_t queue_count_;
  Response last_answer_;       // repeated for a retried request (same id and command)

  bool streaming_;
  uint8_t config_problem_;     // why the EEPROM configuration was rejected or adjusted (0: neither)
  bool tx_overflow_;           // a data record was dropped since the last one sent
  bool stream_changed_;        // a command changed what records mean; none sent since
  uint16_t boot_id_;
  uint32_t serial_number_;
  uint16_t seq_;
  uint16_t last_status_;
  int16_t temperature_centi_;
  uint32_t last_telemetry_us_;
  Counters counters_;

  // Averaging for tare (float wrench sums) or zero capture (count deltas), one at a time.
  uint8_t averaging_;          // 0, proto::kCmdTare or proto::kCmdZeroHere
  uint8_t averaging_request_;
  uint16_t averaging_target_;
  uint16_t averaging_count_;
  // ZERO_HERE: the first sample's counts; the others are wrapped against them, not against the
  // old zero (a rest half a turn from it straddles the wrap, and +8191 and -8192 average to 0).
  uint16_t averaging_first_[6];
  union {
    float wrench[6];
    int32_t counts[6];
  } sums_;

  uint8_t tx_[kTxBuffer];
};

}  // namespace delta6

#endif
