// GENERATED FILE - DO NOT EDIT.
// Written by `delta6 codegen --wire` from delta6.link.protocol and delta6.link.wirescale
// (host/delta6/link/). Regenerate with that command; tests/firmware/test_codegen.py fails
// when this file is out of date. docs/protocol.md explains every number.
#ifndef DELTA6_GENERATED_WIRE_H
#define DELTA6_GENERATED_WIRE_H

#include <stdint.h>

#include "delta6_flash.h"

namespace delta6 {
namespace proto {

const uint8_t kVersionMajor = 1;
const uint8_t kVersionMinor = 3;

// --- records (device -> host): type, payload size (type byte included, CRC
// excluded) and the offset of every field (docs/protocol.md section 3) ---

const uint8_t kWrench = 0x01;
const uint8_t kWrenchSize = 21;
const uint8_t kWrenchOffType = 0;  // u8
const uint8_t kWrenchOffSeq = 1;  // u16
const uint8_t kWrenchOffTimeUs = 3;  // u32
const uint8_t kWrenchOffStatus = 7;  // u16
const uint8_t kWrenchOffWrench = 9;  // 6 x i16

const uint8_t kWrenchRaw = 0x02;
const uint8_t kWrenchRawSize = 33;
const uint8_t kWrenchRawOffType = 0;  // u8
const uint8_t kWrenchRawOffSeq = 1;  // u16
const uint8_t kWrenchRawOffTimeUs = 3;  // u32
const uint8_t kWrenchRawOffStatus = 7;  // u16
const uint8_t kWrenchRawOffWrench = 9;  // 6 x i16
const uint8_t kWrenchRawOffCounts = 21;  // 6 x u16

const uint8_t kInfo = 0x03;
const uint8_t kInfoSize = 228;
const uint8_t kInfoOffType = 0;  // u8
const uint8_t kInfoOffRequestId = 1;  // u8
const uint8_t kInfoOffProtocol = 2;  // 2 x u8
const uint8_t kInfoOffFirmware = 4;  // 3 x u8
const uint8_t kInfoOffMode = 7;  // u8
const uint8_t kInfoOffDesignHash = 8;  // u32
const uint8_t kInfoOffDesignName = 12;  // 24 x char
const uint8_t kInfoDesignNameBytes = 24;  // NUL-padded
const uint8_t kInfoOffFullScale = 36;  // 6 x f32
const uint8_t kInfoOffLsbMantissa = 60;  // 6 x u8
const uint8_t kInfoOffLsbExponent = 66;  // 6 x i8
const uint8_t kInfoOffRateHz = 72;  // u16
const uint8_t kInfoOffMaxRateHz = 74;  // u16
const uint8_t kInfoOffStatus = 76;  // u16
const uint8_t kInfoOffStreaming = 78;  // u8
const uint8_t kInfoOffConfigProblem = 79;  // u8
const uint8_t kInfoOffBaud = 80;  // u32
const uint8_t kInfoOffSerialNumber = 84;  // u32
const uint8_t kInfoOffZeroCounts = 88;  // 6 x u16
const uint8_t kInfoOffTare = 100;  // 6 x f32
const uint8_t kInfoOffJointLimitRad = 124;  // f32
const uint8_t kInfoOffCalibrationHash = 128;  // u32
const uint8_t kInfoOffCalibrationName = 132;  // 24 x char
const uint8_t kInfoCalibrationNameBytes = 24;  // NUL-padded
const uint8_t kInfoOffBootId = 156;  // u16
const uint8_t kInfoOffModelHash = 158;  // u32
const uint8_t kInfoOffModelName = 162;  // 24 x char
const uint8_t kInfoModelNameBytes = 24;  // NUL-padded
const uint8_t kInfoOffFilterHz = 186;  // f32
const uint8_t kInfoOffToolTranslation = 190;  // 3 x f32
const uint8_t kInfoOffToolRpy = 202;  // 3 x f32
const uint8_t kInfoOffLimits = 214;  // 6 x u16
const uint8_t kInfoOffMaxRatePipelineHz = 226;  // u16

const uint8_t kAck = 0x04;
const uint8_t kAckSize = 7;
const uint8_t kAckOffType = 0;  // u8
const uint8_t kAckOffRequestId = 1;  // u8
const uint8_t kAckOffCommand = 2;  // u8
const uint8_t kAckOffValue = 3;  // u32

const uint8_t kNack = 0x05;
const uint8_t kNackSize = 8;
const uint8_t kNackOffType = 0;  // u8
const uint8_t kNackOffRequestId = 1;  // u8
const uint8_t kNackOffCommand = 2;  // u8
const uint8_t kNackOffReason = 3;  // u8
const uint8_t kNackOffDetail = 4;  // u32

const uint8_t kTelemetry = 0x06;
const uint8_t kTelemetrySize = 50;
const uint8_t kTelemetryOffType = 0;  // u8
const uint8_t kTelemetryOffRequestId = 1;  // u8
const uint8_t kTelemetryOffTimeUs = 2;  // u32
const uint8_t kTelemetryOffStatus = 6;  // u16
const uint8_t kTelemetryOffSamples = 8;  // u32
const uint8_t kTelemetryOffOverruns = 12;  // u16
const uint8_t kTelemetryOffEncoderErrors = 14;  // 6 x u16
const uint8_t kTelemetryOffSolverErrors = 26;  // u16
const uint8_t kTelemetryOffRxFrames = 28;  // u16
const uint8_t kTelemetryOffRxCrcErrors = 30;  // u16
const uint8_t kTelemetryOffRxBadFrames = 32;  // u16
const uint8_t kTelemetryOffRxOverflows = 34;  // u16
const uint8_t kTelemetryOffTxDropped = 36;  // u16
const uint8_t kTelemetryOffResponsesDropped = 38;  // u16
const uint8_t kTelemetryOffLoopTimeMaxUs = 40;  // u16
const uint8_t kTelemetryOffLoopTimeMeanUs = 42;  // u16
const uint8_t kTelemetryOffTemperatureCenti = 44;  // i16
const uint8_t kTelemetryOffNextSeq = 46;  // u16
const uint8_t kTelemetryOffBootId = 48;  // u16

const uint8_t kEvent = 0x07;
const uint8_t kEventSize = 6;
const uint8_t kEventOffType = 0;  // u8
const uint8_t kEventOffCode = 1;  // u8
const uint8_t kEventOffArg = 2;  // u32

const uint8_t kMaxRecordSize = 228;
// Bytes on the wire beyond the payload: CRC, one COBS code byte, the delimiter.
const uint8_t kFrameOverhead = 4;
const uint8_t kMaxFrameBytes = 232;

// Payload size of each record type from kFirstRecordType on (0: none).
const uint8_t kFirstRecordType = 0x01;
const uint8_t kRecordTypeCount = 7;
const uint8_t kRecordSizeByType[kRecordTypeCount] DELTA6_FLASH = {21, 33, 228, 7, 8, 50, 6};

// --- commands (host -> device): type, request id, arguments; each command's
// exact payload size (docs/protocol.md section 4) ---
const uint8_t kCmdGetInfo = 0x80;
const uint8_t kCmdGetInfoSize = 2;
const uint8_t kCmdPing = 0x81;
const uint8_t kCmdPingSize = 2;
const uint8_t kCmdStart = 0x82;
const uint8_t kCmdStartSize = 4;  // u16 rate_hz
const uint8_t kCmdStop = 0x83;
const uint8_t kCmdStopSize = 2;
const uint8_t kCmdSetMode = 0x84;
const uint8_t kCmdSetModeSize = 3;  // u8 mode
const uint8_t kCmdTare = 0x85;
const uint8_t kCmdTareSize = 4;  // u16 samples
const uint8_t kCmdClearTare = 0x86;
const uint8_t kCmdClearTareSize = 2;
const uint8_t kCmdSaveConfig = 0x87;
const uint8_t kCmdSaveConfigSize = 2;
const uint8_t kCmdLoadDefaults = 0x88;
const uint8_t kCmdLoadDefaultsSize = 2;
const uint8_t kCmdSetZero = 0x89;
const uint8_t kCmdSetZeroSize = 14;  // 6 x u16 zero_counts
const uint8_t kCmdZeroHere = 0x8A;
const uint8_t kCmdZeroHereSize = 4;  // u16 samples
const uint8_t kCmdGetTelemetry = 0x8B;
const uint8_t kCmdGetTelemetrySize = 2;
const uint8_t kCmdAbort = 0x8C;
const uint8_t kCmdAbortSize = 2;
const uint8_t kCmdSetFilter = 0x8D;
const uint8_t kCmdSetFilterSize = 6;  // f32 cutoff_hz
const uint8_t kCmdSetTool = 0x8E;
const uint8_t kCmdSetToolSize = 26;  // 3 x f32 translation, 3 x f32 rpy
const uint8_t kCmdSetLimits = 0x8F;
const uint8_t kCmdSetLimitsSize = 14;  // 6 x u16 limits
// Types below this are records: a device never answers them (its own output looped
// back must not start an endless exchange).
const uint8_t kFirstCommand = 0x80;
const uint8_t kLastCommand = 0x8F;
const uint8_t kMaxCommandSize = 26;
// Receive buffer (encoded bytes): longer command frames are discarded and counted.
const uint8_t kCommandBuffer = 32;

// Payload size of each command type from kFirstCommandType on (0: none).
const uint8_t kFirstCommandType = 0x80;
const uint8_t kCommandTypeCount = 16;
const uint8_t kCommandSizeByType[kCommandTypeCount] DELTA6_FLASH = {2, 2, 4, 2, 3, 4, 2, 2, 2, 14, 4, 2, 2, 6, 26, 14};

// --- stream modes (SET_MODE argument, INFO) ---
const uint8_t kModeWrench = 1;
const uint8_t kModeWrenchRaw = 2;

// --- status word bits (docs/protocol.md section 5) ---
const uint16_t kStatusEncoder1 = 1u << 0;
const uint16_t kStatusEncoder2 = 1u << 1;
const uint16_t kStatusEncoder3 = 1u << 2;
const uint16_t kStatusEncoder4 = 1u << 3;
const uint16_t kStatusEncoder5 = 1u << 4;
const uint16_t kStatusEncoder6 = 1u << 5;
const uint16_t kStatusOverrange = 1u << 6;
const uint16_t kStatusJointLimit = 1u << 7;
const uint16_t kStatusSolverError = 1u << 8;
const uint16_t kStatusWrenchInvalid = 1u << 9;
const uint16_t kStatusLoopOverrun = 1u << 10;
const uint16_t kStatusTxOverflow = 1u << 11;
const uint16_t kStatusTareActive = 1u << 12;
const uint16_t kStatusTareBusy = 1u << 13;
const uint16_t kStatusConfigDefaults = 1u << 14;
const uint16_t kStatusStreamChanged = 1u << 15;
const uint16_t kStatusEncoderMask = 0x003F;

// --- NACK reasons (docs/protocol.md section 3) ---
const uint8_t kNackUnknownCommand = 1;
const uint8_t kNackBadLength = 2;
const uint8_t kNackBadArgument = 3;
const uint8_t kNackRateTooHigh = 4;
const uint8_t kNackLinkTooSlow = 5;
const uint8_t kNackBusy = 6;
const uint8_t kNackFaultDuringAveraging = 7;
const uint8_t kNackEepromFailed = 8;
const uint8_t kNackAborted = 9;
const uint8_t kNackFilterRange = 10;

// --- event codes (EVENT record) ---
const uint8_t kEventBoot = 1;
const uint8_t kEventConfigDefaults = 2;

// --- why a stored configuration was rejected (CONFIG_DEFAULTS argument), or how it was adjusted (INFO only) ---
const uint8_t kConfigErased = 1;
const uint8_t kConfigBadCrc = 2;
const uint8_t kConfigBadVersion = 3;
const uint8_t kConfigOutOfRange = 4;
const uint8_t kConfigRateLowered = 5;

// --- the configuration blob in EEPROM (docs/protocol.md section 9), followed by its CRC,
// most significant byte first ---
const uint16_t kConfigMagic = 0x3644;
const uint8_t kConfigLayoutVersion = 2;
const uint16_t kConfigBlobSize = 90;
// Older layouts the device still loads: each is a prefix of the newest (same
// offsets), its blob shorter; the fields it lacks take the defaults.
const uint8_t kConfigLayoutV1 = 1;
const uint16_t kConfigBlobSizeV1 = 50;
const uint8_t kConfigOffMagic = 0;  // u16
const uint8_t kConfigOffLayout = 2;  // u8
const uint8_t kConfigOffSize = 3;  // u8
const uint8_t kConfigOffDesignHash = 4;  // u32
const uint8_t kConfigOffRateHz = 8;  // u16
const uint8_t kConfigOffMode = 10;  // u8
const uint8_t kConfigOffTareActive = 11;  // u8
const uint8_t kConfigOffTare = 12;  // 6 x f32
const uint8_t kConfigOffZeroCounts = 36;  // 6 x u16
const uint8_t kConfigOffFilterHz = 48;  // f32
const uint8_t kConfigOffToolTranslation = 52;  // 3 x f32
const uint8_t kConfigOffToolRpy = 64;  // 3 x f32
const uint8_t kConfigOffLimits = 76;  // 6 x u16

// --- the tool frames the device accepts (SET_TOOL): |translation| per axis, m, and
// |angle|, rad ---
const float kMaxToolTranslation = 1.0f;
const float kMaxToolAngle = 6.28318548f;

// --- telemetry ---
const int16_t kTemperatureUnknown = 0x7FFF;  // no temperature sensor

// --- wrench scaling (docs/protocol.md section 7): LSB = mantissa x 10^exponent, the
// smallest step whose +-32767 counts cover kHeadroom x full scale ---
const int8_t kMinExponent = -6;
const int8_t kMaxExponent = 3;
const uint8_t kMantissaCount = 3;
// In flash on the AVR (DELTA6_FLASH): read them with flash::byte and flash::f32.
const uint8_t kMantissas[kMantissaCount] DELTA6_FLASH = {1, 2, 5};
// Decades as float literals: the host (delta6.link.wirescale) rounds the same decimals
// to float32, so both ends pick the same step even at exact boundaries.
const float kDecades[kMaxExponent - kMinExponent + 1] DELTA6_FLASH = {
    1e-6f, 1e-5f, 1e-4f, 1e-3f, 1e-2f, 1e-1f, 1e0f, 1e1f, 1e2f, 1e3f};
const float kHeadroom = 1.25f;
// A wrench value: counts of the LSB; kInvalidValue when the sample has none.
const int16_t kInvalidValue = -32768;
const int16_t kMaxValue = 32767;
// float(kMaxValue) as IEEE-754 binary32 bits: quantize() compares magnitudes as integers.
const uint32_t kMaxValueFloatBits = 0x46FFFE00UL;

// --- the link: data records may fill 9/10 of its baud / 10 bytes per second, computed
// as baud / kLinkBudgetDivisor x kLinkBudgetNumerator (dividing first: no 32-bit overflow) ---
const uint8_t kLinkBudgetNumerator = 9;
const uint16_t kLinkBudgetDivisor = 100;

}  // namespace proto
}  // namespace delta6

#endif  // DELTA6_GENERATED_WIRE_H
