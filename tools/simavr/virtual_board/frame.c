/*
 * The frame an emulated ERCK-05SPI sends: a 16-bit word and its bitwise inverse (our reading
 * of the published firmware, docs/firmware.md "Encoder bus"). Kept apart so that the tests can
 * load it through ctypes and check it against the firmware's decoder.
 */
#include "frame.h"

#define STATUS_VALID 0x0001u
#define STATUS_ERROR 0x0002u
#define FIELD_TOO_STRONG (1u << 4)
#define FIELD_TOO_WEAK (1u << 5)

uint32_t vb_frame(uint16_t count, int fault, unsigned flip)
{
	uint16_t word;
	switch (fault) {
	case VB_FAULT_WEAK:
		word = STATUS_ERROR | FIELD_TOO_WEAK;
		break;
	case VB_FAULT_STRONG:
		word = STATUS_ERROR | FIELD_TOO_STRONG;
		break;
	default:
		word = (uint16_t)(((count & 0x3FFFu) << 2) | STATUS_VALID);
		break;
	}
	uint32_t frame = ((uint32_t)word << 16) | (uint16_t)~word;
	if (fault == VB_FAULT_BITERROR)
		frame ^= 0x80000000u >> (flip % 32u);   /* bit 0 is the first one on the wire */
	return frame;
}
