// C ABI over the firmware's encoder-frame check (delta6_encoder.h) for the ctypes tests
// (tests/firmware/test_encoder_frame.py), compiled together with the virtual board's frame model
// (tools/simavr/virtual_board/frame.c): what the emulated sensor sends, the firmware must read.
#include <stdint.h>

#include "delta6_encoder.h"

extern "C" {

// Returns the fault (0 = ok) and writes the count; *count is untouched on failure.
uint8_t d6_decode_frame(uint16_t word, uint16_t inverse, uint16_t* count) {
  return delta6::encoder::decodeFrame(word, inverse, count);
}

uint16_t d6_valid_word(uint16_t count) { return delta6::encoder::validWord(count); }

}  // extern "C"
