/*
 * Cycle-accurate timing from the firmware's GPIOR0 markers (firmware/src/board_contract.h).
 * The simulator stamps each write with the cycle counter, so the firmware pays one `out`
 * instruction per marker and nothing else.
 *
 *   scan        SCAN_START -> SCAN_END: the six encoders clocked in, in the timer interrupt
 *   period      SCAN_START -> next SCAN_START (a missed tick shows as a double period)
 *   solve       SOLVE_START -> SOLVE_END, minus scans that interrupted it
 *   process     PROCESS_START -> PROCESS_END: frame checks, solve, Device::onSample
 *   on_sample   SOLVE_END -> PROCESS_END
 *   byte        BYTE_START -> BYTE_END: Device::onByte for one received byte
 *   latency     SCAN_START of a sample -> the last byte of its data record out of the UART
 *               (the byte written to UDR plus one 10-bit character time at the baud rate)
 *   busy        1 - time asleep (IDLE -> WAKE) / window
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/sim_io.h>

#include "../../../firmware/src/board_contract.h"
#include "vb.h"

#define GPIOR0_ADDR 0x3E   /* ATmega328P data addresses */
#define GPIOR1_ADDR 0x4A
#define FIFO 64            /* latched samples and queued records in flight; a power of two */
#define HIST_BINS 200000   /* latency histogram, 1 us bins */

typedef struct {
	uint64_t n;
	vb_cycles_t min, max;
	double sum;
} span_t;

static uint32_t baud;
static vb_cycles_t char_cycles;
static vb_cycles_t window_start;
static double wall_window_start;

static span_t scan, period, solve, process, on_sample, byte_span, latency;
static uint64_t missed_ticks, boots, records, uart_bytes, window_bytes, marker_errors;
static vb_cycles_t asleep;
static uint32_t *latency_hist;

/* open spans */
static vb_cycles_t scan_at, last_scan_at, solve_at, process_at, byte_at, idle_at, solve_end_at;
static int in_scan, in_solve, in_process, in_byte, in_idle, have_last_scan;
static vb_cycles_t solve_interrupted;

static vb_cycles_t latch_fifo[FIFO];
static unsigned latch_head, latch_tail;
static vb_cycles_t current_latch;
static int have_current_latch;
static struct {
	uint64_t last_byte;
	vb_cycles_t latch;
} pending[FIFO];
static unsigned pending_head, pending_tail;

static void span_add(span_t *s, vb_cycles_t v)
{
	if (s->n == 0 || v < s->min)
		s->min = v;
	if (s->n == 0 || v > s->max)
		s->max = v;
	s->n++;
	s->sum += (double)v;
}

static void forget_in_flight(void)
{
	latch_head = latch_tail = 0;
	pending_head = pending_tail = 0;
	have_current_latch = 0;
	in_scan = in_solve = in_process = in_byte = in_idle = 0;
	have_last_scan = 0;
}

static void on_marker(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	(void)param;
	avr->data[addr] = v;   /* an io write hook stores the value itself */
	vb_cycles_t now = avr->cycle;
	switch (v) {
	case D6_MARK_BOOT:
		boots++;
		forget_in_flight();
		link_set_ready(0);
		break;
	case D6_MARK_READY:
		link_set_ready(1);
		break;
	case D6_MARK_SCAN_START:
		if (have_last_scan)
			span_add(&period, now - last_scan_at);
		last_scan_at = now;
		have_last_scan = 1;
		scan_at = now;
		in_scan = 1;
		if (((latch_head + 1) & (FIFO - 1)) != latch_tail) {
			latch_fifo[latch_head] = now;
			latch_head = (latch_head + 1) & (FIFO - 1);
		} else {
			marker_errors++;
		}
		break;
	case D6_MARK_SCAN_END:
		if (in_scan) {
			span_add(&scan, now - scan_at);
			if (in_solve)
				solve_interrupted += now - scan_at;
		} else {
			marker_errors++;
		}
		in_scan = 0;
		break;
	case D6_MARK_TICK_MISSED:
		missed_ticks++;
		break;
	case D6_MARK_PROCESS_START:
		process_at = now;
		in_process = 1;
		if (latch_tail != latch_head) {
			current_latch = latch_fifo[latch_tail];
			latch_tail = (latch_tail + 1) & (FIFO - 1);
			have_current_latch = 1;
		} else {
			have_current_latch = 0;
			marker_errors++;
		}
		break;
	case D6_MARK_SOLVE_START:
		solve_at = now;
		solve_interrupted = 0;
		in_solve = 1;
		break;
	case D6_MARK_SOLVE_END:
		if (in_solve)
			span_add(&solve, now - solve_at - solve_interrupted);
		in_solve = 0;
		solve_end_at = now;
		break;
	case D6_MARK_PROCESS_END:
		if (in_process) {
			span_add(&process, now - process_at);
			span_add(&on_sample, now - solve_end_at);
		}
		in_process = 0;
		break;
	case D6_MARK_RECORD_QUEUED:
		records++;
		if (have_current_latch && ((pending_head + 1) & (FIFO - 1)) != pending_tail) {
			pending[pending_head].last_byte = uart_bytes + avr->data[GPIOR1_ADDR];
			pending[pending_head].latch = current_latch;
			pending_head = (pending_head + 1) & (FIFO - 1);
		}
		break;
	case D6_MARK_BYTE_START:
		byte_at = now;
		in_byte = 1;
		break;
	case D6_MARK_BYTE_END:
		if (in_byte)
			span_add(&byte_span, now - byte_at);
		in_byte = 0;
		break;
	case D6_MARK_IDLE:
		idle_at = now;
		in_idle = 1;
		break;
	case D6_MARK_WAKE:
		if (in_idle)
			asleep += now - idle_at;
		in_idle = 0;
		break;
	default:
		break;
	}
}

void stats_uart_byte(vb_cycles_t when)
{
	uart_bytes++;
	window_bytes++;
	while (pending_tail != pending_head && pending[pending_tail].last_byte <= uart_bytes) {
		if (pending[pending_tail].last_byte == uart_bytes) {
			vb_cycles_t v = when + char_cycles - pending[pending_tail].latch;
			span_add(&latency, v);
			uint64_t bin = v * 1000000ull / vb_avr->frequency;
			latency_hist[bin < HIST_BINS ? bin : HIST_BINS - 1]++;
		}
		pending_tail = (pending_tail + 1) & (FIFO - 1);
	}
}

void stats_init(uint32_t uart_baud)
{
	baud = uart_baud;
	char_cycles = (vb_cycles_t)(10.0 * vb_avr->frequency / baud + 0.5);
	latency_hist = calloc(HIST_BINS, sizeof *latency_hist);
	if (!latency_hist)
		vb_die("out of memory");
	avr_register_io_write(vb_avr, GPIOR0_ADDR, on_marker, NULL);
	stats_reset();
}

void stats_reset(void)
{
	memset(&scan, 0, sizeof scan);
	memset(&period, 0, sizeof period);
	memset(&solve, 0, sizeof solve);
	memset(&process, 0, sizeof process);
	memset(&on_sample, 0, sizeof on_sample);
	memset(&byte_span, 0, sizeof byte_span);
	memset(&latency, 0, sizeof latency);
	memset(latency_hist, 0, HIST_BINS * sizeof *latency_hist);
	missed_ticks = records = window_bytes = 0;
	asleep = 0;
	if (in_idle)
		idle_at = vb_avr->cycle;
	window_start = vb_avr->cycle;
	wall_window_start = vb_now_wall();
}

static void span_json(FILE *f, const char *name, const span_t *s)
{
	fprintf(f, "\"%s\": {\"n\": %llu, \"min\": %llu, \"mean\": %.1f, \"max\": %llu}", name,
	        (unsigned long long)s->n, (unsigned long long)s->min, s->n ? s->sum / s->n : 0.0,
	        (unsigned long long)s->max);
}

static double percentile_us(double q)
{
	uint64_t total = 0, seen = 0;
	for (int i = 0; i < HIST_BINS; i++)
		total += latency_hist[i];
	if (!total)
		return 0.0;
	uint64_t want = (uint64_t)ceil(q * (double)total);
	for (int i = 0; i < HIST_BINS; i++) {
		seen += latency_hist[i];
		if (seen >= want && seen)
			return i + 1.0;   /* upper edge of the 1 us bin */
	}
	return HIST_BINS;
}

void stats_json(FILE *f)
{
	vb_cycles_t window = vb_avr->cycle - window_start;
	vb_cycles_t sleeping = asleep + (in_idle ? vb_avr->cycle - idle_at : 0);
	double seconds = vb_seconds(window);
	double wall = vb_now_wall() - wall_window_start;
	fprintf(f, "{\"frequency\": %u, \"baud\": %u, \"window_cycles\": %llu, "
	        "\"window_seconds\": %.6f, \"wall_seconds\": %.3f, \"speed\": %.3f, "
	        "\"samples\": %llu, \"missed_ticks\": %llu, \"records\": %llu, \"boots\": %llu, "
	        "\"marker_errors\": %llu, \"cpu_busy\": %.4f, ",
	        vb_avr->frequency, baud, (unsigned long long)window, seconds, wall,
	        wall > 0 ? seconds / wall : 0.0, (unsigned long long)scan.n,
	        (unsigned long long)missed_ticks, (unsigned long long)records,
	        (unsigned long long)boots, (unsigned long long)marker_errors,
	        window ? 1.0 - (double)sleeping / (double)window : 0.0);
	const struct {
		const char *name;
		const span_t *span;
	} spans[] = {{"scan_cycles", &scan}, {"period_cycles", &period}, {"solve_cycles", &solve},
	             {"process_cycles", &process}, {"on_sample_cycles", &on_sample},
	             {"byte_cycles", &byte_span}, {"latency_cycles", &latency}};
	for (size_t i = 0; i < sizeof spans / sizeof spans[0]; i++) {
		span_json(f, spans[i].name, spans[i].span);
		fputs(", ", f);
	}
	fprintf(f, "\"latency_us_p50\": %.0f, \"latency_us_p99\": %.0f, \"uart_bytes\": %llu, "
	        "\"uart_occupancy\": %.4f}",
	        percentile_us(0.5), percentile_us(0.99), (unsigned long long)window_bytes,
	        seconds > 0 ? window_bytes * 10.0 / baud / seconds : 0.0);
}
