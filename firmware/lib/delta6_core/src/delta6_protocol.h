// The Delta6 wire protocol, version 1.0 (docs/protocol.md is the byte-exact specification;
// host/delta6/protocol.py is the host's copy of every number here, cross-tested against it).
//
// A frame is COBS(payload + CRC-16 big-endian) followed by 0x00. Payload byte 0 is the type.
// Device-to-host records have types 0x01..0x7F, host-to-device commands 0x80..0xFF. Every
// multi-byte field is little-endian, except the CRC, which is appended most significant byte
// first so that the CRC over a whole decoded frame is zero.
#ifndef DELTA6_PROTOCOL_H
#define DELTA6_PROTOCOL_H

#include <stdint.h>

namespace delta6 {
namespace proto {

const uint8_t kVersionMajor = 1;
const uint8_t kVersionMinor = 0;

// --- record types (device -> host) -------------------------------------------------------
const uint8_t kWrench = 0x01;
const uint8_t kWrenchRaw = 0x02;
const uint8_t kInfo = 0x03;
const uint8_t kAck = 0x04;
const uint8_t kNack = 0x05;
const uint8_t kTelemetry = 0x06;
const uint8_t kEvent = 0x07;

// Payload sizes (type byte included, CRC excluded).
const uint8_t kWrenchSize = 21;
const uint8_t kWrenchRawSize = 33;
const uint8_t kInfoSize = 128;
const uint8_t kAckSize = 7;
const uint8_t kNackSize = 8;
const uint8_t kTelemetrySize = 48;
const uint8_t kEventSize = 6;
const uint8_t kMaxRecordSize = kInfoSize;
// Payload size of each record type (type byte included, CRC excluded), or 0 for an unknown type.
uint8_t recordSize(uint8_t type);
// Bytes on the wire: payload + CRC + one COBS code byte + the delimiter.
const uint8_t kFrameOverhead = 4;
const uint8_t kMaxFrameBytes = kMaxRecordSize + kFrameOverhead;

// Offsets inside the data records (shared by kWrench and kWrenchRaw).
const uint8_t kOffSeq = 1;
const uint8_t kOffTime = 3;
const uint8_t kOffStatus = 7;
const uint8_t kOffWrench = 9;
const uint8_t kOffCounts = 21;

// --- commands (host -> device): type, request id, arguments ------------------------------
const uint8_t kCmdGetInfo = 0x80;
const uint8_t kCmdPing = 0x81;
const uint8_t kCmdStart = 0x82;       // u16 rate_hz (0: the configured rate)
const uint8_t kCmdStop = 0x83;
const uint8_t kCmdSetMode = 0x84;     // u8 mode
const uint8_t kCmdTare = 0x85;        // u16 samples to average
const uint8_t kCmdClearTare = 0x86;
const uint8_t kCmdSaveConfig = 0x87;
const uint8_t kCmdLoadDefaults = 0x88;
const uint8_t kCmdSetZero = 0x89;     // u16 zero count of joints 1..6
const uint8_t kCmdZeroHere = 0x8A;    // u16 samples to average
const uint8_t kCmdGetTelemetry = 0x8B;
const uint8_t kFirstCommand = kCmdGetInfo;
const uint8_t kLastCommand = kCmdGetTelemetry;
const uint8_t kMaxCommandSize = 14;   // kCmdSetZero: type, request id, 6 x u16
// Receive buffer: room for commands up to 29 payload bytes, so that a longer command from a
// newer host is answered with kNackBadLength (and its request id) instead of being lost.
const uint8_t kCommandBuffer = 32;

// Payload size of each command (type byte included), or 0 for an unknown type.
uint8_t commandSize(uint8_t type);

// --- stream modes ------------------------------------------------------------------------
const uint8_t kModeWrench = 1;
const uint8_t kModeWrenchRaw = 2;

// --- status word bits (every data and telemetry record, and the info record) -------------
const uint16_t kStatusEncoderError0 = 1u << 0;   // bits 0..5: encoder 1..6 failed this sample
const uint16_t kStatusEncoderMask = 0x003F;
const uint16_t kStatusOverrange = 1u << 6;       // an axis was clipped to +-32767 LSB
const uint16_t kStatusJointLimit = 1u << 7;      // an angle lies outside the design's box
const uint16_t kStatusSolverError = 1u << 8;     // the solver failed or returned non-finite
const uint16_t kStatusWrenchInvalid = 1u << 9;   // no wrench this sample: fields are -32768
const uint16_t kStatusLoopOverrun = 1u << 10;    // the loop missed its period before this
const uint16_t kStatusTxOverflow = 1u << 11;     // records were dropped before this one
const uint16_t kStatusTareActive = 1u << 12;     // tare offsets are subtracted
const uint16_t kStatusTareBusy = 1u << 13;       // a tare or zero capture is averaging
const uint16_t kStatusConfigDefaults = 1u << 14; // EEPROM held no valid configuration
// Bit 15 is reserved and always 0 in version 1.

// Wrench value sent when the sample has no valid wrench (kStatusWrenchInvalid).
const int16_t kInvalidValue = -32768;
const int16_t kMaxValue = 32767;

// --- negative acknowledgement reasons ---------------------------------------------------
const uint8_t kNackUnknownCommand = 1;
const uint8_t kNackBadLength = 2;
const uint8_t kNackBadArgument = 3;
const uint8_t kNackRateTooHigh = 4;   // detail: the board's highest rate
const uint8_t kNackLinkTooSlow = 5;   // detail: the highest rate the link carries in the mode
const uint8_t kNackBusy = 6;          // a tare or zero capture is running
const uint8_t kNackFaultDuringAveraging = 7;  // detail: status bits of the bad sample
const uint8_t kNackEepromFailed = 8;  // the written configuration did not read back

// --- events -----------------------------------------------------------------------------
const uint8_t kEventBoot = 1;             // arg: board-specific reset cause
const uint8_t kEventConfigDefaults = 2;   // arg: why the stored configuration was rejected

// Why a stored configuration was rejected (kEventConfigDefaults argument).
const uint8_t kConfigErased = 1;      // no magic: never saved, or erased
const uint8_t kConfigBadCrc = 2;
const uint8_t kConfigBadVersion = 3;
const uint8_t kConfigOutOfRange = 4;

// --- telemetry --------------------------------------------------------------------------
const int16_t kTemperatureUnknown = 0x7FFF;  // centi-degC field when the board has no sensor

// --- scaling: wrench LSB = mantissa x 10^exponent (N or N*m per count) --------------------
// The smallest 1-2-5 step whose +-32767 range covers kHeadroom x full scale.
struct Scale {
  uint8_t mantissa;  // 1, 2 or 5
  int8_t exponent;   // kMinExponent..kMaxExponent
};
const int8_t kMinExponent = -6;
const int8_t kMaxExponent = 3;
Scale scaleForFullScale(float full_scale);
float scaleValue(Scale s);  // the LSB as a float

// Round value / lsb (value * inverse_lsb) to the nearest count. Non-finite gives
// kInvalidValue; beyond +-32767 clips and sets *clipped.
int16_t quantize(float value, float inverse_lsb, bool* clipped);

// --- little-endian field access --------------------------------------------------------
void putU16(uint8_t* p, uint16_t v);
void putU32(uint8_t* p, uint32_t v);
void putF32(uint8_t* p, float v);
uint16_t getU16(const uint8_t* p);
uint32_t getU32(const uint8_t* p);

// Close a frame built in buf: the payload sits at buf[1..n] (buf[0] is scratch), buf has room
// for n + 4 bytes. Appends the CRC, COBS-encodes in place and adds the delimiter. Returns the
// number of bytes to send from buf[0], or 0 if n is too long.
uint16_t finishFrame(uint8_t* buf, uint16_t n);

// Data record into buf[1..]: kWrench, or kWrenchRaw when counts is non-null. Returns the
// frame length (finishFrame).
uint16_t encodeDataRecord(uint8_t* buf, uint16_t seq, uint32_t time_us, uint16_t status,
                          const int16_t wrench[6], const uint16_t* counts);

// --- command parsing ---------------------------------------------------------------------
struct Command {
  uint8_t type;
  uint8_t request_id;
  uint8_t size;          // payload bytes, type and request id included
  const uint8_t* args;   // size - 2 little-endian argument bytes; valid until the next feed
};

enum ParseResult {
  kParseNone = 0,      // no complete frame yet
  kParseCommand,       // a frame with a valid CRC: see command (its length is not yet checked)
  kParseEmpty,         // an empty frame (two delimiters in a row: harmless)
  kParseBadFrame,      // not valid COBS, shorter than type + request id + CRC
  kParseBadCrc,
  kParseTooLong,       // the frame overflowed the buffer and was discarded
};

// Accumulates received bytes; a 0x00 ends a frame. A frame longer than the buffer is
// discarded up to its delimiter, so one lost delimiter costs at most two commands.
class CommandParser {
 public:
  CommandParser();
  ParseResult feed(uint8_t byte, Command* command);
  void reset();

 private:
  uint8_t buf_[kCommandBuffer];
  uint8_t len_;
  bool overflow_;
};

}  // namespace proto
}  // namespace delta6

#endif
