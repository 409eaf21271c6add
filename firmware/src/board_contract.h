/*
 * What the firmware and the virtual board (tools/simavr/virtual_board/) must agree on: the
 * ATmega328P stand-in's pin map, the encoder bus's command and timing, and the GPIOR0 timing
 * markers. Plain C, so the emulator includes this very file; docs/firmware.md and
 * docs/virtual-board.md describe both.
 */
#ifndef DELTA6_BOARD_CONTRACT_H
#define DELTA6_BOARD_CONTRACT_H

/* --- ATmega328P pin map (classic Nano pin names in brackets) -------------------------------
 * Six encoder data lines on one port, so that one read of PINC samples all six sensors and
 * one write drives the command bits of all six; the six chip selects on another port. */
#define D6_328P_DATA_PORT 'C'   /* PC0..PC5 [A0..A5]: data of encoders 1..6 (half duplex) */
#define D6_328P_DATA_SHIFT 0
#define D6_328P_CS_PORT 'D'     /* PD2..PD7 [D2..D7]: chip selects of encoders 1..6, low active */
#define D6_328P_CS_SHIFT 2
#define D6_328P_CLK_PORT 'B'    /* PB0 [D8]: the shared clock, idle low */
#define D6_328P_CLK_BIT 0
#define D6_328P_TEST_PORT 'B'   /* PB1 [D9]: test builds only: held low, the loop hangs */
#define D6_328P_TEST_BIT 1

/* --- Encoder bus timing, ns (encoder_bus.h explains each one and its margin) --------------
 * The firmware keeps the clock and select times and assumes the sensor's data-valid delay;
 * the virtual board's sensors use all three by default (delta6_vboard --bus-timing). */
#define D6_BUS_HALF_PERIOD_NS 1000    /* clock high and low, each at least (<= 500 kHz) */
#define D6_BUS_SELECT_SETUP_NS 2000   /* chip select low to the first clock edge */
#define D6_BUS_DATA_VALID_NS 600      /* falling edge to the sensor's next bit; < half period */
/* The read command the master clocks out, most significant bit first (delta6_encoder.h's
 * kCommand and kCommandBits, checked equal in encoder_bus.h). */
#define D6_ENCODER_COMMAND 0x55FFu
#define D6_ENCODER_COMMAND_BITS 16

/* --- GPIOR0 markers: one `out` instruction each; the emulator timestamps the writes ---------
 * A marker names the event that just happened. GPIOR1 carries an argument where noted. */
#define D6_MARK_BOOT 0xB0            /* setup() starts */
#define D6_MARK_READY 0xB1           /* setup() done, the loop starts */
#define D6_MARK_SCAN_START 0x10      /* sample timer interrupt: encoders selected (latch) */
#define D6_MARK_SCAN_END 0x11        /* all six frames clocked in */
#define D6_MARK_TICK_MISSED 0x12     /* sample timer interrupt, but the queue is full: a period is lost */
#define D6_MARK_PROCESS_START 0x20   /* the main loop takes the oldest latched sample */
#define D6_MARK_SOLVE_START 0x21
#define D6_MARK_SOLVE_END 0x22
#define D6_MARK_PROCESS_END 0x23     /* Device::onSample returned */
#define D6_MARK_RECORD_QUEUED 0x30   /* a data record entered the UART queue; GPIOR1 = bytes queued */
#define D6_MARK_BYTE_START 0x31      /* a received byte goes to Device::onByte */
#define D6_MARK_BYTE_END 0x32
#define D6_MARK_IDLE 0x40            /* the CPU goes to sleep */
#define D6_MARK_WAKE 0x41            /* it woke up (after the interrupt that woke it) */

#endif /* DELTA6_BOARD_CONTRACT_H */
