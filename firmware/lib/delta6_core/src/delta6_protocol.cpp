#include "delta6_protocol.h"

#include <string.h>

#include "delta6_cobs.h"
#include "delta6_crc16.h"

namespace delta6 {
namespace proto {

uint8_t recordSize(uint8_t type) {
  const uint8_t i = static_cast<uint8_t>(type - kFirstRecordType);  // wraps below: too large
  return i < kRecordTypeCount ? flash::byte(&kRecordSizeByType[i]) : 0;
}

uint8_t commandSize(uint8_t type) {
  const uint8_t i = static_cast<uint8_t>(type - kFirstCommandType);
  return i < kCommandTypeCount ? flash::byte(&kCommandSizeByType[i]) : 0;
}

// The host mirrors the products below in float32, so both ends pick the same step.
static const float kHeadroomPerCount = kHeadroom / static_cast<float>(kMaxValue);

Scale scaleForFullScale(float full_scale) {
  const float needed = full_scale * kHeadroomPerCount;
  for (int8_t e = kMinExponent; e <= kMaxExponent; ++e) {
    for (uint8_t m = 0; m < kMantissaCount; ++m) {
      const uint8_t mantissa = flash::byte(&kMantissas[m]);
      const float step = static_cast<float>(mantissa) * flash::f32(&kDecades[e - kMinExponent]);
      if (step >= needed) {
        Scale s = {mantissa, e};
        return s;
      }
    }
  }
  // Not finite, or beyond the coarsest step's range: that step (never reached by a design).
  Scale s = {flash::byte(&kMantissas[kMantissaCount - 1]), kMaxExponent};
  return s;
}

float scaleValue(Scale s) {
  return static_cast<float>(s.mantissa) * flash::f32(&kDecades[s.exponent - kMinExponent]);
}

int16_t quantize(float value, float inverse_lsb, bool* clipped) {
  const float x = value * inverse_lsb;
  // Range and sign from the bits: integer tests cost a few AVR cycles, float comparisons ~60.
  uint32_t bits;
  memcpy(&bits, &x, 4);
  const uint32_t magnitude = bits & 0x7FFFFFFFUL;
  const bool negative = (bits >> 31) != 0;
  if (magnitude < kMaxValueFloatBits) {  // |x| < kMaxValue
    // Round half away from zero in integers, from the mantissa and exponent: exact, and a
    // fifth of the cycles of a float addition and conversion on the AVR.
    // The exponent from the upper half: a 32-bit shift by 23 is a 23-step loop on the AVR
    // (about 140 cycles an axis), a 16-bit one by 7 a few instructions.
    const uint16_t upper = static_cast<uint16_t>(magnitude >> 16);
    const int16_t exponent = static_cast<int16_t>(upper >> 7) - 127;
    if (exponent < -1) return 0;  // |x| < 0.5, zero and subnormals included
    uint32_t v = (magnitude & 0x7FFFFFUL) | 0x800000UL;  // |x| = v x 2^(exponent - 23)
    uint8_t shift = static_cast<uint8_t>(22 - exponent);   // keep one bit below the point
    if (shift >= 16) {  // whole-byte shifts first: an 8-bit CPU shifts one bit at a time
      v >>= 16;
      shift = static_cast<uint8_t>(shift - 16);
    }
    if (shift >= 8) {
      v >>= 8;
      shift = static_cast<uint8_t>(shift - 8);
    }
    v >>= shift;
    const int16_t rounded = static_cast<int16_t>((v + 1) >> 1);
    return negative ? static_cast<int16_t>(-rounded) : rounded;
  }
  if (magnitude > 0x7F800000UL) return kInvalidValue;  // NaN
  if (magnitude > kMaxValueFloatBits) *clipped = true;  // beyond kMaxValue (infinities too)
  return static_cast<int16_t>(negative ? -kMaxValue : kMaxValue);
}

void putU16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}

void putU32(uint8_t* p, uint32_t v) {
  // Constant shifts (byte moves on the AVR): a loop's v >> (8 * i) shifts bit by bit, about
  // 400 cycles a call.
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
  p[2] = static_cast<uint8_t>(v >> 16);
  p[3] = static_cast<uint8_t>(v >> 24);
}

void putF32(uint8_t* p, float v) {
  uint32_t bits;
  memcpy(&bits, &v, 4);  // IEEE-754 single on both AVR and the host
  putU32(p, bits);
}

uint16_t getU16(const uint8_t* p) {
  return static_cast<uint16_t>(p[0] | (static_cast<uint16_t>(p[1]) << 8));
}

uint32_t getU32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

float getF32(const uint8_t* p) {
  const uint32_t bits = getU32(p);
  float v;
  memcpy(&v, &bits, 4);
  return v;
}

uint16_t finishFrame(uint8_t* buf, uint16_t n) {
  if (n + 2 > kCobsMaxInPlace) return 0;
  const uint16_t crc = crc16(buf + 1, n);
  buf[n + 1] = static_cast<uint8_t>(crc >> 8);
  buf[n + 2] = static_cast<uint8_t>(crc);
  const uint16_t len = cobsEncodeInPlace(buf, static_cast<uint16_t>(n + 2));
  buf[len] = 0;
  return static_cast<uint16_t>(len + 1);
}

uint16_t encodeDataRecord(uint8_t* buf, uint16_t seq, uint32_t time_us, uint16_t status,
                          const int16_t wrench[6], const uint16_t* counts) {
  uint8_t* p = buf + 1;
  p[kWrenchOffType] = counts ? kWrenchRaw : kWrench;
  // WRENCH_RAW is WRENCH with the counts appended (the host checks it): one set of offsets.
  putU16(p + kWrenchOffSeq, seq);
  putU32(p + kWrenchOffTimeUs, time_us);
  putU16(p + kWrenchOffStatus, status);
  for (uint8_t i = 0; i < 6; ++i) {
    putU16(p + kWrenchOffWrench + 2 * i, static_cast<uint16_t>(wrench[i]));
  }
  if (!counts) return finishFrame(buf, kWrenchSize);
  for (uint8_t i = 0; i < 6; ++i) putU16(p + kWrenchRawOffCounts + 2 * i, counts[i]);
  return finishFrame(buf, kWrenchRawSize);
}

CommandParser::CommandParser() : len_(0), overflow_(false) {}

void CommandParser::reset() {
  len_ = 0;
  overflow_ = false;
}

ParseResult CommandParser::feed(uint8_t byte, Command* command) {
  if (byte != 0) {
    if (len_ < kCommandBuffer) {
      buf_[len_++] = byte;
    } else {
      overflow_ = true;
    }
    return kParseNone;
  }
  const uint8_t n = len_;
  const bool overflow = overflow_;
  reset();
  if (overflow) return kParseTooLong;
  if (n == 0) return kParseEmpty;
  const int16_t decoded = cobsDecodeInPlace(buf_, n);
  if (decoded < 4) return kParseBadFrame;  // type, request id, two CRC bytes at least
  if (crc16(buf_, static_cast<uint16_t>(decoded)) != 0) return kParseBadCrc;
  command->type = buf_[0];
  command->request_id = buf_[1];
  command->size = static_cast<uint8_t>(decoded - 2);
  command->args = buf_ + 2;
  return kParseCommand;
}

}  // namespace proto
}  // namespace delta6
