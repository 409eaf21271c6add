/*
 * What an emulated ERCK-05SPI sends (frame.c). Apart from the rest of the harness, with no
 * simavr dependency, so that the tests compile it next to the firmware's decoder.
 */
#ifndef DELTA6_VB_FRAME_H
#define DELTA6_VB_FRAME_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum vb_fault {
	VB_FAULT_NONE = 0,
	VB_FAULT_BITERROR,   /* one bit of the frame flipped on the wire */
	VB_FAULT_WEAK,       /* error status, field too weak */
	VB_FAULT_STRONG,     /* error status, field too strong */
	VB_FAULT_NOANSWER,   /* the sensor never drives its line */
	VB_FAULT_KINDS
};

/* The 32 bits a sensor clocks out for a count and a fault: word << 16 | inverse. `flip` picks
 * the bit a VB_FAULT_BITERROR flips (0..31, from the first bit sent). */
uint32_t vb_frame(uint16_t count, int fault, unsigned flip);

#ifdef __cplusplus
}
#endif

#endif /* DELTA6_VB_FRAME_H */
