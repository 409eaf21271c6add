// The Delta6 wire protocol, version 1.0 (docs/protocol.md is the byte-exact specification).
// Every number of the wire comes from generated/delta6_wire.h, which `delta6 codegen --wire`
// writes from the host's tables (host/delta6/link/protocol.py); this file adds the codec.
//
// A frame is COBS(payload + CRC-16 big-endian) followed by 0x00. Payload byte 0 is the type.
// Device-to-host records have types 0x01..0x7F, host-to-device commands 0x80..0xFF. Every
// multi-byte field is little-endian, except the CRC, which is appended most significant byte
// first so that the CRC over a whole decoded frame is zero.
#ifndef DELTA6_PROTOCOL_H
#define DELTA6_PROTOCOL_H

#include <stdint.h>

#include "generated/delta6_wire.h"

namespace delta6 {
namespace proto {

// Record types, sizes and field offsets, commands and their sizes, modes, status bits, NACK
// reasons, event codes, the EEPROM blob and the scaling constants: generated from the host's
// tables (delta6.link.protocol), never written here.

// Payload size of each record type (type byte included, CRC excluded), or 0 for an unknown type.
uint8_t recordSize(uint8_t type);
// Payload size of each command (type byte included), or 0 for an unknown type.
uint8_t commandSize(uint8_t type);

// --- scaling: wrench LSB = mantissa x 10^exponent (N or N*m per count) --------------------
// The smallest step of kMantissas x kDecades whose +-kMaxValue range covers kHeadroom x full
// scale.
struct Scale {
  uint8_t mantissa;  // one of kMantissas
  int8_t exponent;   // kMinExponent..kMaxExponent
};
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
float getF32(const uint8_t* p);

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
