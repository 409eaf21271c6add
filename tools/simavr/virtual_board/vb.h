/*
 * The Delta6 virtual board: the firmware's ATmega328P image in simavr, six emulated
 * ERCK-05SPI encoders on its pins, its UART on a pseudo-terminal. docs/virtual-board.md
 * describes the behaviour; this header ties the modules together:
 *
 *   main.c      options, set-up, the run loop, pacing against the wall clock, shutdown
 *   frame.c     what one sensor sends for a count or a fault
 *   encoders.c  the six sensors at the bit level: chip selects, clock edges, data lines,
 *               timing checks, bus contention, injected faults, the read log
 *   angles.c    what the sensors measure: a replay schedule and live timed updates
 *   link.c      the UART bridged to a pty of its own (waits for a client), input pacing
 *   live.c      the live channel: a Unix socket speaking a line protocol
 *   stats.c     GPIOR0 markers -> cycle-accurate timing, reported as JSON
 */
#ifndef DELTA6_VB_H
#define DELTA6_VB_H

#include <stdint.h>
#include <stdio.h>

#include <simavr/sim_avr.h>

#include "frame.h"

#define VB_ENCODERS 6
/* A replay sample's count that is no count: that encoder does not answer at that sample (a
 * failed read in the log being replayed). */
#define VB_NO_ANSWER 0xFFFFu

/* Everything below counts time in CPU cycles (avr->cycle) unless it says otherwise. */
typedef uint64_t vb_cycles_t;

void vb_die(const char *fmt, ...) __attribute__((noreturn, format(printf, 1, 2)));
void vb_warn(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
double vb_seconds(vb_cycles_t cycles);
vb_cycles_t vb_cycles_of_seconds(double seconds);
double vb_now_wall(void);   /* wall-clock seconds (monotonic), for pacing and rates */
extern avr_t *vb_avr;

/* --- angles.c: the raw counts the sensors report ----------------------------------------- */
void angles_init(const uint16_t rest[VB_ENCODERS]);
/* Replay file (written by delta6.sim.virtualboard): "D6RP", u32 version 1, u32 n, then n records
 * of f64 time (s, from the start of the run) and u16 counts[6], little-endian. Dies with a
 * one-line message on a bad file. */
void angles_load_replay(const char *path, int loop);
/* A live update: from board time `at` (cycles) on, report counts. Returns 0 if queued, -1 if
 * the queue is full (the caller retries later). */
int angles_push(vb_cycles_t at, const uint16_t counts[VB_ENCODERS]);
/* The counts in force at `now` (applies every update due). */
void angles_at(vb_cycles_t now, uint16_t out[VB_ENCODERS]);

/* --- encoders.c --------------------------------------------------------------------------- */
extern const char *const vb_fault_names[VB_FAULT_KINDS];
int vb_fault_parse(const char *name);   /* -1 if unknown */

typedef struct {
	uint32_t half_period_ns;   /* clock high and low, minimum */
	uint32_t select_setup_ns;  /* chip select low to the first rising edge, minimum */
	uint32_t data_valid_ns;    /* falling edge to the sensor's next bit on the line */
} vb_bus_timing_t;

void encoders_init(const vb_bus_timing_t *timing, const char *read_log_path);
/* Schedule a fault for encoder e (0..5) over [from, to) cycles; a frame is affected when its
 * chip select falls inside the window. */
int encoders_add_fault(int e, int kind, vb_cycles_t from, vb_cycles_t to);
void encoders_clear_faults(int e);   /* e = -1: all */
void encoders_set_test_pin(int low); /* test builds: hold PB1 low to hang the loop */
void encoders_close(void);
void encoders_json(FILE *f);

/* --- link.c: UART <-> pty ----------------------------------------------------------------- */
void link_init(uint32_t baud);
const char *link_pty_name(void);
int link_client_present(void);
/* Move bytes: pty -> UART input queue (paced by a cycle timer), UART output -> pty.
 * With `blocking`, waits for a slow reader instead of dropping (fast, unpaced runs). */
void link_service(int blocking);
int link_fd(void);                  /* for poll() */
void link_set_ready(int ready);     /* the firmware finished setup(): feed it input */
void link_flush(double timeout_s);  /* at exit: give the reader what is queued */
void link_json(FILE *f);
void link_close(void);

/* --- live.c: the live channel -------------------------------------------------------------- */
void live_init(const char *socket_path);
void live_service(void);
int live_fill_fds(void *pollfds, int max);   /* struct pollfd entries */
void live_close(void);

/* --- stats.c ------------------------------------------------------------------------------ */
void stats_init(uint32_t baud);
void stats_uart_byte(vb_cycles_t when);   /* every byte the firmware sends */
void stats_reset(void);                   /* start a new measurement window */
void stats_json(FILE *f);
/* The whole report: stats, encoders, link, run. */
void vb_report_json(FILE *f);

#endif /* DELTA6_VB_H */
