// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR): the checksum of
// every Delta6 frame (docs/protocol.md). Python: binascii.crc_hqx(data, 0xFFFF).
#ifndef DELTA6_CRC16_H
#define DELTA6_CRC16_H

#include <stdint.h>

namespace delta6 {

const uint16_t kCrc16Init = 0xFFFF;

// One byte into a running CRC. Table-free (no 512-byte table in the AVR's 2 KB of RAM) and
// about 20 AVR instructions per byte.
uint16_t crc16Update(uint16_t crc, uint8_t byte);

// CRC of n bytes, continuing from crc.
uint16_t crc16(const uint8_t* data, uint16_t n, uint16_t crc = kCrc16Init);

}  // namespace delta6

#endif
